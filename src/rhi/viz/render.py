"""Offscreen pictures of a device with MuJoCo's renderer.

MuJoCo picks its OpenGL backend from the environment variable ``MUJOCO_GL`` when it is first
imported: ``egl`` (GPU or Mesa's EGL), ``osmesa`` (software, Debian package ``libosmesa6``) or
``glfw`` (a display). `import rhi` picks osmesa or egl on a machine without a display where
``MUJOCO_GL`` is unset (`rhi._gl`). Without a usable backend `render` raises `RenderUnavailable` saying so.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import mujoco
import numpy as np

from rhi._gl import has_display
from rhi._validate import as_array, parent_made, writable_file
from rhi.devices.model import Device
from rhi.errors import InvalidInput, RhiError
from rhi.sim.geometry import FLOOR_MATERIAL, LINK_RGBA, link_radius
from rhi.viz.posed import Posed


class RenderUnavailable(RhiError):
    """No OpenGL backend could be created for offscreen rendering."""


def _span(posed: Posed, Q) -> tuple[np.ndarray, np.ndarray]:
    """The box (3,), (3,) [m] around the drawn device over up to 20 poses of Q: (k, n) (left at Q[0])."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for q in Q[np.linspace(0, len(Q) - 1, min(20, len(Q))).astype(int)]:
        posed.set(q)
        a, b = posed.bounds()
        lo, hi = np.minimum(lo, a), np.maximum(hi, b)
    posed.set(Q[0])
    return lo, hi


def _camera(posed: Posed, azimuth: float | None, elevation: float | None, lo: np.ndarray,
            hi: np.ndarray) -> mujoco.MjvCamera:
    """A free camera framing the box lo, hi: (3,), (3,) [m]."""
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = 0.5 * (lo + hi)
    cam.distance = 1.45 * max(float(np.linalg.norm(hi - lo)), 0.05)
    planar = set(posed.device.task_axes) <= {"x", "y"}
    cam.azimuth = -60.0 if azimuth is None else float(azimuth)
    cam.elevation = (-60.0 if planar else -22.0) if elevation is None else float(elevation)
    return cam


def _check_backend() -> None:
    """Refuse glfw without a display with a clear error (inside MuJoCo it would abort the process)."""
    gl = os.environ.get("MUJOCO_GL", "").lower()
    if gl in ("", "glfw") and not has_display():
        raise RenderUnavailable("no OpenGL backend for offscreen rendering: MuJoCo uses glfw (MUJOCO_GL unset) and "
                                "there is no display; set MUJOCO_GL=egl (a GPU or Mesa's EGL) or MUJOCO_GL=osmesa "
                                "(software: apt-get install libosmesa6) before starting Python")


def _size(width, height) -> None:
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 16 <= v <= 8192:
            raise InvalidInput(f"{name}: expected an integer number of pixels in [16, 8192], got {v!r}")


