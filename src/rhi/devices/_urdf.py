"""Reading robot description files for `rhi.devices.loaders`: xacro expansion, `package://` paths, checks.

Every check names the link or joint and the attribute at fault, before Pinocchio sees the
file (its own parser reports most problems only on stderr).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
import sysconfig
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from rhi.devices._description_checks import check_finite_numbers, check_mesh_files, check_urdf_tree
from rhi.errors import InvalidInput, ModelError

UNBOUNDED = 1e12  # |limit| >= this in a joint range means "no limit" (continuous joints)
FILL_DENSITY = 1000.0  # [kg/m³] inertia="fill": a point-mass link becomes a solid sphere of water of its mass
_PACKAGE = re.compile(r"package://([^/\"'\s]+)/")
_MOVABLE = ("revolute", "continuous", "prismatic")
_KNOWN_TYPES = _MOVABLE + ("fixed",)


def description_roots() -> list[Path]:
    """Folders holding installed robot description packages (example-robot-data, rtb-data)."""
    roots = []
    for base in {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}:
        for sub in ("cmeel.prefix/share/example-robot-data/robots", "rtbdata/xacro"):
            if (Path(base) / sub).is_dir():
                roots.append(Path(base) / sub)
    return roots


def find_package(pkg: str, near: Path | None, package_dirs: Sequence[str | Path] = ()) -> Path | None:
    """The folder of ROS package `pkg`: in `package_dirs`, ROS_PACKAGE_PATH, in or above `near`, or installed."""
    roots = [Path(p) for p in package_dirs]
    roots += [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    if near is not None:
        roots += [near.resolve(), *list(near.resolve().parents)[:6]]  # Pinocchio searches `near` too
    roots += description_roots()
    for root in roots:
        if root.name == pkg and root.is_dir():
            return root
        if (root / pkg).is_dir():
            return root / pkg
    return None


@contextlib.contextmanager
def _xacro_find(near: Path | None, package_dirs: Sequence[str | Path]) -> Iterator[None]:
    """Resolve xacro's `$(find pkg)` with `find_package` (xacro's own needs a ROS installation)."""
    from xacro import substitution_args

    def _eval_find(pkg: str) -> str:
        found = find_package(pkg, near, package_dirs)
        if found is None:
            raise ModelError(f"path: xacro $(find {pkg}): package {pkg!r} not found; pass package_dirs=[...]")
        return str(found)

    saved = substitution_args._eval_find
    substitution_args._eval_find = _eval_find
    try:
        yield
    finally:
        substitution_args._eval_find = saved


def read_description(source, package_dirs: Sequence[str | Path] = ()) -> tuple[str, Path | None, str]:
    """Read a URDF/xacro file or XML text: (XML with xacro expanded and package:// resolved, folder, stem).

    Raises:
        InvalidInput: `source` is neither a path nor XML text.
        ModelError: missing file, xacro error.
    """
    if isinstance(source, Path) or (isinstance(source, str) and not source.lstrip().startswith("<")):
        path = Path(source)
        if not path.is_file():
            raise ModelError(f"path: file {str(path)!r} does not exist")
        try:
            text = path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise ModelError(f"path: cannot read {str(path)!r} ({exc})") from None
        near, stem = path.parent, path.name.split(".")[0]
    elif isinstance(source, str):
        text, near, stem, path = source, None, "robot", None
    else:
        raise InvalidInput(f"path: expected a file path or URDF XML text, got {type(source).__name__}")
    if "xmlns:xacro" in text or (path is not None and ".xacro" in path.suffixes):
        text = _expand_xacro(text, path, near, package_dirs)
    text = _PACKAGE.sub(lambda m: _package_url(m, near, package_dirs), text)
    return text, near, stem


def _expand_xacro(text: str, path: Path | None, near: Path | None, package_dirs) -> str:
    import xacro

    try:
        with _xacro_find(near, package_dirs):
            if path is not None:
                doc = xacro.process_file(str(path))
            else:
                doc = xacro.parse(text)
                xacro.process_doc(doc)
        return doc.toxml()
    except ModelError:
        raise
    except Exception as exc:  # xacro raises XacroException, XML errors, NameError ... with its own text
        raise ModelError(f"path: {path if path is not None else 'XML text'}: xacro expansion failed: {exc}") from None


@contextlib.contextmanager
def stderr_captured(into: list[str]) -> Iterator[None]:
    """Capture what C++ code (urdfdom, MuJoCo) prints on file descriptor 2 into `into` (one string)."""
    import sys
    import tempfile

    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            into.append(tmp.read().decode(errors="replace"))


def _package_url(m: re.Match, near: Path | None, package_dirs) -> str:
    found = find_package(m.group(1), near, package_dirs)
    return m.group(0) if found is None else f"{found}/"


# ---------------------------------------------------------------- validation
@dataclasses.dataclass(frozen=True)
class JointInfo:
    """What the loaders need from a description beyond Pinocchio's model."""

    mimic: dict[str, tuple[str, float, float]]  # joint: (primary, multiplier, offset)
    continuous: set[str]
    no_effort: set[str]  # movable joints without an effort limit
    filled: dict[str, float] = dataclasses.field(default_factory=dict)  # point-mass link: the moment given [kg m²]


def fill_inertia(mass: float) -> float:
    """The principal moment [kg m²] `inertia="fill"` gives a point mass of `mass` [kg] (> 0).

    A uniform solid sphere of that mass at the density of water (`FILL_DENSITY`): r = (3m / 4πρ)^(1/3),
    I = (2/5) m r² about every axis (1 kg: r = 6.2 cm, I = 1.5e-3 kg m²; 0.1 kg: r = 2.9 cm, I = 3.3e-5 kg m²).
    """
    r = (3.0 * mass / (4.0 * np.pi * FILL_DENSITY)) ** (1.0 / 3.0)
    return 0.4 * mass * r * r


def _floats(elem: ET.Element, attr: str, what: str, count: int, default: str | None = None) -> np.ndarray:
    raw = elem.get(attr, default)
    if raw is None:
        raise ModelError(f"{what}: missing attribute {attr!r}")
    try:
        vals = np.array([float(v) for v in raw.split()], dtype=float)
    except ValueError:
        raise ModelError(f"{what}: attribute {attr}={raw!r} is not numeric") from None
    if vals.shape != (count,) or not np.all(np.isfinite(vals)):
        raise ModelError(f"{what}: attribute {attr}={raw!r} must be {count} finite number(s)")
    return vals


def check_urdf(text: str, *, inertia: str = "strict", where: str = "path",
               near: Path | None = None) -> tuple[str, JointInfo]:
    """Validate URDF text and normalise it for Pinocchio.

    Every error names `where` (the file), the element and the attribute.
    The checks of `rhi.devices._description_checks` come first (finite numbers, one kinematic tree of at most
    `MAX_JOINTS` joints, mesh files that exist relative to `near`).

    Continuous joints become revolute joints with an unbounded range; revolute/prismatic
    joints without `<limit>` get an unbounded range and no effort limit (recorded in
    `JointInfo.no_effort`). Masses must be >= 0 (0 only with a zero inertia: a massless
    dummy link), inertias symmetric positive definite and physically consistent (triangle
    inequalities), joint axes finite and non-zero. A link with a mass and a zero inertia (a point mass)
    is refused, or with ``inertia="fill"`` given the inertia of `fill_inertia` (listed in `JointInfo.filled`).

    Returns:
        (normalised URDF text, joint information).
    """
    if inertia not in ("strict", "fill"):
        raise InvalidInput(f'inertia: expected "strict" or "fill", got {inertia!r}')
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise ModelError(f"{where}: malformed URDF XML ({exc})") from None
    if root.tag != "robot":
        raise ModelError(f"{where}: a URDF's root element is <robot>, got <{root.tag}>")
    links = root.findall("link")
    if not links:
        raise ModelError(f"{where}: no <link> elements in the URDF")
    check_finite_numbers(root, where)
    check_urdf_tree(root, where)
    check_mesh_files(root, where, near)
    filled = {}
    for link in links:
        moment = _check_link(link, inertia == "fill", where)
        if moment is not None:
            filled[str(link.get("name"))] = moment
    names = {n for j in root.findall("joint") if (n := j.get("name")) is not None}
    mimic: dict[str, tuple[str, float, float]] = {}
    continuous: set[str] = set()
    no_effort: set[str] = set()
    for joint in root.findall("joint"):
        name, kind = str(joint.get("name")), joint.get("type")
        what = f"{where}: joint {name!r}"
        if kind not in _KNOWN_TYPES:
            raise ModelError(f"{what}: type {kind!r} not supported (revolute, continuous, prismatic, fixed)")
        origin = joint.find("origin")
        if origin is not None:
            _floats(origin, "xyz", f"{what} <origin>", 3, "0 0 0")
            _floats(origin, "rpy", f"{what} <origin>", 3, "0 0 0")
        if kind == "fixed":
            continue
        axis_el = joint.find("axis")
        axis = np.array([1.0, 0, 0]) if axis_el is None else _floats(axis_el, "xyz", f"{what} <axis>", 3)
        if np.linalg.norm(axis) < 1e-9:
            raise ModelError(f"{what} <axis>: xyz must be a non-zero vector, got {axis.tolist()}")
        limit = joint.find("limit")
        if limit is None:
            limit = ET.SubElement(joint, "limit", {"effort": "0", "velocity": "0"})
            limit.set("lower", str(-UNBOUNDED))
            limit.set("upper", str(UNBOUNDED))
        for attr in ("effort", "velocity"):  # urdfdom requires both; rhi reads no velocity limit
            limit.set(attr, limit.get(attr, "0"))
        effort = float(_floats(limit, "effort", f"{what} <limit>", 1, "0")[0])
        _floats(limit, "velocity", f"{what} <limit>", 1, "0")
        if effort < 0:
            raise ModelError(f"{what} <limit>: effort must be >= 0, got {effort}")
        if effort == 0:
            no_effort.add(name)
        if kind == "continuous":
            joint.set("type", "revolute")
            limit.set("lower", str(-UNBOUNDED))
            limit.set("upper", str(UNBOUNDED))
            continuous.add(name)
        elif kind == "revolute" or kind == "prismatic":
            lo = _floats(limit, "lower", f"{what} <limit>", 1, "0")[0]
            hi = _floats(limit, "upper", f"{what} <limit>", 1, "0")[0]
            if lo > hi:
                raise ModelError(f"{what} <limit>: lower={lo} > upper={hi}")
        m = joint.find("mimic")
        if m is not None:
            primary = m.get("joint")
            if primary is None or primary not in names or primary == name:
                raise ModelError(f"{what} <mimic>: joint={primary!r} is not another joint of the URDF")
            mult = float(_floats(m, "multiplier", f"{what} <mimic>", 1, "1")[0])
            off = float(_floats(m, "offset", f"{what} <mimic>", 1, "0")[0])
            mimic[name] = (primary, mult, off)
            joint.remove(m)  # rhi models mimic joints through its actuation map
    return ET.tostring(root, encoding="unicode"), JointInfo(mimic, continuous, no_effort, filled)


def _check_link(link: ET.Element, fill: bool, where: str) -> float | None:
    """Check a link's <inertial>; with `fill`, a point mass's moment of inertia given (returned), else None."""
    what = f"{where}: link {link.get('name')!r}"
    inertial = link.find("inertial")
    if inertial is None:
        return None
    mass_el = inertial.find("mass")
    if mass_el is None:
        raise ModelError(f"{what} <inertial>: missing <mass>")
    mass = float(_floats(mass_el, "value", f"{what} <mass>", 1)[0])
    if mass < 0:
        raise ModelError(f"{what} <mass>: value must be >= 0 [kg], got {mass}")
    origin = inertial.find("origin")
    if origin is not None:
        _floats(origin, "xyz", f"{what} <inertial><origin>", 3, "0 0 0")
        _floats(origin, "rpy", f"{what} <inertial><origin>", 3, "0 0 0")
    el = inertial.find("inertia")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    if el is None:
        vals = dict.fromkeys(keys, 0.0)
    else:
        vals = {k: float(_floats(el, k, f"{what} <inertia>", 1, "0")[0]) for k in keys}
    inertia = np.array([[vals["ixx"], vals["ixy"], vals["ixz"]],
                        [vals["ixy"], vals["iyy"], vals["iyz"]],
                        [vals["ixz"], vals["iyz"], vals["izz"]]])
    if mass == 0:
        if np.any(inertia != 0):
            raise ModelError(f"{what} <mass>: value 0 with a non-zero <inertia> (give the mass in kg)")
        return None
    if not np.any(inertia):
        if not fill:
            raise ModelError(f"{what} <inertia>: a point mass ({mass:g} kg, zero inertia); give it an inertia, or "
                             'load with inertia="fill" (--inertia fill, [device] inertia = "fill") for a small one')
        moment = fill_inertia(mass)
        el = el if el is not None else ET.SubElement(inertial, "inertia")
        for k in keys:
            el.set(k, repr(moment) if k in ("ixx", "iyy", "izz") else "0")
        return moment
    check_inertia(inertia, f"{what} <inertia>")
    return None


def check_inertia(inertia: np.ndarray, what: str) -> None:
    """Raise ModelError unless the (3, 3) rotational inertia is SPD and satisfies the triangle inequalities."""
    eig = np.linalg.eigvalsh(inertia)
    if eig[0] <= 0:
        raise ModelError(f"{what}: not positive definite (principal moments {np.round(eig, 12).tolist()} kg m²)")
    tol = 1e-9 * eig[-1]
    if eig[0] + eig[1] < eig[2] - tol:
        raise ModelError(
            f"{what}: physically inconsistent, principal moments {np.round(eig, 12).tolist()} kg m² "
            "violate the triangle inequality I1 + I2 >= I3"
        )
