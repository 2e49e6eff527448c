"""`Excitation`: the identification programme of `rhi identify` as a controller, `step(t, q, dq, sensors) -> τ`.

The programme is planned at the first reading, from wherever the device is, in three parts:

1. a quintic move to the hold configuration q0 (by default the configuration nearest the device's first reading
   that is `margin` inside every limit);
2. joint friction, one motor at a time: the others are held at q0 while motor i sweeps a stroke
   [a, b] of its room (its joint range and every linear joint limit with the others at q0, less a
   margin; the stroke need not contain q0) at three cruise speeds, both ways, with cosine ramps.
   Each cruise is a `Window` of the log where q̇_i is nearly constant;
3. apparent inertia (thesis §3.5 / §6.4, Tables 3.2 and 6.1): `trials` pushes from rest at q0 along u,
   each a constant force F = Λ(q0) a_k (Λ of eq. 3.13 from the model, a_k seeded uniform in `accel`:
   fast enough to measure, slow enough for the safety layer) rendered by the motors with the model's
   velocity-product force μ = Λ(J M⁻¹ C q̇ − J̇ q̇) and gravity compensated, so uᵀẍ = F/M_x minus the
   reflected joint friction (eq. 3.24) without the Coriolis bias of an external push; a null-space
   hold keeps the posture. A push ends at `push_time`, `push_speed`, `push_distance` or when it has used
   half its room to a joint or linear limit (at most half the margin), whichever comes first (`Push`); a
   quintic from its end state brings the device back to q0 and it rests there before the next.

Between and around them every motor tracks its reference by computed torque,
τ = M(q̈_ref + k_p e + k_d ė) + C q̇ + g (critically damped at `bandwidth`). `windows` and `pushes` are
filled in as the run goes (device time), for `rhi.analysis.sysid.on_device`.
"""

from __future__ import annotations

import dataclasses
import math
import threading
from collections.abc import Callable

import numpy as np

from rhi.errors import InvalidInput


@dataclasses.dataclass(frozen=True)
class Programme:
    """Settings of the identification programme (defaults and their reasons: docs/runtime.md).

    Attributes:
        stroke: largest half-width of a motor's stroke [rad or m].
        speeds: cruise speeds as fractions of the motor's top speed (three or more for the friction fit).
        top_speed: highest cruise speed of a motor [rad/s or m/s].
        handle_speed: highest handle speed a stroke may cause at q0, |J_i| v [m/s].
        ramp: length of each speed ramp [s].
        margin: distance kept from every joint and linear limit [rad or m].
        trials: number of pushes (the thesis pools ten).
        accel: (low, high) push accelerations a_k [m/s²]; the force is Λ(q0) a_k.
        push_time, push_speed, push_distance: a push ends after this long [s], this speed along u [m/s]
            or this distance along u [m].
        rest: hold at q0 before each push [s].
        back: length of the return to q0 after a push [s].
        bandwidth: tracking bandwidth [Hz].
        seed: seed of the push accelerations.
    """

    stroke: float = 0.15
    speeds: tuple[float, ...] = (1.0, 0.6, 0.3)
    top_speed: float = 1.5
    handle_speed: float = 0.4
    ramp: float = 0.1
    margin: float = 0.1
    trials: int = 10
    accel: tuple[float, float] = (3.0, 9.0)
    push_time: float = 0.25
    push_speed: float = 0.5
    push_distance: float = 0.03
    rest: float = 0.2
    back: float = 0.4
    bandwidth: float = 5.0
    seed: int = 0

    def __post_init__(self) -> None:
        for f in ("stroke", "top_speed", "handle_speed", "ramp", "margin", "push_time", "push_speed",
                  "push_distance", "rest", "back", "bandwidth"):
            v = getattr(self, f)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
                raise InvalidInput(f"{f}: expected a finite number > 0, got {v!r}")
        if isinstance(self.trials, bool) or not isinstance(self.trials, int) or not 2 <= self.trials <= 1000:
            raise InvalidInput(f"trials: expected an integer in 2..1000, got {self.trials!r}")
        if len(self.speeds) < 3 or not all(isinstance(s, (int, float)) and 0 < s <= 1 for s in self.speeds):
            raise InvalidInput(f"speeds: expected three or more fractions in (0, 1], got {self.speeds!r}")
        lo, hi = self.accel
        if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo <= hi):
            raise InvalidInput(f"accel: expected (low, high) with 0 < low <= high [m/s²], got {self.accel!r}")


@dataclasses.dataclass(frozen=True)
class Window:
    """A cruise of motor `joint` at the planned speed `speed` [rad/s or m/s, signed], device times t0..t1 [s]."""

    joint: int
    speed: float
    t0: float
    t1: float


