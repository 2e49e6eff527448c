"""The device in a viser scene: MuJoCo's visual geometry as meshes, one frame per moving body, on a floor.

The geometry is built once (`DeviceScene`); each update sets only the pose of every body
frame (a few hundred bytes to the browser), from `mj_kinematics` of the configuration.
MuJoCo's tree is the device's serial chain; the links of its parallelograms that the chain leaves out
(`rhi.viz.posed.Posed.linkages`: the Quanser arm's and the PHANToM's of the rhi4) are drawn too, each a
capsule on a frame of its own placed at every update.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import trimesh

from rhi.sim.geometry import LINK_RGBA, geom_rgba, link_radius
from rhi.viz.posed import Posed

_G = mujoco.mjtGeom
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


def z_to(v: np.ndarray) -> np.ndarray:
    """The rotation (4,) wxyz that turns the z axis onto the direction of v (3,)."""
    quat = np.zeros(4)
    mujoco.mju_quatZ2Vec(quat, np.asarray(v, dtype=float))
    return quat


class DeviceScene:
    """A device drawn in a viser scene under `root`.

    Args:
        server: the `viser.ViserServer`.
        posed: the device's drawable MuJoCo model (at the pose drawn first).
        root: scene-node prefix.

    Attributes:
        frames: {body id: viser frame handle} of the bodies that move.
        meshes: {scene name: mesh handle} of every part drawn (its `color` is the part's).
        links: per segment of `Posed.linkages`, the frame its capsule hangs from (at the segment's start, z along it).
        floor: z of the floor [m] (a plate with a grid is drawn there).
    """

    def __init__(self, server, posed: Posed, root: str = "/device") -> None:
        self.server, self.posed, self.root = server, posed, root
        m = posed.model
        moving = {b for b in range(1, m.nbody) if m.body_weldid[b] != 0}
        self.frames: dict[int, Any] = {}
        self.meshes: dict[str, Any] = {}
        self._bodies = np.array(sorted(moving), dtype=int)
        mujoco.mj_kinematics(m, posed.data)
        for g in range(m.ngeom):
            b = int(m.geom_bodyid[g])
            if m.geom_type[g] == _G.mjGEOM_PLANE:  # drawn as the floor's plate and grid
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
        r = 0.6 * link_radius(posed.device)
        self.links = []
        for k, (a, b) in enumerate(posed.linkages()):  # rigid links: their lengths at the first pose hold
            self.links.append(server.scene.add_frame(f"{root}/link{k}", show_axes=False))
            length = float(np.linalg.norm(b - a))
            capsule = trimesh.creation.capsule(height=length, radius=r, count=[12, 12])
            capsule.apply_translation([0.0, 0.0, 0.5 * length])
            self._mesh(f"{root}/link{k}/capsule", capsule, LINK_RGBA)
        self._pose_links()
        lo, hi = posed.bounds()
        self.floor = posed.floor()
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

    def _pose_links(self) -> None:
        for frame, (a, b) in zip(self.links, self.posed.linkages()):
            frame.position, frame.wxyz = a, z_to(b - a)

    def update(self, q) -> None:
        """Move the bodies to configuration q: (n,) [rad or m] (call it inside `server.atomic()`)."""
        self.posed.set(q)
        d = self.posed.data
        for b, frame in self.frames.items():
            frame.position = d.xpos[b]
            frame.wxyz = d.xquat[b]
        self._pose_links()

    def set_visible(self, visible: bool) -> None:
        """Show or hide the device's geometry."""
        for frame in self.frames.values():
            frame.visible = bool(visible)
        for frame in self.links:
            frame.visible = bool(visible)

    def handle_position(self) -> np.ndarray:
        """World position of the handle at the last update: (3,) [m]."""
        return self.posed.data.xpos[self.posed.handle].copy()
