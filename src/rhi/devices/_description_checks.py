"""Checks shared by the robot description loaders (URDF and MJCF), before Pinocchio or MuJoCo read a file.

Each check raises `rhi.errors.ModelError` naming the file (``where``), the element and the attribute:
non-finite numbers in any attribute, the URDF's kinematic tree (unique non-empty names, parents and
children that exist, one root, no cycle, at most `MAX_JOINTS` joints) and the mesh files it refers to.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

from rhi.errors import ModelError

MAX_JOINTS = 256
"""Most joints a description may hold. More than any arm or humanoid rhi loads (a Panda has 9, a humanoid
about 60); Pinocchio's model data grows with the square of the joint count (2,000 joints exhaust memory)."""

# attributes that hold names or words, never numbers ("inf" is a valid joint name)
_WORDS = frozenset({
    "name", "link", "joint", "joint1", "joint2", "body", "body1", "body2", "site", "class", "childclass", "mesh",
    "material", "texture", "hfield", "tendon", "actuator", "objname", "objtype", "target", "file", "filename",
    "type", "mode", "version", "model", "prefix", "content_type", "meshdir", "texturedir", "assetdir", "reftype",
    "refname",
})


def element_name(elem: ET.Element) -> str:
    """``<tag name='x'>`` or ``<tag>`` for messages."""
    name = elem.get("name")
    return f"<{elem.tag}>" if name is None else f"<{elem.tag} name={name!r}>"


def check_finite_numbers(root: ET.Element, where: str) -> None:
    """Refuse an attribute whose value is a list of numbers holding NaN or ±inf (names and words are skipped).

    The error names the element with its closest named ancestor, e.g. ``<joint name='elbow'> <origin>``.
    """
    stack: list[tuple[ET.Element, str]] = [(root, "")]
    while stack:
        elem, owner = stack.pop()
        label = element_name(elem) if elem.get("name") is not None or not owner else f"{owner} <{elem.tag}>"
        for attr, raw in elem.attrib.items():
            if attr in _WORDS or not raw or len(raw) > 100_000:
                continue
            try:
                vals = [float(v) for v in raw.split()]
            except ValueError:
                continue  # not a list of numbers
            if any(not math.isfinite(v) for v in vals):
                raise ModelError(f"{where}: {label}: attribute {attr}={raw!r:.80} must be finite numbers")
        named = element_name(elem) if elem.get("name") is not None else owner
        stack.extend((child, named) for child in reversed(list(elem)))


def check_urdf_tree(root: ET.Element, where: str) -> None:
    """Check that the URDF's links and joints form one tree.

    Unique non-empty names, existing parent and child links, each link the child of at most one joint,
    one root link, no cycle, at most `MAX_JOINTS` joints.
    """
    links: dict[str, ET.Element] = {}
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            raise ModelError(f"{where}: a <link> without a name attribute")
        if name in links:
            raise ModelError(f"{where}: <link name={name!r}>: the name is used twice (link names must be unique)")
        links[name] = link
    joints = root.findall("joint")
    if len(joints) > MAX_JOINTS:
        raise ModelError(f"{where}: {len(joints)} joints; at most {MAX_JOINTS} are supported "
                         "(rhi.devices._description_checks.MAX_JOINTS)")
    parent_of: dict[str, str] = {}  # link: the joint it is the child of
    child_to_parent: dict[str, str] = {}  # link: its parent link
    seen: set[str] = set()
    for joint in joints:
        name = joint.get("name")
        if not name:
            raise ModelError(f"{where}: a <joint> without a name attribute")
        what = f"{where}: <joint name={name!r}>"
        if name in seen:
            raise ModelError(f"{what}: the name is used twice (joint names must be unique)")
        seen.add(name)
        ends = {}
        for end in ("parent", "child"):
            el = joint.find(end)
            ref = None if el is None else el.get("link")
            if not ref:
                raise ModelError(f"{what}: missing <{end} link=...>")
            if ref not in links:
                raise ModelError(f"{what}: <{end} link={ref!r}>: no link of that name")
            ends[end] = ref
        if ends["child"] in parent_of:
            raise ModelError(f"{what}: <child link={ends['child']!r}>: the link is already the child of joint "
                             f"{parent_of[ends['child']]!r} (a link has one parent)")
        if ends["child"] == ends["parent"]:
            raise ModelError(f"{what}: parent and child are both {ends['child']!r}")
        parent_of[ends["child"]] = name
        child_to_parent[ends["child"]] = ends["parent"]
    roots = [n for n in links if n not in child_to_parent]
    if len(roots) != 1:
        # no root: every link has a parent, so the joints close a loop
        raise ModelError(f"{where}: the joints form a cycle (no root link)" if not roots else
                         f"{where}: {len(roots)} root links ({', '.join(map(repr, roots[:5]))}); a URDF has one root")
    for start in links:  # with one root and one parent per link, a cycle is a loop not reaching the root
        steps, at = 0, start
        while at in child_to_parent:
            at, steps = child_to_parent[at], steps + 1
            if at == start or steps > len(links):
                raise ModelError(f"{where}: the joints form a cycle through link {start!r}")


def check_mesh_files(root: ET.Element, where: str, near: Path | None) -> None:
    """Every ``<mesh filename=...>`` names a file that exists (relative to `near`, the description's folder)."""
    for link in root.findall("link"):
        for mesh in link.iter("mesh"):
            fn = mesh.get("filename")
            what = f"{where}: <link name={link.get('name')!r}> <mesh filename={fn!r}>"
            if not fn:
                raise ModelError(f"{where}: <link name={link.get('name')!r}> <mesh>: missing attribute 'filename'")
            if fn.startswith("package://"):
                pkg = fn[len("package://"):].split("/")[0]
                raise ModelError(f"{what}: ROS package {pkg!r} not found; pass package_dirs=[...]")
            path = Path(fn[len("file://"):] if fn.startswith("file://") else fn)
            if not path.is_absolute():
                path = (near if near is not None else Path.cwd()) / path
            if not path.is_file():
                raise ModelError(f"{what}: no file {str(path)!r}")
