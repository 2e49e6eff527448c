"""`Recorder`: the view's record button — what the page showed, written as an MP4 video when recording stops.

While recording, each frame the view draws adds its snapshot (t, q, τ, the hand and environment
forces, V, α, β); stopping turns them into a `Log` and writes it with `rhi.viz.video.render_video`
(MuJoCo offscreen, the forces and the environment drawn) in a background thread, so the view keeps
drawing. A time that goes back (a reset, a replay seek) starts the recording's log afresh.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np

from rhi.devices.model import Device
from rhi.sim.environment import describe
from rhi.sim.log import Log


class Recorder:
    """Collects the view's snapshots and writes them as a video.

    Args:
        device: the device drawn.
        folder: where videos go (``view-YYYYmmdd-HHMMSS.mp4``).
        virtual: the environment drawn in the video (the view's), or None.

    Attributes:
        recording: whether frames are being collected.
        status: a line for the page ("recording: 42 frames", "writing …", "saved: PATH", an error).
        last: the path of the last video written, or None.
    """

    def __init__(self, device: Device, folder="out", *, virtual=None) -> None:
        self.device, self.folder, self.virtual = device, Path(folder), virtual
        self.recording = False
        self.status = ""
        self.last: Path | None = None
        self._rows: list[tuple] = []
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start collecting frames (a recording in progress starts afresh)."""
        self._rows, self.recording, self.status = [], True, "recording: 0 frames"

    def add(self, snap) -> None:
        """Add the frame the view just drew (ignored unless recording)."""
        if not self.recording:
            return
        if self._rows and float(snap.t) < self._rows[-1][0]:
            self._rows = []
        z = np.zeros(self.device.m)
        g = lambda k: float(getattr(snap, k, np.nan))  # noqa: E731
        self._rows.append((float(snap.t), np.array(snap.q, dtype=float), np.array(snap.tau, dtype=float),
                           np.array(getattr(snap, "F_hand", z), dtype=float),
                           np.array(getattr(snap, "F_env", z), dtype=float), g("V"), g("alpha"), g("beta")))
        self.status = f"recording: {len(self._rows)} frames"

    def stop(self) -> threading.Thread | None:
        """Stop and write the video in a background thread (returned; None when fewer than two frames)."""
        self.recording = False
        rows, self._rows = self._rows, []
        if len(rows) < 2:
            self.status = "nothing recorded"
            return None
        path = self.folder / time.strftime("view-%Y%m%d-%H%M%S.mp4")
        self.status = f"writing {path} …"
        self._thread = threading.Thread(target=self._write, args=(rows, path), daemon=True, name="rhi-record")
        self._thread.start()
        return self._thread

    def _write(self, rows: list[tuple], path: Path) -> None:
        from rhi.viz.video import render_video

        t, q, tau, Fh, Fe, V, a, b = (np.array(c) for c in zip(*rows))
        k, n, m = len(t), self.device.n, self.device.m
        log = Log(t=t, q=q, dq=np.zeros((k, n)), tau=tau, x=np.zeros((k, m)), xdot=np.zeros((k, m)), F_hand=Fh,
                  F_env=Fe, ft=np.zeros((k, 6)), work=np.zeros(k), V=V, omega=np.full(k, np.nan), alpha=a, beta=b,
                  slave_x=np.zeros((k, 0)))
        log.meta = {"device": self.device.name, "environment": describe(self.virtual), "source": "rhi view"}
        try:
            self.last = render_video(self.device, log, path)
            self.status = f"saved: {self.last}"
        except Exception as exc:  # noqa: BLE001 - a failed video must not stop the view; the page says why
            self.status = f"video not written: {type(exc).__name__}: {exc}"
