"""Offscreen pictures of a device with MuJoCo's renderer.

MuJoCo picks its OpenGL backend from the environment variable ``MUJOCO_GL`` when it is first
imported: ``egl`` (GPU or Mesa's EGL), ``osmesa`` (software, Debian package ``libosmesa6``) or
``glfw`` (a display). `import rhi` picks osmesa or egl on a machine without a display where
``MUJOCO_GL`` is unset (`rhi._gl`). Without a usable backend `render` raises `RenderUnavailable` saying so.
"""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from rhi._gl import has_display
from rhi.device import Device
from rhi.errors import InvalidInput, RhiError
from rhi.viz.posed import Posed


class RenderUnavailable(RhiError):
    """No OpenGL backend could be created for offscreen rendering."""


def _camera(posed: Posed, azimuth: float | None, elevation: float | None) -> mujoco.MjvCamera:
    lo, hi = posed.bounds()
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
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 16 <= v <= 8192:
            raise InvalidInput(f"{name}: expected an integer number of pixels in [16, 8192], got {v!r}")
    posed = device if isinstance(device, Posed) else Posed(device)
    posed.set(q)
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
        renderer.update_scene(posed.data, camera=_camera(posed, azimuth, elevation), scene_option=opt)
        return renderer.render().copy()
    finally:
        renderer.close()


def save_png(image: np.ndarray, path) -> Path:
    """Write an RGB image (H, W, 3) uint8 as PNG; returns the path."""
    from PIL import Image

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.asarray(image, dtype=np.uint8)).save(p)
    return p
