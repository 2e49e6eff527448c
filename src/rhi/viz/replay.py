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


#: the playback speeds the view offers (× real time); a player accepts any speed between the first and the last
SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0)


def _speed(v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not SPEEDS[0] <= v <= SPEEDS[-1]:
        raise InvalidInput(f"speed: must be within {SPEEDS[0]}..{SPEEDS[-1]} (× real time), got {v!r}")
    return float(v)


class LogPlayer:
    """Plays a `Log` (from `simulate`, `rhi.runtime.run` or `Log.load`) against the wall clock; starts paused.

    Args:
        log: the run.
        speed: playback speed, 0.1–4 (1: real time).

    Attributes:
        playing: whether the time advances.
    """

    def __init__(self, log: Log, *, speed: float = 1.0) -> None:
        if not isinstance(log, Log) or len(log) == 0:
            raise InvalidInput("log: expected a Log with at least one tick")
        self.log, self._speed = log, _speed(speed)
        self.t0, self.t1 = float(log.t[0]), float(log.t[-1])
        self.playing = False
        self._lock = threading.Lock()
        self._anchor = (self.t0, time.monotonic())

    @property
    def speed(self) -> float:
        """Playback speed (× real time, 0.1–4); changing it keeps the current time."""
        return self._speed

    @speed.setter
    def speed(self, v: float) -> None:
        v = _speed(v)
        t = self.time
        with self._lock:
            self._anchor, self._speed = (t, time.monotonic()), v

    @property
    def state(self) -> str:
        """"playing at 2×", "paused at t = 1.234 s" or "at the end"."""
        t = self.time
        if self.playing:
            return f"playing at {self._speed:g}×"
        return "at the end" if t >= self.t1 else f"paused at t = {t:.3f} s"

    def step(self, frames: int, fps: float = 30.0) -> None:
        """Pause and move by `frames` frames of 1/`fps` s of log time (negative: back)."""
        self.pause()
        self.seek(self.time + frames / fps)

    @property
    def time(self) -> float:
        """The playback time [s] (a time of the log)."""
        with self._lock:
            t, wall = self._anchor
            if self.playing:
                t += (time.monotonic() - wall) * self._speed
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