def frames(posed: Posed, Q, *, width: int = 800, height: int = 600, azimuth: float | None = None,
           elevation: float | None = None, decorate=None) -> Iterator[np.ndarray]:
    """RGB pictures of the device at each configuration of Q: (k, n), from one renderer and one camera.

    Args:
        posed: the drawable device.
        Q: (k, n) motor coordinates [rad or m].
        width: image width [pixels].
        height: image height [pixels].
        azimuth: camera azimuth [deg]; None: a three-quarter view framing every pose of Q.
        elevation: camera elevation [deg]; None: as for `azimuth`.
        decorate: called as decorate(scene, i) after the scene of pose i is built, to add geoms (overlays).

    Yields:
        (height, width, 3) uint8 images.

    Raises:
        RenderUnavailable: no OpenGL backend (names MUJOCO_GL and how to get one).
        InvalidInput: a bad Q or image size.
    """
    _size(width, height)
    Q = as_array("Q", Q, shape_tail=(None, posed.device.n))
    m = posed.model
    m.vis.global_.offwidth = max(int(m.vis.global_.offwidth), int(width))
    m.vis.global_.offheight = max(int(m.vis.global_.offheight), int(height))
    _check_backend()
    try:
        renderer = mujoco.Renderer(m, int(height), int(width))
    except Exception as exc:  # ImportError, RuntimeError or mujoco.FatalError, depending on the backend
        gl = os.environ.get("MUJOCO_GL", "")
        raise RenderUnavailable(
            f"no OpenGL backend for offscreen rendering (MUJOCO_GL={gl!r}: {exc}); set MUJOCO_GL=egl (a GPU or "
            "Mesa's EGL) or MUJOCO_GL=osmesa (software: apt-get install libosmesa6) before starting Python") from None
    try:
        opt = mujoco.MjvOption()
        opt.geomgroup[:] = 1
        lo, hi = _span(posed, Q)
        cam = _camera(posed, azimuth, elevation, lo, hi)
        floor = None if (m.geom_type == mujoco.mjtGeom.mjGEOM_PLANE).any() else posed.floor(float(lo[2]))
        for i, q in enumerate(Q):
            posed.set(q)
            renderer.update_scene(posed.data, camera=cam, scene_option=opt)
            if floor is not None:
                add_floor(renderer.scene, posed, floor, float(np.max(hi - lo)), 0.5 * (lo + hi))
            add_linkages(renderer.scene, posed)
            if decorate is not None:
                decorate(renderer.scene, i)
            yield renderer.render().copy()
    finally:
        renderer.close()


def add_floor(scene: mujoco.MjvScene, posed: Posed, z: float, size: float, centre: np.ndarray) -> None:
    """Add a checker floor at height z [m] under a device of `size` [m] centred at `centre` (3,) to a scene.

    As the browser's (`rhi.viz.scene.DeviceScene`): 40 cells of 10^⌊log10(size/4)⌋ m a side.
    """
    if scene.ngeom >= scene.maxgeom:
        return
    cell = 10 ** np.floor(np.log10(max(size, 1e-3) / 4))
    g = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_PLANE, np.array([20 * cell, 20 * cell, cell]),
                        np.array([centre[0], centre[1], z]), np.eye(3).ravel(), np.ones(4, dtype=np.float32))
    g.matid = posed.model.material(FLOOR_MATERIAL).id
    scene.ngeom += 1


def add_linkages(scene: mujoco.MjvScene, posed: Posed) -> None:
    """Add the parallelograms' links the serial chain leaves out (`Posed.linkages`) to a scene, as capsules."""
    r = 0.6 * link_radius(posed.device)
    for a, b in posed.linkages():
        if scene.ngeom >= scene.maxgeom:
            return
        g = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                            np.array(LINK_RGBA, dtype=np.float32))
        mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_CAPSULE, r, a, b)
        scene.ngeom += 1


def render(device: Device | Posed, q, *, width: int = 800, height: int = 600, azimuth: float | None = None,
           elevation: float | None = None) -> np.ndarray:
    """An RGB picture of the device at configuration q.

    Args:
        device: the device (or an already built `Posed`).
        q: (n,) motor coordinates [rad or m].
        width: image width [pixels].
        height: image height [pixels].
        azimuth: camera azimuth [deg]; None: a three-quarter view (from above for planar devices).
        elevation: camera elevation [deg]; None: as for `azimuth`.

    Returns:
        (height, width, 3) uint8 image.

    Raises:
        RenderUnavailable: no OpenGL backend (names MUJOCO_GL and how to get one).
        InvalidInput: a bad q or image size.
    """
    _size(width, height)
    posed = device if isinstance(device, Posed) else Posed(device)
    q = as_array("q", q, shape_tail=(posed.device.n,))
    if q.ndim != 1:
        raise InvalidInput(f"q: expected shape ({posed.device.n},), got {q.shape}")
    return next(frames(posed, q[None], width=width, height=height, azimuth=azimuth, elevation=elevation))


def save_png(image: np.ndarray, path) -> Path:
    """Write an RGB image (H, W, 3) uint8 as PNG; returns the path.

    Raises:
        InvalidInput: `path` does not end in .png, is a folder, or cannot be written.
    """
    from PIL import Image

    p = writable_file("out", path, suffix=".png")
    Image.fromarray(np.asarray(image, dtype=np.uint8)).save(parent_made(p))
    return p



