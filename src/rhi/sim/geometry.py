"""Visual geometry of a device's MuJoCo model: what the renderer and the browser view draw.

A device whose URDF has ``<visual>`` elements is drawn from them (meshes, boxes, cylinders,
spheres; ``package://`` and relative mesh paths resolved by Pinocchio's URDF geometry loader,
the mesh vertices handed to MuJoCo through `MjSpec`), in the URDF's colours, or else in the mesh
files' own material colours part by part (`mesh_parts`: a DAE's or an OBJ's, read by trimesh).
A device from an MJCF is drawn from the geoms MuJoCo's viewer shows of it (groups 0–2: meshes,
primitives and planes, in their rgba or material colours; `add_mjcf_visuals`).
Otherwise every link is a capsule from its joint to each child joint (or to the handle) — the real link lengths — with a cylinder
at each revolute joint along its axis, a pedestal under the first joint and a ball at the
handle. Geometry is visual only (no contacts, no mass: the bodies carry Pinocchio's inertias)
unless ``collision=True``.
"""

from __future__ import annotations

from collections.abc import Collection

import mujoco
import numpy as np
import pinocchio as pin

from rhi.errors import ModelError

#: Colours (RGBA) of the drawn parts.
LINK_RGBA = (0.3, 0.42, 0.6, 1.0)
JOINT_RGBA = (0.18, 0.2, 0.24, 1.0)
BASE_RGBA = (0.35, 0.35, 0.38, 1.0)
HANDLE_RGBA = (0.95, 0.55, 0.1, 1.0)
WHEEL_RGBA = (0.12, 0.12, 0.12, 1.0)
#: the material of a floor (a checker texture), in every drawable model
FLOOR_MATERIAL = "grid"

_G = mujoco.mjtGeom


def quat_wxyz(R: np.ndarray) -> list[float]:
    """Quaternion (w, x, y, z) of a rotation matrix R: (3, 3)."""
    q = pin.Quaternion(np.asarray(R))
    return [q.w, q.x, q.y, q.z]


