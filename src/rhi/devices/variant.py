"""Named parameter variants of a bundled device: other link inertias and rotor inertias, same kinematics.

A variant lives in the device's model folder as ``<name with - as _>.toml`` (e.g. rhi4's
``thesis_fit.toml``, written by `rhi.experiments.calibration.write_thesis_fit`) and is loaded
only when asked for: ``rhi.device("rhi4", params="thesis-fit")``. The default model never
changes. Format:

    armature = [..]                 # (n,) rotor inertia [kg m²] replacing the device's
    [links.<urdf link>]             # any of: mass [kg], com_x [m] (along the link), izz [kg m²]
    [fit]                           # provenance (bounds, parameters, residuals); not read here
"""

from __future__ import annotations

import dataclasses
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

from rhi.errors import InvalidInput, ModelError

_LINK_KEYS = ("mass", "com_x", "izz")


@dataclasses.dataclass(frozen=True)
class Variant:
    """A parameter variant of a device.

    Attributes:
        name: its name, e.g. "thesis-fit".
        links: {URDF link name: {"mass" [kg], "com_x" [m], "izz" [kg m²]}} overrides.
        armature: (n,) rotor inertias [kg m²] or None (keep device.toml's).
        path: the file it was read from.
    """

    name: str
    links: dict[str, dict[str, float]]
    armature: np.ndarray | None
    path: Path


def available_variants(folder: Path) -> list[str]:
    """Names of the variants in a model folder (file stems with _ as -)."""
    return sorted(p.stem.replace("_", "-") for p in Path(folder).glob("*.toml") if p.stem != "device")


def read_variant(folder: Path, name: str, device: str) -> Variant:
    """The variant `name` of the device in `folder`.

    Raises:
        InvalidInput: `name` is not a variant of this device (names the known ones).
        ModelError: the variant file is malformed.
    """
    known = available_variants(folder)
    if not isinstance(name, str) or name not in known:
        raise InvalidInput(f"params: {device} has no parameter variant {name!r}; "
                           f"known: {', '.join(['default', *known])}")
    path = Path(folder) / (name.replace("-", "_") + ".toml")
    try:
        doc = tomllib.loads(path.read_text())
        unknown = set(doc) - {"armature", "links", "fit"}
        if unknown:
            raise ValueError(f"unknown keys {sorted(unknown)}")
        links = {}
        for link, values in doc.get("links", {}).items():
            bad = set(values) - set(_LINK_KEYS)
            if bad:
                raise ValueError(f"links.{link}: unknown keys {sorted(bad)}")
            links[link] = {k: float(v) for k, v in values.items()}
            if any(not np.isfinite(v) or (k != "com_x" and v <= 0) for k, v in links[link].items()):
                raise ValueError(f"links.{link}: masses and inertias must be finite and > 0")
        arm = doc.get("armature")
        armature = None if arm is None else np.array(arm, dtype=float)
        if armature is not None and (not np.all(np.isfinite(armature)) or np.any(armature < 0)):
            raise ValueError("armature: must be finite and >= 0")
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, TypeError, ValueError) as exc:
        raise ModelError(f"{path}: malformed parameter variant ({exc})") from None
    return Variant(name, links, armature, path)


def model_with_links(urdf: Path, links: dict[str, dict[str, float]]) -> pin.Model:
    """The Pinocchio model of `urdf` with the inertial blocks of `links` replaced.

    Args:
        urdf: the device's URDF file.
        links: {link: {"mass", "com_x", "izz"}} (each key optional) [kg, m, kg m²].

    Raises:
        ModelError: a link the URDF does not have, or one without an inertial block.
    """
    root = ET.parse(urdf).getroot()
    by_name = {el.get("name"): el for el in root.iter("link")}
    for link, values in links.items():
        el = by_name.get(link)
        inertial = None if el is None else el.find("inertial")
        if inertial is None:
            raise ModelError(f"links: {urdf.name} has no link {link!r} with an inertial block")
        if "mass" in values:
            inertial.find("mass").set("value", repr(values["mass"]))  # type: ignore[union-attr]
        if "com_x" in values:
            origin = inertial.find("origin")
            xyz = [float(v) for v in origin.get("xyz", "0 0 0").split()]  # type: ignore[union-attr]
            xyz[0] = values["com_x"]
            origin.set("xyz", " ".join(repr(v) for v in xyz))  # type: ignore[union-attr]
        if "izz" in values:
            inertia = inertial.find("inertia")
            inertia.set("izz", repr(values["izz"]))  # type: ignore[union-attr]
            inertia.set("iyy", repr(values["izz"]))  # type: ignore[union-attr]  # planar rods: I_yy = I_zz
    return pin.buildModelFromXML(ET.tostring(root, encoding="unicode"))


__all__ = ["Variant", "available_variants", "model_with_links", "read_variant"]
