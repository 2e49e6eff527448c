"""Telemetry: the newest tick of a running loop, for a live view, without blocking the loop.

The loop calls `publish` every tick; every `every`-th call copies the log row (a few hundred
bytes) into a single slot. A reader (another thread, e.g. the browser view) calls `latest`
whenever it likes and gets the newest snapshot. Replacing the slot is one reference
assignment, atomic under the GIL: no lock, no queue, nothing the loop can wait on.
"""

from __future__ import annotations

import types
from typing import Protocol

import numpy as np

from rhi.errors import InvalidInput


class TelemetrySink(Protocol):
    """What a loop publishes its ticks to: `Telemetry`, or `rhi.viz.remote.SharedTelemetry` across processes."""

    def publish(self, row: np.ndarray, cols: dict, fault: str | None = None) -> None:
        """Offer the current log row (called by the loop every tick)."""
        ...


class Telemetry:
    """A single-slot mailbox of the newest tick.

    Args:
        every: publish one tick in `every` (10 at 1 kHz: 100 snapshots per second).
    """

    def __init__(self, every: int = 10) -> None:
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise InvalidInput(f"every: must be an integer >= 1, got {every!r}")
        self.every = every
        self.count = 0  # snapshots published
        self._k = 0
        self._slot: tuple[np.ndarray, dict, str | None] | None = None

    def publish(self, row: np.ndarray, cols: dict, fault: str | None = None) -> None:
        """Offer the current log row (called by the loop every tick)."""
        self._k += 1
        if self._k >= self.every or fault is not None:
            self._k = 0
            self._slot = (row.copy(), cols, fault)
            self.count += 1

    def latest(self) -> types.SimpleNamespace | None:
        """The newest snapshot, or None before the first one.

        Returns an object with the log's columns as attributes (t, q, dq, tau, x, xdot, F_hand, F_env,
        ft, work, V, omega, alpha, beta, seq, timing...; arrays or floats), plus `safety`
        ("ok" or "fault") and `fault` (the reason, or None).
        """
        slot = self._slot
        if slot is None:
            return None
        row, cols, fault = slot
        snap = {name: (float(row[i]) if isinstance(i, int) else row[i].copy()) for name, i in cols.items()}
        snap["fault"] = fault
        snap["safety"] = "fault" if (fault is not None or snap.get("safety", 0.0) == 1.0) else "ok"
        return types.SimpleNamespace(**snap)
