"""`SimLink`: the MuJoCo plant, its simulated hand and physical world behind the device-link interface."""

from __future__ import annotations

import numpy as np

from rhi.runtime.link import Reading, Status
from rhi.sim.loop import Session
from rhi.sim.plant import Plant

#: the status flags as ints (an IntFlag's `|` costs microseconds per tick)
_SIMULATED, _ENABLED, _FAULT = int(Status.SIMULATED), int(Status.ENABLED), int(Status.FAULT)


class SimLink:
    """A simulated device: each `write` applies the torque for one control period and advances the plant.

    Paced by the loop: `rhi.runtime.run(..., realtime=True)` keeps it in step with the wall clock,
    `realtime=False` runs it as fast as it can (tests, batch studies). Readings carry the encoders,
    the F/T sensor and, flagged `Status.SIMULATED`, the ground truth "x", "xdot", "F_hand" and
    "work" for the log.

    Args:
        plant: the simulated device (already `reset` to its start).
        rate: control rate [Hz] (the plant's timestep must divide its period).
        hand, physical: as in `rhi.sim.simulate` (a teleoperated slave: wrap the link in
            `rhi.runtime.teleoperated.Teleoperated`).

    Attributes:
        session: the `rhi.sim.Session` it advances (its `hand` may be replaced while running).
        fault: why the simulation stopped (non-finite force, unstable physics), else None.
    """

    def __init__(self, plant: Plant, *, rate: float = 1000.0, hand=None, physical=None) -> None:
        self.plant = plant
        self.session = Session(plant, rate=rate, hand=hand, physical=physical)
        self.n, self.m = plant.n, plant.m
        self.rate = float(rate)
        self.seq = 0
        self.cmd_seq = -1
        self.enabled = False
        self._zero = np.zeros(plant.n)
        # the handle's true position and velocity in MuJoCo's sensordata (`Plant.x`, `Plant.xdot`): one gather per read
        self._xv = np.concatenate([plant._pos, plant._vel])

    @property
    def fault(self) -> str | None:
        """Why the simulation stopped (non-finite force, unstable physics), else None."""
        return self.session.fault

    @property
    def hand(self):
        """The simulated hand (replaceable while running, e.g. by a `DraggableHand`)."""
        return self.session.hand

    @hand.setter
    def hand(self, hand) -> None:
        self.session.hand = hand

    def open(self) -> None:
        """Nothing to connect; loads the compiled sensor read (`Plant.sensors`) before the first tick."""
        self.plant.sensors()

    def read(self) -> Reading:
        """The plant's encoders, F/T sensor and ground truth (flagged `Status.SIMULATED`)."""
        p, s = self.plant, self.session
        status = _SIMULATED | (_ENABLED if self.enabled else 0) | (_FAULT if s.fault else 0)
        io, n, m = p.sensors(), p.n, p.m  # q, q̇ and the F/T reading in one call
        xv = p._sd[self._xv]
        sensors = {"ft": io[2 * n:], "x": xv[:m], "xdot": xv[m:], "F_hand": s.F_hand, "work": np.array([s.work])}
        return Reading(s.t, self.seq, io[:n], io[n:2 * n], sensors, status, self.cmd_seq, s.fault or "")

    def write(self, tau, *, enable: bool) -> None:
        """Apply τ for one control period (zero when disabled or faulted) and advance the plant."""
        s = self.session
        self.enabled = bool(enable) and s.fault is None
        s.advance(np.asarray(tau, dtype=float) if self.enabled else self._zero)
        self.cmd_seq += 1
        self.seq += 1

    def close(self) -> None:
        """Leave the motors disabled."""
        self.enabled = False