@dataclasses.dataclass(frozen=True)
class Push:
    """Push `trial` with force `force` [N] along u, from its first tick t0 to its last t1 (device time) [s]."""

    trial: int
    force: float
    t0: float
    t1: float


def _quintic(p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, T: float) -> Callable[[float], tuple]:
    """(q, q̇, q̈)(s) from (p0, v0, 0) at s = 0 to (p1, 0, 0) at s = T, constant beyond."""
    d = p1 - p0 - v0 * T
    c3 = (10 * d + 4 * v0 * T) / T**3
    c4 = (-15 * d - 7 * v0 * T) / T**4
    c5 = (6 * d + 3 * v0 * T) / T**5
    zero = np.zeros_like(p0)

    def ref(s: float) -> tuple:
        if s >= T:
            return p1, zero, zero
        return (p0 + v0 * s + c3 * s**3 + c4 * s**4 + c5 * s**5, v0 + 3 * c3 * s**2 + 4 * c4 * s**3 + 5 * c5 * s**4,
                6 * c3 * s + 12 * c4 * s**2 + 20 * c5 * s**3)

    return ref


def _stroke(base: np.ndarray, i: int, a: float, b: float, v: float, ramp: float) -> Callable[[float], tuple]:
    """Motor i from a to b at cruise speed v > 0 with cosine ramps of `ramp` s; the others at `base`."""
    L, sgn = abs(b - a), math.copysign(1.0, b - a)
    T = L / v + ramp

    def ref(s: float) -> tuple:
        q, dq, ddq = base.copy(), np.zeros_like(base), np.zeros_like(base)
        s = min(max(s, 0.0), T)
        if s < ramp:  # v(s) = v/2 (1 − cos(π s / ramp))
            x, vel, acc = 0.5 * v * (s - ramp / math.pi * math.sin(math.pi * s / ramp)), \
                0.5 * v * (1 - math.cos(math.pi * s / ramp)), 0.5 * v * math.pi / ramp * math.sin(math.pi * s / ramp)
        elif s <= T - ramp:
            x, vel, acc = 0.5 * v * ramp + v * (s - ramp), v, 0.0
        else:
            r = T - s
            x = L - 0.5 * v * (r - ramp / math.pi * math.sin(math.pi * r / ramp))
            vel, acc = 0.5 * v * (1 - math.cos(math.pi * r / ramp)), -0.5 * v * math.pi / ramp * math.sin(math.pi * r / ramp)
        q[i], dq[i], ddq[i] = a + sgn * x, sgn * vel, sgn * acc
        return q, dq, ddq

    return ref


