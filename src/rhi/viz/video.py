"""Videos of a run: a log's motion drawn with MuJoCo's offscreen renderer, with its forces and environment.

`render_video` samples the log at the video's frame rate (frame k shows the last tick at or before
t₀ + k/fps, so a log of duration T gives round(T·fps) + 1 frames), poses the device, adds the
overlays to MuJoCo's scene as extra geoms — the hand force (magenta) and the environment force (red)
as arrows at the handle, a wall as a thin red slab; a planar device is seen from above — and encodes
H.264 MP4 with the ffmpeg binary that the `imageio-ffmpeg` wheel bundles (nothing to install on the system).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from rhi._validate import parent_made, writable_file
from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.sim.environment import Wall, from_description
from rhi.sim.log import Log
from rhi.viz.posed import Posed
from rhi.viz.render import frames

HAND_RGBA = (0.78, 0.12, 0.63, 1.0)
ENV_RGBA = (0.78, 0.16, 0.16, 1.0)


def frame_times(log: Log, fps: float) -> np.ndarray:
    """Times of the video's frames [s]: t₀, t₀ + 1/fps, … up to the log's last time."""
    t0, t1 = float(log.t[0]), float(log.t[-1])
    return t0 + np.arange(int(np.floor((t1 - t0) * fps + 1e-9)) + 1) / fps


class _Overlay:
    """Adds the log's forces and wall to a MuJoCo scene, in world coordinates at the handle."""

    def __init__(self, posed: Posed, log: Log, size: float, virtual) -> None:
        self.posed, self.log = posed, log
        self.rows = ["xyz".index(a) for a in posed.device.task_axes]
        f = np.nanmax(np.abs(np.concatenate([log.F_hand, log.F_env], axis=1)), initial=0.0)
        self.scale = 0.5 * size / max(float(f), 1.0)  # [m/N]: the largest force seen is half the device
        self.size = size
        parts = getattr(virtual, "parts", (virtual,)) if virtual is not None else ()
        self.walls = [w for w in parts if isinstance(w, Wall)]

    def _world(self, v: np.ndarray, z: float) -> np.ndarray:
        out = np.array([0.0, 0.0, z])
        out[self.rows] = v
        return out

    def add(self, scene, k: int) -> None:
        handle = self.posed.data.xpos[self.posed.handle]
        for F, rgba in ((self.log.F_hand[k], HAND_RGBA), (self.log.F_env[k], ENV_RGBA)):
            tip = handle + self.scale * self._world(np.nan_to_num(F), 0.0)
            if np.linalg.norm(tip - handle) > 1e-4 and scene.ngeom < scene.maxgeom:
                g = scene.geoms[scene.ngeom]
                mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                                    np.array(rgba, dtype=np.float32))
                mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_ARROW, 0.03 * self.size, handle, tip)
                scene.ngeom += 1
        for w in self.walls:
            if scene.ngeom >= scene.maxgeom:
                break
            n = self._world(w.normal, 0.0)
            p = self._world(w.point, float(handle[2]))
            R = np.eye(3)
            R[:, 2] = n / np.linalg.norm(n)  # the slab's thin axis along the normal
            R[:, 0] = np.cross([0.0, 0.0, 1.0], R[:, 2]) if abs(R[2, 2]) < 0.9 else [1.0, 0.0, 0.0]
            R[:, 0] /= np.linalg.norm(R[:, 0])
            R[:, 1] = np.cross(R[:, 2], R[:, 0])
            half = (0.45 * self.size, 0.45 * self.size, 0.002 * self.size)
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_BOX, np.array(half),
                                p + R[:, 2] * half[2], R.ravel(), np.array((0.78, 0.16, 0.16, 0.35), dtype=np.float32))
            scene.ngeom += 1


def render_video(device: Device, log: Log, path, *, fps: float = 30.0, width: int = 640, height: int = 480,
                 virtual=None, progress=None) -> Path:
    """Write the run in `log` as an MP4 video.

    Args:
        device: the device the log was recorded on.
        log: the run (`Log.load` of a `.rhilog` or CSV).
        path: the output file (`.mp4`).
        fps: frames per second of the video (and of the sampling of the log).
        width: frame width [pixels] (even: H.264's 4:2:0).
        height: frame height [pixels] (even).
        virtual: the environment to draw (default: the one stored in the log's header).
        progress: called with (frames written, frames in all) after each frame, or None.

    Returns:
        The path written.

    Raises:
        InvalidInput: a log of another device, an fps outside (0, 240], an odd frame size, a path not ending .mp4.
    """
    p = writable_file("path", path, suffix=".mp4")  # before any frame is drawn
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not 0 < fps <= 240:
        raise InvalidInput(f"fps: expected frames per second in (0, 240], got {fps!r}")
    if width % 2 or height % 2:
        raise InvalidInput(f"width, height: H.264 needs even frame sizes, got {width}×{height}")
    if not isinstance(log, Log) or len(log) == 0 or log.q.shape[1:] != (device.n,):
        raise InvalidInput(f"log: expected a run of {device.name} ({device.n} motors) with at least one tick")
    import imageio_ffmpeg

    virtual = virtual if virtual is not None else from_description(log.meta.get("environment"))
    times = frame_times(log, float(fps))
    idx = np.maximum(np.searchsorted(log.t, times + 1e-9, side="right") - 1, 0)
    posed = Posed(device)
    posed.set(log.q[0])
    lo, hi = posed.bounds()
    overlay = _Overlay(posed, log, float(np.max(hi - lo)), virtual)
    writer = imageio_ffmpeg.write_frames(str(parent_made(p)), (int(width), int(height)), fps=float(fps), quality=7,
                                         macro_block_size=2, ffmpeg_log_level="error")
    writer.send(None)
    try:
        planar = set(device.task_axes) <= {"x", "y"}  # seen from above: the task plane, forces and wall in it
        for i, img in enumerate(frames(posed, log.q[idx], width=width, height=height, azimuth=-90.0 if planar else None,
                                       elevation=-85.0 if planar else None,
                                       decorate=lambda scene, j: overlay.add(scene, int(idx[j])))):
            writer.send(np.ascontiguousarray(img))
            if progress is not None:
                progress(i + 1, len(idx))
    finally:
        writer.close()
    return p
