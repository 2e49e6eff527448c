"""The safety layer between any controller and any device link.

It knows nothing of the controllers: it sees readings going in and torques going out. Every
fault latches: zero torque with the motors disabled until an explicit `reset`, the reason and
the time recorded as an event. Torques outside the limits are clamped and counted (not a
fault); a non-finite torque is a fault.

Checks, each tick: device status flags (e-stop, watchdog, fault), non-finite readings, a
sequence number that goes backwards (out of order) or does not advance for `stale_ticks`
ticks (a stalled stream), frozen sensors (below), a device clock that stalls or runs backwards, link
silence longer than `silence` (on the host's clock, from the newest reading's arrival), a round-trip age
above `max_age`, joint speed above `max_joint_speed`, a joint beyond its range by more than `range_margin`,
handle speed above `max_handle_speed`, an external e-stop (`estop`; SIGINT, SIGTERM and SIGHUP in
`rhi.runtime.run`).

Frozen sensors (sequence numbers advance, values do not), over `frozen_ticks` consecutive new
readings: the encoders, when the joint positions and velocities are identical bit for bit while
a reported velocity implies more than `frozen_motion` of motion over that time (device clock);
the force/torque sensor, when its six values are identical bit for bit while the joints moved
(a reading below `FT_EXEMPT`, a simulated sensor without contact, is exempt). Neither can trip
on a device at rest: its velocities are zero and its positions do not change. Commanded torque
against friction is deliberately not a criterion: a user's grip can hold the handle still
against any torque the device commands.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput
from rhi.runtime.link import Reading, Status


def _positive(name: str, v, *, integer: bool = False) -> None:
    if integer and (isinstance(v, bool) or not isinstance(v, int) or v <= 0):
        raise InvalidInput(f"{name}: must be a finite integer > 0, got {v!r}")
    scalar(name, v, positive=True)


#: A force/torque reading whose components are all below this [N, N m] (a simulated sensor without contact)
#: is exempt from the frozen-sensor rule: a real sensor's noise is far above it.
FT_EXEMPT = 1e-6
_BAD_STATUS = int(Status.ESTOP | Status.WATCHDOG | Status.FAULT)


@dataclasses.dataclass(frozen=True)
class SafetyConfig:
    """Limits of the safety layer (all finite and positive).

    Attributes:
        stale_ticks: ticks without a new sequence number before the stream counts as stalled.
        frozen_ticks: consecutive new readings with identical values before the frozen-sensor rule applies.
        frozen_motion: the displacement the reported joint velocity implies over those readings above which
            unchanged positions count as frozen encoders [rad].
        silence: longest time without a new reading before the link counts as dead [s], on the host's
            monotonic clock from the newest reading's arrival (also between two arrivals).
        max_age: longest round-trip age of a reading [s] (`Reading.age`: from sending a command to the arrival
            of the reading that echoes it; a constant link delay shows here, not as silence).
        max_joint_speed: |q̇| limit [rad/s], one value or (n,).
        range_margin: how far beyond a joint limit a joint may be [rad].
        max_handle_speed: |ẋ| limit [m/s].
    """

    stale_ticks: int = 3
    frozen_ticks: int = 50
    frozen_motion: float = 1e-3
    silence: float = 0.02
    max_age: float = 0.02
    max_joint_speed: float | tuple[float, ...] = 20.0
    range_margin: float = 0.05
    max_handle_speed: float = 1.5

    def __post_init__(self) -> None:
        _positive("stale_ticks", self.stale_ticks, integer=True)
        _positive("frozen_ticks", self.frozen_ticks, integer=True)
        for f in ("silence", "max_age", "range_margin", "max_handle_speed", "frozen_motion"):
            _positive(f, getattr(self, f))
        v = self.max_joint_speed
        vals = v if isinstance(v, (tuple, list)) else (v,)
        if not vals:
            raise InvalidInput("max_joint_speed: expected one value or one per motor, got none")
        for x in vals:
            _positive("max_joint_speed", x)

    @classmethod
    def from_dict(cls, d: dict) -> SafetyConfig:
        """From a mapping (e.g. a TOML table); unknown keys are refused by name."""
        if not isinstance(d, dict):
            raise InvalidInput(f"safety: expected a table of settings, got {type(d).__name__}")
        names = {f.name for f in dataclasses.fields(cls)}
        bad = sorted(set(d) - names)
        if bad:
            raise InvalidInput(f"safety: unknown setting(s) {bad}; known: {sorted(names)}")
        d = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}
        return cls(**d)


class Safety:
    """The latched safety state of one run.

    Args:
        device: the device model (torque and joint limits; both must be finite where used).
        config: the limits.

    Attributes:
        fault: the latched reason, or None.
        fault_kind: short name of the fault ("stale", "nan", "estop", ...).
        clamped: number of ticks whose torque was clamped into the limits.
        ratio: the largest τ_i / limit_i of the last torque `filter` returned (≤ 1).
        events: [(kind, detail)] raised since the last `drain`.
        resets: how many times `reset` ran.

    Raises:
        InvalidInput: non-finite or non-positive torque limits (torque limits are never infinite).
    """

    def __init__(self, device, config: SafetyConfig | None = None) -> None:
        self.config = config or SafetyConfig()
        n = device.n
        lo, hi = np.asarray(device.torque_min, float), np.asarray(device.torque_max, float)
        if lo.shape != (n,) or hi.shape != (n,) or not (np.isfinite(lo).all() and np.isfinite(hi).all()) \
                or not (lo < 0).all() or not (hi > 0).all():
            raise InvalidInput(f"device: torque limits must be finite with torque_min < 0 < torque_max for every "
                               f"motor, got torque_min={lo.tolist()}, torque_max={hi.tolist()}")
        self.n = n
        self.lo, self.hi = lo, hi
        v = np.broadcast_to(np.asarray(self.config.max_joint_speed, float), (n,)) \
            if np.ndim(self.config.max_joint_speed) == 0 or np.size(self.config.max_joint_speed) == n else None
        if v is None:
            raise InvalidInput(f"max_joint_speed: expected one value or {n}, got {self.config.max_joint_speed!r}")
        self.max_dq = v.copy()
        m = self.config.range_margin
        self.q_lo = np.asarray(device.q_min, float) - m
        self.q_hi = np.asarray(device.q_max, float) + m
        # the per-tick checks run on Python floats: a handful of comparisons, cheaper than NumPy's ufuncs
        self._bounds = list(zip(self.q_lo.tolist(), self.q_hi.tolist(), self.max_dq.tolist()))
        self._box = list(zip(lo.tolist(), hi.tolist()))
        self._max_speed = float(self.config.max_handle_speed)
        self.fault: str | None = None
        self.fault_kind: str | None = None
        self.clamped = 0
        self.ratio = 0.0
        self.events: list[tuple[str, str]] = []
        self.resets = 0
        self._last_seq: int | None = None
        self._same = 0
        self._last_new: float | None = None
        self._last_t: float | None = None
        self._estop: str | None = None
        # the frozen-sensor rule: the last new reading's (q, q̇) and F/T as Python floats, how many new readings
        # repeated them, since when (device time [s]) and from which positions
        self._joints: tuple | None = None
        self._joints_same, self._joints_t0 = 0, 0.0
        self._ft: list[float] | None = None
        self._ft_same = 0
        self._ft_q0: list[float] | None = None

    @property
    def last_t(self) -> float | None:
        """Device time of the last new reading checked [s]; None before the first one (and after `reset`)."""
        return self._last_t

    # ------------------------------------------------------------------ faults
    def trip(self, kind: str, detail: str) -> None:
        """Latch a fault (the first one wins; later ones are recorded as events too)."""
        self.events.append((kind, detail))
        if self.fault is None:
            self.fault, self.fault_kind = detail, kind

    def estop(self, reason: str = "e-stop") -> None:
        """External emergency stop (thread- and signal-safe: takes effect at the next tick)."""
        self._estop = str(reason)

    def reset(self) -> None:
        """Clear a latched fault (an explicit operator action); the staleness counters restart."""
        if self.fault is not None:
            self.events.append(("reset", f"fault cleared: {self.fault}"))
        self.fault = self.fault_kind = self._estop = None
        self._same, self._last_new, self._last_t = 0, None, None
        self._joints = self._ft = None
        self._joints_same = self._ft_same = 0
        self.resets += 1

    def drain(self) -> list[tuple[str, str]]:
        """The events since the last call."""
        ev, self.events = self.events, []
        return ev

    # ------------------------------------------------------------------ checks
    def check(self, r: Reading, now: float | None, xdot: np.ndarray | None = None) -> bool:
        """Check a reading; return whether the controller may act (no fault latched).

        `now`: the host's monotonic time of the check [s] (None: no silence check, e.g. a simulation not in
        real time); the reading's `arrival` (else `now`) times its arrival. ẋ: (m,) [m/s] if known.
        """
        if self._estop is not None:
            self.trip("estop", f"emergency stop: {self._estop}")
        st = int(r.status)
        if st & _BAD_STATUS:
            names = [str(s.name).lower() for s in (Status.ESTOP, Status.WATCHDOG, Status.FAULT) if st & s]
            self.trip("device", f"device reports {'+'.join(names)} at t={r.t:.4f} s"
                      + (f": {r.detail}" if r.detail else ""))
        seq = int(r.seq)
        last = self._last_seq
        q, dq = r.q, r.dq
        ql, dql = q.tolist(), dq.tolist()  # sums of Python floats: cheaper than NumPy's reductions on a few values
        if last is None or seq > last:
            arrival = r.arrival if r.arrival is not None else now  # a local link's reading "arrives" when read
            if now is not None and r.arrival is not None and self._last_new is not None \
                    and r.arrival - self._last_new > self.config.silence:
                self.trip("silence", f"no reading arrived for {1e3 * (r.arrival - self._last_new):.1f} ms (limit "
                          f"{1e3 * self.config.silence:g} ms) before t={r.t:.4f} s")
            if self._last_t is not None and not r.t > self._last_t:
                self.trip("clock", f"device clock {'stalled' if r.t == self._last_t else 'ran backwards'}: reading "
                          f"{seq} at t={r.t!r} s after t={self._last_t!r} s")
            self._same, self._last_new, self._last_seq, self._last_t = 0, arrival, seq, r.t
            self._check_frozen(r, ql, dql)
        elif seq < last:
            self.trip("order", f"out-of-order reading: sequence {seq} after {last} at t={r.t:.4f} s")
        else:
            self._same += 1
            if self._same >= self.config.stale_ticks:
                self.trip("stale", f"sensors frozen: sequence {seq} repeated for {self._same} ticks at t={r.t:.4f} s")
        if now is not None and self._last_new is not None and now - self._last_new > self.config.silence:
            self.trip("silence", f"link silent for {1e3 * (now - self._last_new):.1f} ms (limit "
                      f"{1e3 * self.config.silence:g} ms) at t={r.t:.4f} s")
        if r.age > self.config.max_age:
            self.trip("latency", f"round-trip age {1e3 * r.age:.2f} ms above {1e3 * self.config.max_age:g} ms at "
                      f"t={r.t:.4f} s (reading {seq} echoes command {r.cmd_seq})")
        if not math.isfinite(sum(ql) + sum(dql)) and not (np.isfinite(q).all() and np.isfinite(dq).all()):
            self.trip("nan", f"non-finite joint reading at t={r.t:.4f} s: q={ql}, dq={dql}")
            return False
        total = 0.0
        for v in r.sensors.values():
            total += sum(v.tolist() if v.ndim == 1 else v.ravel().tolist())
        if not math.isfinite(total):  # which one (an overflow of the sum alone is not a fault)
            for name, v in r.sensors.items():
                if not np.isfinite(v).all():
                    self.trip("nan", f"non-finite sensor {name!r} at t={r.t:.4f} s: {np.asarray(v).tolist()}")
        if not _inside(ql, dql, self._bounds):
            if (np.abs(dq) > self.max_dq).any():
                j = int(np.argmax(np.abs(dq) - self.max_dq))
                self.trip("speed", f"joint {j + 1} speed {dq[j]:.3g} rad/s above {self.max_dq[j]:g} at t={r.t:.4f} s")
            if (q < self.q_lo).any() or (q > self.q_hi).any():
                j = int(np.argmax(np.maximum(self.q_lo - q, q - self.q_hi)))
                self.trip("range", f"joint {j + 1} at {q[j]:.4g} rad, beyond its range by more than "
                          f"{self.config.range_margin:g} rad at t={r.t:.4f} s")
        if xdot is not None:
            s = math.hypot(*xdot.tolist())
            if not s <= self._max_speed:
                self.trip("handle_speed", f"handle speed {s:.3g} m/s above {self.config.max_handle_speed:g} "
                          f"at t={r.t:.4f} s")
        return self.fault is None

    def _check_frozen(self, r: Reading, ql: list[float], dql: list[float]) -> None:
        """The frozen-sensor rule (module docstring) on a reading with a new sequence number."""
        t = float(r.t)
        if (ql, dql) != self._joints:
            self._joints, self._joints_same, self._joints_t0 = (ql, dql), 0, t
        else:
            self._joints_same += 1
        ft = r.sensors.get("ft")
        ftl = None if ft is None else ft.tolist()
        if ftl != self._ft:
            self._ft, self._ft_same, self._ft_q0 = ftl, 0, ql
        else:
            self._ft_same += 1
        n = self.config.frozen_ticks
        if self._joints_same >= n:
            moved = max(map(abs, dql), default=0.0) * (t - self._joints_t0)
            if moved > self.config.frozen_motion:
                self.trip("frozen", f"encoders frozen: positions unchanged for {self._joints_same} readings while the "
                          f"joint velocities {dql} rad/s imply {moved:.3g} rad of motion at t={t:.4f} s")
        if self._ft_same >= n and ftl is not None and ql != self._ft_q0 and max(map(abs, ftl)) >= FT_EXEMPT:
            self.trip("frozen", f"force/torque sensor frozen: {ftl} repeated bit for bit for {self._ft_same} "
                      f"readings while the joints moved at t={t:.4f} s")

    def filter(self, tau, t: float) -> np.ndarray:
        """The torque to send: τ clamped into the limits (counted), or zeros on a fault or a non-finite τ.

        Sets `ratio`, the largest τ_i / limit_i of what it returns (the limit on τ_i's side; 0 for zeros).
        """
        self.ratio = 0.0
        if self.fault is not None:
            return np.zeros(self.n)
        tau = np.asarray(tau, dtype=float)
        if tau.shape != (self.n,):
            self.trip("torque", f"controller returned torque of shape {tau.shape}, expected ({self.n},) at t={t:.4f} s")
            return np.zeros(self.n)
        ratio = _ratio(tau.tolist(), self._box)
        if ratio is None:  # outside the box, or not finite
            if not math.isfinite(float(tau @ tau)):
                self.trip("torque", f"non-finite torque {tau.tolist()} at t={t:.4f} s")
                return np.zeros(self.n)
            if self.clamped == 0:
                self.events.append(("clamp", f"torque {tau.tolist()} clamped into the limits at t={t:.4f} s "
                                    "(first of the run; the summary counts them)"))
            self.clamped += 1
            tau = np.minimum(np.maximum(tau, self.lo), self.hi)
            ratio = _ratio(tau.tolist(), self._box)
        self.ratio = ratio or 0.0
        return tau


def _inside(q: list[float], dq: list[float], bounds: list[tuple[float, float, float]]) -> bool:
    """Every joint within its range (with the margin) and its speed limit (NaN fails)."""
    for x, v, (lo, hi, vmax) in zip(q, dq, bounds):
        if not (lo <= x <= hi and -vmax <= v <= vmax):
            return False
    return True


def _ratio(tau: list[float], box: list[tuple[float, float]]) -> float | None:
    """The largest τ_i / limit_i (the limit on τ_i's side), or None when a torque is outside [lo, hi] (NaN too)."""
    top = 0.0
    for t, (lo, hi) in zip(tau, box):
        if not lo <= t <= hi:
            return None
        r = t / hi if t > 0.0 else t / lo
        if r > top:
            top = r
    return top