class Excitation:
    """The identification programme (module docstring) as a runtime controller.

    Args:
        device: the device model (its limits, M, C, g, J).
        u: (m,) push direction (normalised here).
        q0: (n,) hold configuration [rad or m]; None: the configuration nearest the first reading that is `margin`
            inside every joint and linear limit (`inside`).
        programme: the settings.

    Attributes:
        windows: the friction cruises run so far (`Window`).
        pushes: the pushes run so far (`Push`).
        forces: (trials,) the pushes' forces [N] (after the first tick).
        done: the programme has ended (the device rests at q0); `finished` is set then (for `run(until=...)`).
    """

    def __init__(self, device, u, *, q0=None, programme: Programme | None = None) -> None:
        self.device = device
        self.p = programme if programme is not None else Programme()
        u = np.asarray(u, dtype=float).reshape(-1)
        if u.shape != (device.m,) or not np.all(np.isfinite(u)) or not np.linalg.norm(u) > 0:
            raise InvalidInput(f"u: expected {device.m} finite numbers, not all zero, got {u.tolist()}")
        self.u = u / np.linalg.norm(u)
        self.q0 = None if q0 is None else np.asarray(q0, dtype=float)
        if self.q0 is not None:
            if self.q0.shape != (device.n,) or not np.all(np.isfinite(self.q0)):
                raise InvalidInput(f"q0: expected {device.n} finite numbers, got {self.q0.tolist()}")
            self._check_inside(self.q0)
        w = 2 * math.pi * self.p.bandwidth
        self.kp, self.kd = w * w, 2 * w
        self.windows: list[Window] = []
        self.pushes: list[Push] = []
        self.forces = np.zeros(0)
        self.done = False
        self.finished = threading.Event()
        self._started = False
        self._plan: list[Callable] = []  # segment factories, each (t, q, dq) -> (duration or None, segment)
        self._seg: tuple | None = None  # (t_start, duration or None, segment)
        self._push: dict | None = None

    # ------------------------------------------------------------------ planning
    def _check_inside(self, q: np.ndarray) -> None:
        lo, hi = self.device.joint_limits
        bad = np.flatnonzero((q < lo) | (q > hi))
        if bad.size:
            j = int(bad[0])
            raise InvalidInput(f"q0: motor {j + 1} at {q[j]:.4g} is outside its range [{lo[j]:.4g}, {hi[j]:.4g}]")
        L = self.device.linear_limits
        if L is not None:
            s = L.C @ q
            bad = np.flatnonzero((s < L.lower) | (s > L.upper))
            if bad.size:
                r = int(bad[0])
                raise InvalidInput(f"q0: linear joint limit {r + 1} ({L.lower[r]:.4g} <= {L.C[r].tolist()} · q "
                                   f"<= {L.upper[r]:.4g}) is violated: {s[r]:.4g}")

    def room(self, i: int, q0: np.ndarray) -> tuple[float, float]:
        """The interval motor i may sweep with the others held at q0, `margin` inside every limit [rad or m]."""
        lo, hi = self.device.joint_limits
        a, b = lo[i] + self.p.margin, hi[i] - self.p.margin
        L = self.device.linear_limits
        if L is not None:
            for r in np.flatnonzero(L.C[:, i] != 0):
                c = L.C[r, i]
                rest = L.C[r] @ q0 - c * q0[i]
                e1, e2 = (L.lower[r] - rest) / c, (L.upper[r] - rest) / c
                a, b = max(a, min(e1, e2) + self.p.margin), min(b, max(e1, e2) - self.p.margin)
        return float(a), float(b)

    def strokes(self, q0: np.ndarray) -> list[tuple[float, float, float]]:
        """Per motor: (a, b, top speed) of its stroke at hold configuration q0.

        Raises:
            InvalidInput: a motor has less than 0.05 rad (or m) of room there (choose q0 farther from the limits).
        """
        J = self.device.jacobian(q0)
        out = []
        for i in range(self.device.n):
            lo, hi = self.room(i, q0)
            if hi - lo < 0.05:
                raise InvalidInput(f"q0: motor {i + 1} has {max(hi - lo, 0.0):.3g} of room between its limits with the "
                                   f"others held (less the {self.p.margin:g} margin); choose a hold configuration "
                                   "farther from the joint and linear limits")
            half = min(self.p.stroke, 0.5 * (hi - lo))
            c = min(max(float(q0[i]), lo + half), hi - half)
            reach = float(np.linalg.norm(J[:, i]))
            top = min(self.p.top_speed, self.p.handle_speed / reach if reach > 0 else math.inf,
                      2 * half / (2 * self.p.ramp))
            out.append((c - half, c + half, top))
        return out

    def inside(self, q: np.ndarray) -> np.ndarray:
        """The configuration nearest q, by alternating projections, that is `margin` inside every joint and linear limit.

        Raises:
            InvalidInput: the limits leave no such configuration (a margin wider than the room between them).
        """
        lo, hi = self.device.joint_limits
        m, L = self.p.margin, self.device.linear_limits
        a, b = np.where(np.isfinite(lo), lo + m, -np.inf), np.where(np.isfinite(hi), hi - m, np.inf)
        x = np.clip(np.asarray(q, dtype=float), a, b)
        for _ in range(200):
            if L is None:
                return x
            for c, low, up in zip(L.C, L.lower + m, L.upper - m, strict=True):
                s = float(c @ x)
                if s < low or s > up:
                    x = x + c * ((low if s < low else up) - s) / float(c @ c)
            x = np.clip(x, a, b)
            s = L.C @ x
            if np.all(s >= L.lower + m - 1e-9) and np.all(s <= L.upper - m + 1e-9):
                return x
        raise InvalidInput(f"q0: no configuration is {m:g} inside every joint and linear limit of {self.device.name}")

    def _start(self, t: float, q: np.ndarray) -> None:
        dev, p = self.device, self.p
        q0 = self.inside(q) if self.q0 is None else self.q0
        self._check_inside(q0)
        self.q0 = q0
        J, M = dev.jacobian(q0), dev.mass_matrix(q0)
        lam = 1.0 / float(self.u @ J @ np.linalg.solve(M, J.T @ self.u))
        self.lambda_q0 = lam
        self.forces = lam * np.random.default_rng(p.seed).uniform(*p.accel, p.trials)
        plan = self._plan

        def move(target: np.ndarray) -> Callable:
            def make(t, q, dq):
                T = max(0.3, 1.875 * float(np.max(np.abs(target - q))) / 0.5)  # quintic peak speed ≤ 0.5 rad/s
                return T, ("track", _quintic(q.copy(), np.zeros_like(q), target, T))
            return make

        plan.append(move(q0))
        for i, (a, b, top) in enumerate(self.strokes(q0)):
            start = q0.copy()
            start[i] = a
            plan.append(move(start))
            ends = (a, b)
            for k, frac in enumerate(s for s in p.speeds for _ in (0, 1)):
                v = top * frac
                frm, to = ends[k % 2], ends[(k + 1) % 2]
                plan.append(self._cruise(q0, i, frm, to, v))
            plan.append(move(q0))
        for k in range(p.trials):
            plan.append(lambda t, q, dq: (p.rest, ("track", _quintic(q0, np.zeros_like(q0), q0, p.rest))))
            plan.append(self._pusher(k))
            plan.append(self._returner())

    def _cruise(self, q0: np.ndarray, i: int, a: float, b: float, v: float) -> Callable:
        def make(t, q, dq):
            T = abs(b - a) / v + self.p.ramp
            self.windows.append(Window(i, math.copysign(v, b - a), t + self.p.ramp, t + T - self.p.ramp))
            return T, ("track", _stroke(q0, i, a, b, v, self.p.ramp))
        return make

    def _pusher(self, k: int) -> Callable:
        def make(t, q, dq):
            T = self.device.terms(q, dq)
            self._push = {"trial": k, "t0": t, "t1": t, "x0": float(self.u @ T.x), "q": q.copy(),
                          "room": self._distances(q)}
            return None, ("push", float(self.forces[k]))
        return make

    def _returner(self) -> Callable:
        q0 = self.q0
        assert q0 is not None

        def make(t, q, dq):
            return self.p.back, ("track", _quintic(q.copy(), dq.copy(), q0, self.p.back))
        return make

    # ------------------------------------------------------------------ control
    def warmup(self) -> None:
        """Load the device's compiled terms before the link opens."""
        q = np.zeros(self.device.n) if self.q0 is None else self.q0
        self.device.terms(q, np.zeros_like(q)).C  # noqa: B018 (compiles the velocity terms)

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, sensors=None) -> np.ndarray:
        """τ (n,) [N m] at device time t [s] for encoder readings q (n,) [rad], q̇ (n,) [rad/s]."""
        if self.q0 is None or not self._started:
            self._started = True
            self._start(t, q)
            self._next(t, q, dq)
        T = self.device.terms(q, dq)
        while self._seg is not None:
            t0, dur, seg = self._seg
            if seg[0] == "push":
                tau = self._push_torque(t, T, seg[1])
                if tau is not None:
                    return tau
                self._next(t, q, dq)
            elif t - t0 >= dur:
                self._next(t0 + dur, q, dq)
            else:
                break
        if self._seg is None:
            ref = (self.q0, np.zeros_like(q), np.zeros_like(q))
        else:
            t0, _, seg = self._seg
            ref = seg[1](t - t0)
        qr, vr, ar = ref
        return T.M @ (ar + self.kp * (qr - q) + self.kd * (vr - dq)) + T.C @ dq + T.g

    def _next(self, t: float, q: np.ndarray, dq: np.ndarray) -> None:
        if not self._plan:
            self._seg, self.done = None, True
            self.finished.set()
            return
        dur, seg = self._plan.pop(0)(t, q, dq)
        self._seg = (t, dur, seg)

    def _push_torque(self, t: float, T, force: float) -> np.ndarray | None:
        """The push's torque at this tick, or None when the push has ended (recorded in `pushes`)."""
        p, s = self.p, self._push
        assert s is not None
        u = self.u
        near = self._near_limit(T.q)
        if (t - s["t0"] >= p.push_time or u @ T.x - s["x0"] >= p.push_distance or u @ T.xdot >= p.push_speed
                or near) and t > s["t0"]:
            self.pushes.append(Push(s["trial"], force, s["t0"], s["t1"]))
            self._push = None
            return None
        s["t1"] = t
        mu = T.Lambda @ (T.JMinv @ (T.C @ T.dq) - T.Jdot @ T.dq)
        hold = T.M @ (self.kp * (s["q"] - T.q) - self.kd * T.dq)
        return T.J.T @ (u * force + mu) + T.g + T.N @ hold

    def _distances(self, q: np.ndarray) -> np.ndarray:
        """Distance of q to each finite joint limit and each side of each linear limit [rad or m]."""
        lo, hi = self.device.joint_limits
        d = [q - lo, hi - q]
        L = self.device.linear_limits
        if L is not None:
            s = L.C @ q
            d += [s - L.lower, L.upper - s]
        out = np.concatenate(d)
        return np.where(np.isfinite(out), out, np.inf)

    def _near_limit(self, q: np.ndarray) -> bool:
        """Whether q has used half the room to a limit that the push began with (or came within half the margin)."""
        assert self._push is not None
        return bool(np.any(self._distances(q) < np.minimum(0.5 * self.p.margin, 0.5 * self._push["room"])))


__all__ = ["Excitation", "Programme", "Push", "Window"]
