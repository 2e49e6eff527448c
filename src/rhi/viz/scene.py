"""The device in a viser scene: MuJoCo's visual geometry as meshes, one frame per moving body, on a floor.

The geometry is built once (`DeviceScene`); each update sets only the pose of every body
frame (a few hundred bytes to the browser), from `mj_kinematics` of the configuration.
MuJoCo's tree is the device's serial chain; a link driven through a parallelogram (`parallelograms`:
the Quanser arm and the PHANToM of the rhi4) also gets the parallelogram's crank, coupler and the
link's rear extension, posed from the chain at every update.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import trimesh

from rhi.sim.geometry import LINK_RGBA, joint_axis, link_radius
from rhi.viz.posed import Posed

_G = mujoco.mjtGeom
#: a parallelogram's crank as a fraction of the link it parallels
CRANK = 0.3
#: the floor's colour (RGB 0..255) under the grid
FLOOR_RGB = (222, 226, 231)


def geom_mesh(model: mujoco.MjModel, g: int) -> trimesh.Trimesh | None:
    """Mesh of MuJoCo geom g in its own frame (None for planes, drawn as a grid instead)."""
    kind, size = model.geom_type[g], model.geom_size[g]
    if kind == _G.mjGEOM_CAPSULE:
        return trimesh.creation.capsule(height=2 * size[1], radius=size[0], count=[16, 16])
    if kind == _G.mjGEOM_CYLINDER:
        return trimesh.creation.cylinder(radius=size[0], height=2 * size[1], sections=24)
    if kind == _G.mjGEOM_BOX:
        return trimesh.creation.box(extents=2 * size)
    if kind == _G.mjGEOM_SPHERE:
        return trimesh.creation.icosphere(subdivisions=2, radius=size[0])
    if kind == _G.mjGEOM_ELLIPSOID:
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        mesh.apply_scale(size)
        return mesh
    if kind == _G.mjGEOM_MESH:
        i = model.geom_dataid[g]
        va, vn = model.mesh_vertadr[i], model.mesh_vertnum[i]
        fa, fn = model.mesh_faceadr[i], model.mesh_facenum[i]
        return trimesh.Trimesh(model.mesh_vert[va:va + vn].copy(), model.mesh_face[fa:fa + fn].copy(), process=False)
    return None


def geom_rgba(model: mujoco.MjModel, g: int) -> np.ndarray:
    """Colour (4,) of geom g as MuJoCo draws it: its material's where it has one and keeps the default rgba."""
    mat = int(model.geom_matid[g])
    if mat >= 0 and np.allclose(model.geom_rgba[g], [0.5, 0.5, 0.5, 1.0]):
        return model.mat_rgba[mat]
    return model.geom_rgba[g]


def parallelograms(device) -> list[tuple[int, int]]:
    """Chain joints (p, j) whose link j is driven through a parallelogram from joint p's axis.

    The actuation map says so: θ_p = q_a and θ_j = q_b − q_a with parallel hinge axes, so the motor b sets
    link j's absolute angle from the base (thesis §3.5: the Quanser arm and the PHANToM 1.5A of the rhi4).
    """
    model, A = device.model, np.asarray(device.A, dtype=float)
    out = []
    for j in range(2, model.njoints):
        p = int(model.parents[j])
        if p == 0 or list(model.parents).count(p) != 1:  # a branch at p: the chain models its linkage itself
            continue
        rp, rj = A[model.joints[p].idx_v], A[model.joints[j].idx_v]
        a = np.flatnonzero(rp)
        if len(a) != 1 or rp[a[0]] != 1.0 or rj[a[0]] != -1.0 or np.count_nonzero(rj) != 2 or rj.sum() != 0.0:
            continue
        (kp, ap), (kj, aj) = joint_axis(model.joints[p]), joint_axis(model.joints[j])
        if kp == kj == "hinge" and abs(abs(float(ap @ (model.jointPlacements[j].rotation @ aj))) - 1.0) < 1e-9:
            out.append((p, j))
    return out


def _segment(a: np.ndarray, b: np.ndarray, r: float) -> trimesh.Trimesh:
    """A capsule of radius r [m] from point a to point b (3,) [m]."""
    v = np.asarray(b, dtype=float) - np.asarray(a, dtype=float)
    mesh = trimesh.creation.capsule(height=float(np.linalg.norm(v)), radius=r, count=[12, 12])
    T = trimesh.geometry.align_vectors([0.0, 0.0, 1.0], v)
    T[:3, 3] = 0.5 * (np.asarray(a) + np.asarray(b))
    mesh.apply_transform(T)
    return mesh


