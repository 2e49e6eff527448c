"""Record hooks of `rhi.sim.simulate`, and `Probe`: one that the compiled simulation loop runs too.

A ``record`` hook is called after every tick and returns ``{name: value}``; each name becomes
``Log.extra[name]`` of shape (N, *value.shape). A plain callable runs only in the Python loop (the
compiled loop, `rhi.sim._compiled.fast_loop`, does not return to Python between ticks). A `Probe`
records values of the loop's own state instead, from the set both loops know (`STATE`): the Python
loop reads them from the controller and the session after each tick, the compiled loop copies them from
its kernels' buffers into one snapshot row per tick (`rhi.sim._compiled.fast_loop.SNAPSHOT`), so a run
with a probe stays compiled and records the same values.

Usage::

    log = simulate(plant, ctrl, duration=2.0, teleop=tele, record=Probe(slave_q="slave_q", held="held"))
    log.extra["slave_q"]  # (N, n_s) [rad]; log.extra["held"]: (N, n) bool

A new state value needs a line in `STATE`, its read in `Probe.read` and its columns in the snapshot row.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from rhi.errors import InvalidInput

#: The state values a `Probe` records, by name.
STATE = {
    "held": "(n,) bool: the joints the allocation held in the tick (`ControllerState.saturated`; none before one)",
    "pc_scale": "the passivity layer's λ of its last tick (`PassivityState.scale`; NaN without the layer)",
    "tank": "the null-space energy tank's T_O + T_A after the tick [J] (`ControllerState.tank`; NaN without one)",
    "tank_scale": "the tank's λ of the tick, the factor on the objectives' torque (NaN without a tank)",
    "tank_damping": "the tank's damper rate μ of the tick [1/s] (NaN without a tank)",
    "slave_q": "(n_s,) the teleoperated slave's encoders after the period [rad] (`Teleoperation.slave`)",
}

#: The tank's state values: the `TankState` field each reads ("tank": energy + allocation).
_TANK = {"tank": "energy", "tank_scale": "scale", "tank_damping": "damping"}


class Probe:
    """A `simulate` record hook of state values both simulation loops record (see the module).

    Args:
        **names: log name → state name (a key of `STATE`), e.g. ``Probe(saturated="held")``.

    Raises:
        InvalidInput: no names, or a state name that is not in `STATE`.
    """

    def __init__(self, **names: str) -> None:
        bad = sorted(f"{k}={v!r}" for k, v in names.items() if v not in STATE)
        if not names or bad:
            raise InvalidInput(f"names: expected log name=state name pairs with state names in {sorted(STATE)}, "
                               f"got {bad or 'none'}")
        self.names = dict(names)

    def read(self, controller, session) -> dict[str, np.ndarray]:
        """One tick's values as the Python loop reads them: {log name: value}."""
        out = {}
        for name, what in self.names.items():
            if what == "held":
                s = getattr(controller, "state", None)
                held = None if s is None else s.saturated
                n = session.plant.n
                out[name] = np.zeros(n, bool) if held is None else np.array(held, dtype=bool)
            elif what == "pc_scale":
                ps = getattr(controller, "passivity", None)
                out[name] = np.array(math.nan if ps is None else ps.scale)
            elif what in _TANK:
                s = getattr(controller, "state", None)
                ts = None if s is None else s.tank
                out[name] = np.array(math.nan if ts is None else ts.energy + ts.allocation if what == "tank" else
                                     getattr(ts, _TANK[what]))
            else:
                if session.teleop is None:
                    raise InvalidInput(f"record: {name!r} records the slave's encoders, but the run has no teleop")
                out[name] = session.teleop.slave.q.copy()
        return out

    def hook(self, controller, session) -> Callable[[], dict]:
        """The plain record hook the Python loop calls after each tick."""
        return lambda: self.read(controller, session)


class Recorded:
    """What a run's record hook returned so far: per-tick values and blocks of ticks, by name."""

    def __init__(self, columns) -> None:
        self.columns = columns
        self.parts: dict[str, list[np.ndarray]] = {}
        self.ticks = 0

    def tick(self, values: dict) -> None:
        """Append one tick's {name: value}.

        Raises:
            InvalidInput: a name that is a log column, or names that differ from the first tick's.
        """
        self._check(values)
        for name, v in values.items():
            self.parts[name].append(np.array(v)[None])
        self.ticks += 1

    def block(self, values: dict[str, np.ndarray]) -> None:
        """Append a block of ticks: {name: (k, ...)} (the compiled loop's probe)."""
        self._check(values)
        for name, v in values.items():
            self.parts[name].append(v)
        self.ticks += len(next(iter(values.values())))

    def _check(self, values: dict) -> None:
        if self.ticks == 0 and not self.parts:
            clash = sorted(set(values) & set(self.columns))
            if clash:
                raise InvalidInput(f"record: {clash} are log columns already; name the recorded values differently")
            self.parts = {name: [] for name in values}
        elif values.keys() != self.parts.keys():
            raise InvalidInput(f"record: returned {sorted(values)} at tick {self.ticks}, {sorted(self.parts)} before")

    def arrays(self) -> dict[str, np.ndarray]:
        """{name: (N, ...)} of every tick recorded."""
        return {name: np.concatenate(v) if v else np.zeros(0) for name, v in self.parts.items()}


__all__ = ["STATE", "Probe", "Recorded"]
