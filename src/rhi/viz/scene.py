"""The device in a viser scene: MuJoCo's visual geometry as meshes, one frame per moving body.

The geometry is built once (`DeviceScene`); each update sets only the pose of every body
frame (a few hundred bytes to the browser), from `mj_kinematics` of the configuration.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np
import trimesh

from rhi.viz.posed import Posed

_G = mujoco.mjtGeom


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


class DeviceScene:
    """A device drawn in a viser scene under `root`.

    Args:
        server: the `viser.ViserServer`.
        posed: the device's drawable MuJoCo model.
        root: scene-node prefix.

    Attributes:
        frames: {body id: viser frame handle} of the bodies that move.
        floor: z of the floor [m] (a grid is drawn there).
    """

    def __init__(self, server, posed: Posed, root: str = "/device") -> None:
        self.server, self.posed, self.root = server, posed, root
        m = posed.model
        moving = {b for b in range(1, m.nbody) if m.body_weldid[b] != 0}
        self.frames: dict[int, Any] = {}
        self._bodies = np.array(sorted(moving), dtype=int)
        floor = None
        for g in range(m.ngeom):
            b = int(m.geom_bodyid[g])
            if m.geom_type[g] == _G.mjGEOM_PLANE:
                floor = float(m.geom_pos[g][2])
                continue
            mesh = geom_mesh(m, g)
            if mesh is None:
                continue
            parent = f"{root}/b{b}" if b in moving else f"{root}/static"
            if b in moving and b not in self.frames:
                self.frames[b] = server.scene.add_frame(parent, show_axes=False)
            if b not in moving:  # static geometry: its world pose
                mujoco.mj_kinematics(m, posed.data)
                pos, quat = posed.data.geom_xpos[g].copy(), np.zeros(4)
                mujoco.mju_mat2Quat(quat, posed.data.geom_xmat[g])
            else:
                pos, quat = m.geom_pos[g], m.geom_quat[g]
            rgba = m.geom_rgba[g]
            server.scene.add_mesh_simple(f"{parent}/g{g}", mesh.vertices.astype(np.float32),
                                         mesh.faces.astype(np.uint32), color=tuple(int(255 * c) for c in rgba[:3]),
                                         position=tuple(pos), wxyz=tuple(quat))
        lo, hi = posed.bounds()
        self.floor = floor if floor is not None else float(lo[2]) - 0.02
        size = float(np.max(hi - lo))
        cell = 10 ** np.floor(np.log10(max(size, 1e-3) / 4))
        server.scene.add_grid(f"{root}/grid", width=40 * cell, height=40 * cell, cell_size=cell,
                              section_size=5 * cell, position=(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), self.floor))

    def update(self, q) -> None:
        """Move the bodies to configuration q: (n,) [rad or m] (call it inside `server.atomic()`)."""
        self.posed.set(q)
        d = self.posed.data
        for b, frame in self.frames.items():
            frame.position = d.xpos[b]
            frame.wxyz = d.xquat[b]

    def set_visible(self, visible: bool) -> None:
        """Show or hide the device's geometry."""
        for frame in self.frames.values():
            frame.visible = bool(visible)

    def handle_position(self) -> np.ndarray:
        """World position of the handle at the last update: (3,) [m]."""
        return self.posed.data.xpos[self.posed.handle].copy()