class DeviceScene:
    """A device drawn in a viser scene under `root`.

    Args:
        server: the `viser.ViserServer`.
        posed: the device's drawable MuJoCo model (at the pose drawn first).
        root: scene-node prefix.

    Attributes:
        frames: {body id: viser frame handle} of the bodies that move.
        meshes: {scene name: mesh handle} of every part drawn (its `color` is the part's).
        linkages: per parallelogram, (body of joint p, body of joint j, crank (3,) in j's frame [m], crank frame,
            coupler frame).
        floor: z of the floor [m] (a plate with a grid is drawn there).
    """

    def __init__(self, server, posed: Posed, root: str = "/device") -> None:
        self.server, self.posed, self.root = server, posed, root
        m = posed.model
        moving = {b for b in range(1, m.nbody) if m.body_weldid[b] != 0}
        self.frames: dict[int, Any] = {}
        self.meshes: dict[str, Any] = {}
        self._bodies = np.array(sorted(moving), dtype=int)
        floor = None
        mujoco.mj_kinematics(m, posed.data)
        for g in range(m.ngeom):
            b = int(m.geom_bodyid[g])
            if m.geom_type[g] == _G.mjGEOM_PLANE:
                floor = float(m.geom_pos[g][2])
                continue
            mesh = geom_mesh(m, g)
            if mesh is None:
                continue
            if b not in moving:  # static geometry: its world pose
                pos, quat = posed.data.geom_xpos[g].copy(), np.zeros(4)
                mujoco.mju_mat2Quat(quat, posed.data.geom_xmat[g])
            else:
                pos, quat = m.geom_pos[g], m.geom_quat[g]
            self._mesh(f"{self._parent(b, moving)}/g{g}", mesh, geom_rgba(m, g), pos, quat)
        self.linkages = [self._linkage(k, p, j, moving) for k, (p, j) in enumerate(parallelograms(posed.device))]
        lo, hi = posed.bounds()
        self.floor = floor if floor is not None else float(lo[2]) - 0.02
        size = float(np.max(hi - lo))
        cell = 10 ** np.floor(np.log10(max(size, 1e-3) / 4))
        centre = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]))
        server.scene.add_box(f"{root}/floor", color=FLOOR_RGB, dimensions=(40 * cell, 40 * cell, 0.1 * cell),
                             position=(*centre, self.floor - 0.06 * cell), cast_shadow=False)
        server.scene.add_grid(f"{root}/grid", width=40 * cell, height=40 * cell, cell_size=cell,
                              section_size=5 * cell, position=(*centre, self.floor))

    def _parent(self, b: int, moving: set[int]) -> str:
        """The scene node a body's geometry hangs from (a frame per moving body, made on first use)."""
        if b not in moving:
            return f"{self.root}/static"
        if b not in self.frames:
            self.frames[b] = self.server.scene.add_frame(f"{self.root}/b{b}", show_axes=False)
        return f"{self.root}/b{b}"

    def _mesh(self, name: str, mesh: trimesh.Trimesh, rgba, pos=(0.0, 0.0, 0.0), quat=(1.0, 0.0, 0.0, 0.0)) -> None:
        self.meshes[name] = self.server.scene.add_mesh_simple(
            name, mesh.vertices.astype(np.float32), mesh.faces.astype(np.uint32),
            color=tuple(int(round(255 * float(c))) for c in rgba[:3]), position=tuple(pos), wxyz=tuple(quat))

    def _linkage(self, k: int, p: int, j: int, moving: set[int]) -> tuple:
        """Draw parallelogram k at joints (p, j): the crank at p, the coupler parallel to link p, j's rear extension."""
        model, dev, d = self.posed.model, self.posed.device, self.posed.data
        bp, bj = (model.body(f"b_{dev.model.names[i]}").id for i in (p, j))
        children = [i for i in range(1, dev.model.njoints) if dev.model.parents[i] == j]
        end = model.body(f"b_{dev.model.names[children[0]]}").id if children else self.posed.handle
        O, P, C = d.xpos[bp], d.xpos[bj], d.xpos[end]
        Rp, Rj = d.xmat[bp].reshape(3, 3), d.xmat[bj].reshape(3, 3)
        crank = -CRANK * float(np.linalg.norm(P - O)) * (Rj.T @ (C - P)) / float(np.linalg.norm(C - P))
        r = 0.6 * link_radius(dev)
        zero = np.zeros(3)
        self._mesh(f"{self._parent(bj, moving)}/para{k}_rear", _segment(zero, crank, r), LINK_RGBA)
        crank_frame = self.server.scene.add_frame(f"{self.root}/para{k}_crank", show_axes=False)
        self._mesh(f"{self.root}/para{k}_crank/link", _segment(zero, crank, r), LINK_RGBA)
        coupler_frame = self.server.scene.add_frame(f"{self.root}/para{k}_coupler", show_axes=False)
        self._mesh(f"{self.root}/para{k}_coupler/link", _segment(zero, Rp.T @ (P - O), r), LINK_RGBA)
        link = (bp, bj, crank, crank_frame, coupler_frame)
        self._pose_linkage(link)
        return link

    def _pose_linkage(self, link: tuple) -> None:
        bp, bj, crank, crank_frame, coupler_frame = link
        d = self.posed.data
        crank_frame.position, crank_frame.wxyz = d.xpos[bp], d.xquat[bj]
        coupler_frame.position = d.xpos[bp] + d.xmat[bj].reshape(3, 3) @ crank
        coupler_frame.wxyz = d.xquat[bp]

    def update(self, q) -> None:
        """Move the bodies to configuration q: (n,) [rad or m] (call it inside `server.atomic()`)."""
        self.posed.set(q)
        d = self.posed.data
        for b, frame in self.frames.items():
            frame.position = d.xpos[b]
            frame.wxyz = d.xquat[b]
        for link in self.linkages:
            self._pose_linkage(link)

    def set_visible(self, visible: bool) -> None:
        """Show or hide the device's geometry."""
        for frame in self.frames.values():
            frame.visible = bool(visible)
        for link in self.linkages:
            link[3].visible = link[4].visible = bool(visible)

    def handle_position(self) -> np.ndarray:
        """World position of the handle at the last update: (3,) [m]."""
        return self.posed.data.xpos[self.posed.handle].copy()