def _align_z(axis: np.ndarray) -> list[float]:
    """Quaternion rotating z onto `axis`."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    q = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), a)
    return [q.w, q.x, q.y, q.z]


class GeomAdder:
    """Adds geoms to bodies of an `MjSpec`, visual-only or colliding."""

    def __init__(self, spec: mujoco.MjSpec, *, collision: bool = False) -> None:
        self.spec = spec
        self.collision = bool(collision)
        self.count = 0

    def __call__(self, body, kind, *, rgba, **attrs):
        """Add a geom of type `kind` to `body` (visual only unless collision is on) and return it."""
        g = body.add_geom(type=kind, rgba=list(rgba), **attrs)
        g.name = f"vis{self.count}"
        self.count += 1
        c = 1 if self.collision else 0
        g.contype, g.conaffinity = c, c
        g.group = 0 if self.collision else 1
        g.mass = 0.0
        return g


def link_radius(device) -> float:
    """Capsule radius [m]: 6 % of the longest link, within [4, 25] mm."""
    model = device.model
    lengths = [np.linalg.norm(model.jointPlacements[j].translation) for j in range(1, model.njoints)]
    lengths.append(np.linalg.norm(model.frames[device.ee_frame_id].placement.translation))
    return float(np.clip(0.06 * max(lengths, default=0.1), 0.004, 0.025))


def joint_axis(jm) -> tuple[str, np.ndarray]:
    """MuJoCo joint type ("hinge" or "slide") and axis (3,) of a one-DoF Pinocchio joint model."""
    name = jm.shortname()
    fixed = {"JointModelRX": ("hinge", 0), "JointModelRY": ("hinge", 1), "JointModelRZ": ("hinge", 2),
             "JointModelPX": ("slide", 0), "JointModelPY": ("slide", 1), "JointModelPZ": ("slide", 2)}
    if name in fixed:
        kind, i = fixed[name]
        return kind, np.eye(3)[i]
    if name == "JointModelRevoluteUnaligned":
        return "hinge", np.asarray(jm.extract().axis, dtype=float)
    if name == "JointModelPrismaticUnaligned":
        return "slide", np.asarray(jm.extract().axis, dtype=float)
    raise ModelError(f"device: joint type {name} has no MuJoCo plant equivalent (revolute/prismatic only)")


def add_skeleton(add: GeomAdder, device, bodies: dict, *, skip: Collection[int] = frozenset(), base: bool = True) -> None:
    """Capsules between joint origins, joint cylinders and a pedestal under the first joint.

    Args:
        add: the geom adder of the spec.
        device: the device (its Pinocchio model and end-effector frame).
        bodies: MuJoCo body of each Pinocchio joint index (0: the world body).
        skip: joint indices whose bodies get no geometry (e.g. a mobile base's sliders).
        base: draw the pedestal under the first drawn joint.
    """
    model = device.model
    r = link_radius(device)
    ends: dict[int, list[np.ndarray]] = {j: [] for j in range(model.njoints)}
    for j in range(1, model.njoints):
        ends[model.parents[j]].append(np.asarray(model.jointPlacements[j].translation))
    fr = model.frames[device.ee_frame_id]
    ends[fr.parentJoint].append(np.asarray(fr.placement.translation))
    for j in range(1, model.njoints):
        if j in skip:
            continue
        body = bodies[j]
        for p in ends[j]:
            if np.linalg.norm(p) > 1e-3:
                add(body, _G.mjGEOM_CAPSULE, fromto=[0, 0, 0, *p], size=[r, 0, 0], rgba=LINK_RGBA)
        kind, axis = joint_axis(model.joints[j])
        if kind == "hinge":
            add(body, _G.mjGEOM_CYLINDER, quat=_align_z(axis), size=[1.5 * r, 1.3 * r, 0], rgba=JOINT_RGBA)
        else:
            add(body, _G.mjGEOM_BOX, quat=_align_z(axis), size=[1.2 * r, 1.2 * r, 1.2 * r], rgba=JOINT_RGBA)
    if base:
        first = next((j for j in range(1, model.njoints) if j not in skip), None)
        if first is not None:
            parent = model.parents[first]
            M = model.jointPlacements[first]
            _, axis = joint_axis(model.joints[first])
            a = M.rotation @ axis
            add(bodies[parent], _G.mjGEOM_CYLINDER, pos=list(M.translation - 2.6 * r * a), quat=_align_z(a),
                size=[3.5 * r, 1.2 * r, 0], rgba=BASE_RGBA)


def add_handle(add: GeomAdder, handle_body, radius: float) -> None:
    """A ball with a short grip along the handle's z axis."""
    add(handle_body, _G.mjGEOM_SPHERE, size=[1.8 * radius, 0, 0], rgba=HANDLE_RGBA)
    add(handle_body, _G.mjGEOM_CAPSULE, fromto=[0, 0, 0, 0, 0, 5 * radius], size=[0.9 * radius, 0, 0],
        rgba=HANDLE_RGBA)


def add_visuals(add: GeomAdder, device, bodies: dict) -> bool:
    """The device's own visual geometry (its URDF's or its MJCF's) on `bodies`; False where it has none."""
    desc = getattr(device, "visual_description", None)
    if desc is not None and desc[0] == "mjcf":
        return add_mjcf_visuals(add, device, desc[1], bodies)
    shapes = urdf_visuals(device)
    if shapes is None:
        return False
    add_urdf_visuals(add, shapes, bodies)
    return True


def urdf_visuals(device) -> pin.GeometryModel | None:
    """The URDF's visual geometry (meshes resolved), or None when it declares none or the device has no URDF."""
    desc = getattr(device, "visual_description", None)
    if desc is None or desc[0] != "urdf":
        return None
    _, text, dirs = desc
    try:
        geom = pin.buildGeomFromUrdfString(device.model, text, pin.GeometryType.VISUAL, package_dirs=list(dirs))
    except (RuntimeError, ValueError) as exc:
        raise ModelError(f"urdf: cannot load the visual geometry of {device.name}: {exc}") from None
    return geom if geom.ngeoms else None


def add_urdf_visuals(add: GeomAdder, geom: pin.GeometryModel, bodies: dict) -> None:
    """Meshes and primitives of a URDF's visual elements, on the bodies of their joints."""
    spec = add.spec
    for k, go in enumerate(geom.geometryObjects):
        body = bodies[go.parentJoint]
        M = go.placement
        rgba = tuple(float(c) for c in go.meshColor) if np.any(go.meshColor[:3] != 0.9) else LINK_RGBA
        at = {"pos": list(M.translation), "quat": quat_wxyz(M.rotation)}
        shape = go.geometry
        kind = type(shape).__name__
        if kind == "Box":
            add(body, _G.mjGEOM_BOX, size=list(shape.halfSide), rgba=rgba, **at)
        elif kind == "Cylinder":
            add(body, _G.mjGEOM_CYLINDER, size=[shape.radius, shape.halfLength, 0], rgba=rgba, **at)
        elif kind == "Sphere":
            add(body, _G.mjGEOM_SPHERE, size=[shape.radius, 0, 0], rgba=rgba, **at)
        elif kind == "Capsule":
            add(body, _G.mjGEOM_CAPSULE, size=[shape.radius, shape.halfLength, 0], rgba=rgba, **at)
        elif hasattr(shape, "vertices") and shape.num_tris:
            V = np.asarray(shape.vertices(), dtype=float)
            F = np.array([[t[0], t[1], t[2]] for t in (shape.tri_indices(i) for i in range(shape.num_tris))])
            # no colour in the URDF: the mesh file's own materials, part by part (a DAE's or an OBJ's)
            parts = mesh_parts(go.meshPath, go.meshScale, V) if rgba == LINK_RGBA else None
            for i, (Vi, Fi, ci) in enumerate(parts or [(V, F, rgba)]):
                name = f"mesh{k}_{i}"
                spec.add_mesh(name=name, uservert=Vi.ravel().tolist(), userface=Fi.ravel().tolist())
                add(body, _G.mjGEOM_MESH, meshname=name, rgba=ci, **at)
        else:
            raise ModelError(f"urdf: visual {go.name!r} has geometry {kind} that rhi cannot draw")


def geom_rgba(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Colour (4,) of geom g as MuJoCo draws it: its material's where it has one and keeps the default rgba."""
    mat = int(model.geom_matid[g])
    if mat >= 0 and np.allclose(model.geom_rgba[g], [0.5, 0.5, 0.5, 1.0]):
        return model.mat_rgba[mat]
    return model.geom_rgba[g]


#: MJCF geoms drawn as themselves (the compiled model's sizes carry over)
_PRIMITIVES = {int(k) for k in (_G.mjGEOM_PLANE, _G.mjGEOM_SPHERE, _G.mjGEOM_CAPSULE, _G.mjGEOM_ELLIPSOID,
                                 _G.mjGEOM_CYLINDER, _G.mjGEOM_BOX)}


def add_mjcf_visuals(add: GeomAdder, device, path: str, bodies: dict) -> bool:
    """The geoms MuJoCo's viewer shows of an MJCF file (groups 0–2), on the bodies of their joints.

    Each geom keeps its pose in its MJCF body, placed through that body's frame in the device's Pinocchio
    model (`pinocchio.buildModelFromMJCF` names body frames after the bodies), its size or mesh (the compiled
    vertices) and its colour (`geom_rgba`); a texture is left out. Returns False where none is visible.

    Raises:
        ModelError: the file no longer loads, a body has no frame in the device's model, or a geom is of a
            kind rhi cannot draw (height fields, SDFs).
    """
    try:
        mj = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:
        raise ModelError(f"mjcf: cannot load the visual geometry of {device.name} from {path}: {exc}") from None
    model, spec, drawn = device.model, add.spec, False
    for g in range(mj.ngeom):
        if mj.geom_group[g] > 2:
            continue
        b = int(mj.geom_bodyid[g])
        joint, M = 0, pin.SE3.Identity()
        if b != 0:
            name = mj.body(b).name
            if not model.existFrame(name, pin.FrameType.BODY):
                raise ModelError(f"mjcf: body {name!r} of {path} has no frame in {device.name}'s model")
            fr = model.frames[model.getFrameId(name, pin.FrameType.BODY)]
            joint, M = fr.parentJoint, fr.placement
        quat = mj.geom_quat[g]
        G = M * pin.SE3(pin.Quaternion(*quat).toRotationMatrix(), np.array(mj.geom_pos[g], dtype=float))
        at = {"pos": list(G.translation), "quat": quat_wxyz(G.rotation)}
        rgba, kind = tuple(float(c) for c in geom_rgba(mj, g)), int(mj.geom_type[g])
        if kind in _PRIMITIVES:
            add(bodies[joint], _G(kind), size=list(mj.geom_size[g]), rgba=rgba, **at)
        elif kind == int(_G.mjGEOM_MESH):
            i = mj.geom_dataid[g]
            va, vn, fa, fn = mj.mesh_vertadr[i], mj.mesh_vertnum[i], mj.mesh_faceadr[i], mj.mesh_facenum[i]
            mesh = f"mjcf_mesh{g}"
            spec.add_mesh(name=mesh, uservert=mj.mesh_vert[va:va + vn].ravel().tolist(),
                          userface=mj.mesh_face[fa:fa + fn].ravel().tolist())
            add(bodies[joint], _G.mjGEOM_MESH, meshname=mesh, rgba=rgba, **at)
        else:
            raise ModelError(f"mjcf: geom {mj.geom(g).name or g!r} of {path} is a {_G(kind).name}, which rhi cannot "
                             "draw (meshes, planes and primitives)")
        drawn = True
    return drawn


def mesh_parts(path: str, scale, vertices: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, tuple]] | None:
    """A mesh file's parts in their own material colours: [(V (k, 3) [m], F (l, 3), RGBA)], or None.

    None where the file gives no colour (an STL), trimesh cannot read it, or its geometry differs from the
    one Pinocchio loaded (`vertices`: (N, 3) [m], scaled): the caller then draws that in one colour.

    Args:
        path: the mesh file (a resolved URDF ``<mesh filename>``).
        scale: (3,) the URDF's mesh scale.
        vertices: Pinocchio's vertices of the same mesh, to check the reading against.
    """
    import trimesh

    try:
        scene = trimesh.load_scene(path)
    except Exception:  # noqa: BLE001 - any reader failure: the mesh is drawn as Pinocchio loaded it
        return None
    parts = []
    for node in scene.graph.nodes_geometry:
        T, geom = scene.graph[node]
        mesh = scene.geometry[geom]
        vis = mesh.visual
        if isinstance(vis, trimesh.visual.TextureVisuals) and vis.material is not None:
            color = np.asarray(vis.material.main_color, dtype=float)
        elif isinstance(vis, trimesh.visual.ColorVisuals) and vis.kind is not None:
            color = np.asarray(vis.main_color, dtype=float)
        else:
            return None
        V = trimesh.transform_points(np.asarray(mesh.vertices, dtype=float), T) * np.asarray(scale, dtype=float)
        parts.append((V, np.asarray(mesh.faces, dtype=np.int64), tuple((color / 255.0).tolist())))
    if not parts:
        return None
    every = np.vstack([V for V, _, _ in parts])
    size = float(np.max(np.ptp(vertices, axis=0))) or 1.0
    same = np.allclose(every.min(axis=0), vertices.min(axis=0), atol=1e-3 * size) and \
        np.allclose(every.max(axis=0), vertices.max(axis=0), atol=1e-3 * size)
    return parts if same else None


#: The drawn Mecanum chassis: its centre below the arm mount, its half height, the wheel axles below the mount [m].
_CHASSIS_Z, _CHASSIS_H, _AXLE_Z = -0.1, 0.06, -0.14


def floor_height(wheel_radius: float) -> float:
    """Height of the floor under the drawn Mecanum base (the wheels' lowest points) in the arm mount's frame [m]."""
    return _AXLE_Z - wheel_radius


def add_mecanum_base(add: GeomAdder, body, *, wheel_radius: float, half_length: float, half_width: float) -> float:
    """Chassis and four wheels of a Mecanum base on `body` (the yaw body, arm mount at its origin).

    Returns:
        z of the floor in the body frame [m] (`floor_height`).
    """
    add(body, _G.mjGEOM_BOX, pos=[0, 0, _CHASSIS_Z], size=[half_length + 0.06, half_width - 0.035, _CHASSIS_H],
        rgba=BASE_RGBA)
    zc = _AXLE_Z
    for sx in (-1, 1):
        for sy in (-1, 1):
            add(body, _G.mjGEOM_CYLINDER, pos=[sx * half_length, sy * half_width, zc],
                quat=_align_z(np.array([0.0, 1.0, 0.0])), size=[wheel_radius, 0.025, 0], rgba=WHEEL_RGBA)
    return floor_height(wheel_radius)


def add_floor(add: GeomAdder, spec: mujoco.MjSpec, z: float, half: float = 2.0) -> None:
    """A checker floor plane at height z [m] (visual; the material `add_scenery` made)."""
    g = add(spec.worldbody, _G.mjGEOM_PLANE, pos=[0, 0, z], size=[half, half, 0.05], rgba=(1, 1, 1, 1))
    g.material = FLOOR_MATERIAL


def add_scenery(spec: mujoco.MjSpec) -> None:
    """A light background, a head light, a light from above and the floor's checker material (`FLOOR_MATERIAL`)."""
    tex = spec.add_texture(name=FLOOR_MATERIAL, type=mujoco.mjtTexture.mjTEXTURE_2D,
                           builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=256, height=256,
                           rgb1=[0.82, 0.84, 0.86], rgb2=[0.74, 0.76, 0.78])
    mat = spec.add_material(name=FLOOR_MATERIAL, texrepeat=[8, 8])
    mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
    spec.add_texture(name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
                     width=64, height=64, rgb1=[1.0, 1.0, 1.0], rgb2=[0.86, 0.89, 0.93])
    hl = spec.visual.headlight
    hl.ambient, hl.diffuse, hl.specular = [0.45, 0.45, 0.45], [0.55, 0.55, 0.55], [0.1, 0.1, 0.1]
    spec.worldbody.add_light(name="top", pos=[0, 0, 3], dir=[0, 0, -1], diffuse=[0.4, 0.4, 0.4])
