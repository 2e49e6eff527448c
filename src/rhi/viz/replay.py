"""`LogPlayer`: a saved run played back at real speed, with the same `latest()` as `rhi.runtime.Telemetry`."""

from __future__ import annotations

import threading
import time
import types
from typing import Any

import numpy as np

from rhi.errors import InvalidInput
from rhi.sim.log import Log

_FIELDS = ("t", "q", "dq", "tau", "x", "xdot", "F_hand", "F_env", "V", "omega", "alpha", "beta")


class LogPlayer:
    """Plays a `Log` (from `simulate`, `rhi.runtime.run` or `Log.load`) against the wall clock.

    Args:
        log: the run.
        speed: playback speed (1: real time).

    Attributes:
        playing: whether the time advances.
    """

    def __init__(self, log: Log, *, speed: float = 1.0) -> None:
        if not isinstance(log, Log) or len(log) == 0:
            raise InvalidInput("log: expected a Log with at least one tick")
        if not np.isfinite(speed) or speed <= 0:
            raise InvalidInput(f"speed: must be > 0, got {speed!r}")
        self.log, self.speed = log, float(speed)
        self.t0, self.t1 = float(log.t[0]), float(log.t[-1])
        self.playing = False
        self._lock = threading.Lock()
        self._anchor = (self.t0, time.monotonic())

    @property
    def time(self) -> float:
        """The playback time [s] (a time of the log)."""
        with self._lock:
            t, wall = self._anchor
            if self.playing:
                t += (time.monotonic() - wall) * self.speed
                if t >= self.t1:
                    t, self.playing = self.t1, False
                    self._anchor = (t, time.monotonic())
            return min(max(t, self.t0), self.t1)

    def seek(self, t: float) -> None:
        """Go to log time t [s] (clipped to the run)."""
        if not np.isfinite(t):
            raise InvalidInput(f"t: must be finite, got {t!r}")
        with self._lock:
            self._anchor = (min(max(float(t), self.t0), self.t1), time.monotonic())

    def play(self) -> None:
        """Start (or restart at the end) playing at `speed`."""
        t = self.time
        with self._lock:
            self._anchor = (self.t0 if t >= self.t1 else t, time.monotonic())
            self.playing = True

    def pause(self) -> None:
        """Stop at the current time."""
        t = self.time
        with self._lock:
            self.playing = False
            self._anchor = (t, time.monotonic())

    def index(self, t: float) -> int:
        """The last tick at or before log time t."""
        return max(int(np.searchsorted(self.log.t, t, side="right")) - 1, 0)

    def latest(self) -> types.SimpleNamespace:
        """The tick at the playback time, as a telemetry snapshot (plus `safety` and `fault`)."""
        log = self.log
        k = self.index(self.time)
        snap: dict[str, Any] = {f: (np.asarray(getattr(log, f)[k]).copy() if np.ndim(getattr(log, f)) > 1 else
                    float(getattr(log, f)[k])) for f in _FIELDS}
        bad = log.safety is not None and np.isfinite(log.safety[k]) and log.safety[k] == 1.0
        snap["safety"] = "fault" if bad else "ok"
        snap["fault"] = log.fault if bad else None
        return types.SimpleNamespace(**snap)
