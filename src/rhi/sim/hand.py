"""The simulated user: a hand that holds the handle and moves it along a reference path.

`Hand` is a Cartesian impedance (PD) between the handle and a reference point that moves
along a `HandPath`, F_h = K_h (x_r − x) + B_h (ẋ_r − ẋ) [N], optionally saturated at the force
a person comfortably applies; `MinimumJerkPalpation` strokes along a line with the minimum-jerk
profile (the §3.5 palpation); `HandSequence` passes the handle from one hand to the next at given
times. `PushForce` is the constant external force of the system identification experiments (§3.5,
§6.4). The simulation loop logs F_h, ẋ and the user's work W = ∫ F_hᵀ ẋ dt (eq. 5.15).
"""

from __future__ import annotations

import bisect
import dataclasses
import math

import numpy as np

from rhi._validate import as_array, float_array, scalar, unit_vector
from rhi.errors import InvalidInput, Unreachable


@dataclasses.dataclass(frozen=True)
class HandPath:
    """A polyline through `points` travelled at constant `speed` from time `start` [s], then held.

    After its last point the reference stays there; a single point is a hold.

    Attributes:
        points: (k, m) waypoints [m].
        speed: path speed [m/s].
        start: time the motion starts [s].
    """

    points: np.ndarray
    speed: float = 0.0
    start: float = 0.0
    # derived in __post_init__, plain floats for `segment`: arc length at each point, the points, segment
    # directions and velocities, a zero vector
    _s: list[float] = dataclasses.field(init=False, repr=False, compare=False)
    _P: list[list[float]] = dataclasses.field(init=False, repr=False, compare=False)
    _u: list[list[float]] = dataclasses.field(init=False, repr=False, compare=False)
    _v: list[list[float]] = dataclasses.field(init=False, repr=False, compare=False)
    _rest: list[float] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        P = as_array("points", self.points, ndim_min=1)
        P = P[None] if P.ndim == 1 else P
        if P.ndim != 2 or P.size == 0:
            raise InvalidInput(f"points: expected (k, m) waypoints with k, m >= 1, got shape {P.shape}")
        speed = scalar("speed", self.speed, nonnegative=True)
        if len(P) > 1 and speed <= 0:
            raise InvalidInput(f"speed: must be > 0 [m/s] for a path of {len(P)} points, got {self.speed!r}")
        object.__setattr__(self, "speed", speed)
        object.__setattr__(self, "start", scalar("start", self.start))
        object.__setattr__(self, "points", P)
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        u = np.diff(P, axis=0) / np.where(seg > 0, seg, 1.0)[:, None]
        # plain floats for `segment`, which the simulation's hand calls at every physics step
        object.__setattr__(self, "_s", np.concatenate([[0.0], np.cumsum(seg)]).tolist())
        object.__setattr__(self, "_P", P.tolist())
        object.__setattr__(self, "_u", u.tolist())
        object.__setattr__(self, "_v", (speed * u).tolist())
        object.__setattr__(self, "_rest", [0.0] * P.shape[1])

    @property
    def length(self) -> float:
        """Length of the path [m]."""
        return float(self._s[-1])

    @property
    def duration(self) -> float:
        """Time to travel the path [s] (excluding `start`)."""
        return self.length / self.speed if self.length > 0 else 0.0

    def __call__(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference position (m,) [m] and velocity (m,) [m/s] at time t [s]."""
        p, u, d, v = self.segment(t)
        return np.array([a + d * b for a, b in zip(p, u)]), np.array(v)

    def segment(self, t: float) -> tuple[list[float], list[float], float, list[float]]:
        """The reference at time t [s] as (p, u, d, v) on plain floats: position p + d u [m], velocity v [m/s].

        p: (m,) start of the current segment [m], u: (m,) its direction, d: distance travelled along it [m],
        v: (m,) the velocity [m/s] (before the start and after the end: p the held point, d = 0, u = v = 0).
        What the hand evaluates at every physics step, without array overhead; the lists are shared:
        do not modify them.
        """
        P, s, rest = self._P, self._s, self._rest
        if len(P) == 1 or t <= self.start:
            return P[0], rest, 0.0, rest
        d = (t - self.start) * self.speed
        if d >= s[-1]:
            return P[-1], rest, 0.0, rest
        i = bisect.bisect_right(s, d) - 1  # the segment holding d (zero-length segments skipped)
        return P[i], self._u[i], d - s[i], self._v[i]

    def sample(self, step: float) -> np.ndarray:
        """Points along the path every `step` metres: (k, m) [m]."""
        d = np.append(np.arange(0.0, self.length, step), self.length)
        return np.array([self(self.start + di / self.speed)[0] for di in d]) if self.length > 0 else self.points.copy()


def w_path(center, *, width: float = 0.08, height: float = 0.04, speed: float = 0.02) -> HandPath:
    """The W-shaped trajectory of §5.4 (Fig. 5.5) centred at `center` (m,) [m], 2 cm/s by default.

    Four strokes across `width` [m] with peaks `height` [m] apart along the second axis.
    """
    c = as_array("center", center, ndim_min=1)
    if c.shape not in ((2,), (3,)):
        raise InvalidInput(f"center: expected shape (2,) or (3,), got {c.shape}")
    width, height = scalar("width", width, positive=True), scalar("height", height, positive=True)
    speed = scalar("speed", speed, positive=True)
    xs = c[0] + width * np.linspace(-0.5, 0.5, 5)
    ys = c[1] + height * np.array([0.5, -0.5, 0.5, -0.5, 0.5])
    return HandPath(np.column_stack([xs, ys] + ([np.full(5, c[2])] if c.shape[0] > 2 else [])), speed)


@dataclasses.dataclass(frozen=True)
class Hand:
    """A hand tracking a path with a Cartesian impedance.

    Attributes:
        path: the reference motion.
        stiffness: K_h [N/m] (a relaxed grasp: a few hundred N/m).
        damping: B_h [N s/m].
        max_force: saturation of |F_h| [N] (None: unbounded).
    """

    path: HandPath
    stiffness: float = 300.0
    damping: float = 10.0
    max_force: float | None = 20.0

    def __post_init__(self) -> None:
        if not isinstance(self.path, HandPath):
            raise InvalidInput(f"path: expected a rhi.sim.HandPath, got {type(self.path).__name__}")
        for f in ("stiffness", "damping"):
            object.__setattr__(self, f, scalar(f, getattr(self, f), nonnegative=True))
        if self.max_force is not None:
            object.__setattr__(self, "max_force", scalar("max_force", self.max_force, positive=True))

    def force(self, t: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """F_h: (m,) [N] the hand applies to the handle at position x (m,) [m], velocity ẋ (m,) [m/s]."""
        p, u, d, v = self.path.segment(t)
        K, B = self.stiffness, self.damping
        # on plain floats (the simulation calls this at every physics step): K (x_r − x) + B (ẋ_r − ẋ), x_r = p + d u
        m = len(p)
        F = [K * ((pi + d * ui) - xi) + B * (vi - wi)
             for pi, ui, xi, vi, wi in zip(p, u, _vector("x", x, m), v, _vector("xdot", xdot, m))]
        if self.max_force is not None:
            nf = math.hypot(*F)
            if nf > self.max_force:
                r = self.max_force / nf
                F = [f * r for f in F]
        return np.array(F)


@dataclasses.dataclass(frozen=True)
class MinimumJerkPalpation:
    """A hand probing a virtual tissue: a minimum-jerk stroke along u, then a hold.

    The reference moves from ``start`` to ``start + depth u`` along the minimum-jerk profile
    s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ (τ = t/duration; peak speed 1.875 depth/duration), the
    smooth reaching motion of human arms (Flash & Hogan 1985), and stays there; the hand
    is a Cartesian impedance to it, F_h = K_h (x_r − x) + B_h (ẋ_r − ẋ), saturated at
    ``max_force``. With ``depth`` beyond the physical stop, the stroke ends on the stop.

    Attributes:
        start: (m,) start point [m].
        direction: (m,) u.
        depth: stroke length [m].
        duration: stroke duration [s].
        stiffness, damping: K_h [N/m], B_h [N s/m] (a relaxed grasp).
        max_force: saturation of |F_h| [N].
    """

    start: np.ndarray
    direction: np.ndarray
    depth: float
    duration: float
    stiffness: float = 300.0
    damping: float = 10.0
    max_force: float = 20.0

    def __post_init__(self) -> None:
        p = as_array("start", self.start, ndim_min=1)
        object.__setattr__(self, "start", p)
        object.__setattr__(self, "direction", unit_vector("direction", self.direction, p.shape[-1]))
        for name in ("depth", "duration", "stiffness", "max_force"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
        if not (math.isfinite(self.damping) and self.damping >= 0):
            raise InvalidInput(f"damping: must be finite and >= 0, got {self.damping!r}")

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference position (m,) [m] and velocity (m,) [m/s] at time t [s]."""
        tau = min(max(t / self.duration, 0.0), 1.0)
        t2, w = tau * tau, 1.0 - tau  # powers as products, in the order of the compiled hand (libm's pow rounds else)
        s = t2 * tau * (10.0 - 15.0 * tau + 6.0 * t2)
        ds = 30.0 * t2 * (w * w) / self.duration
        return self.start + self.depth * s * self.direction, self.depth * ds * self.direction

    def force(self, t: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """F_h: (m,) [N] on the handle at position x (m,) [m], velocity ẋ (m,) [m/s]."""
        xr, vr = self.reference(t)
        F = self.stiffness * (xr - x) + self.damping * (vr - xdot)
        nf = math.sqrt(float(F @ F))  # = np.linalg.norm(F), without its overhead (called at every plant step)
        if nf > self.max_force:
            F = F * (self.max_force / nf)
        return F


@dataclasses.dataclass(frozen=True)
class HandSequence:
    """Hands in turn: ``hands[i]`` while ``switch[i - 1] <= t < switch[i]`` (the first before switch[0], the last after).

    E.g. a hand that pushes in along one path, holds, and comes back along another.

    Attributes:
        hands: the phases' hands (`Hand` or `MinimumJerkPalpation` for the compiled loop; any `force(t, x, ẋ)`).
        switch: (len(hands) − 1,) the times the next hand takes over [s], non-decreasing.
    """

    hands: tuple
    switch: tuple[float, ...]

    def __post_init__(self) -> None:
        hands, switch = tuple(self.hands), tuple(self.switch)
        if not hands:
            raise InvalidInput("hands: expected at least one hand")
        for i, h in enumerate(hands):
            if not callable(getattr(h, "force", None)):
                raise InvalidInput(f"hands[{i}]: {type(h).__name__} has no force(t, x, xdot) method")
        if len(switch) != len(hands) - 1:
            raise InvalidInput(f"switch: expected {len(hands) - 1} times for {len(hands)} hands, got {len(switch)}")
        times = [scalar(f"switch[{i}]", v) for i, v in enumerate(switch)]
        if any(b < a for a, b in zip(times, times[1:])):
            raise InvalidInput(f"switch: the times must not decrease, got {times}")
        object.__setattr__(self, "hands", hands)
        object.__setattr__(self, "switch", tuple(times))

    def force(self, t: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """F_h: (m,) [N] of the hand of time t [s] at position x (m,) [m], velocity ẋ (m,) [m/s]."""
        return self.hands[bisect.bisect_right(self.switch, t)].force(t, x, xdot)


def _vector(name: str, v, m: int) -> list[float]:
    """An (m,) vector as a list of floats.

    Raises:
        InvalidInput: v is not of shape (m,) (named).
    """
    a = v if type(v) is np.ndarray else float_array(name, v)
    if a.shape != (m,):
        raise InvalidInput(f"{name}: expected shape ({m},) (the path's dimension), got {a.shape}")
    values = a.tolist()
    if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):
        raise InvalidInput(f"{name}: contains NaN or inf: {values}")
    return values


@dataclasses.dataclass(frozen=True)
class PushForce:
    """A constant force of `magnitude` [N] along `direction` from time `start` [s] (sysid, §3.5/§6.4)."""

    direction: np.ndarray
    magnitude: float
    start: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "direction", unit_vector("direction", self.direction))
        object.__setattr__(self, "magnitude", scalar("magnitude", self.magnitude))
        object.__setattr__(self, "start", scalar("start", self.start))

    def force(self, t: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """F: (m,) [N] on the handle at time t [s] (x, ẋ unused)."""
        return self.magnitude * self.direction if t >= self.start else np.zeros_like(self.direction)


def check_path_in_workspace(device, path: HandPath, *, q0=None, step: float = 0.005) -> np.ndarray:
    """IK along the path, every `step` [m].

    Returns:
        The joint path (k, n) [rad].

    Raises:
        Unreachable: naming the first point outside the device's workspace.
    """
    if q0 is None:
        lo, hi = device.joint_limits
        q0 = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), 0.0)
    qs, q = [], q0
    for i, x in enumerate(path.sample(step)):
        try:
            q = device.ik(x, q0=q)
        except Unreachable:
            raise Unreachable(f"path: point {i} at {np.round(x, 4).tolist()} m is outside the workspace of "
                              f"{device.name}") from None
        qs.append(q)
    return np.array(qs)


class DraggableHand:
    """A hand holding the handle, pulled towards a target that can move while the simulation runs.

    The browser view's gizmo: the mouse as the hand.

    F_h = K_h (x_t − x) − B_h ẋ, saturated at `max_force`; zero while no target is set. Setting the
    target is one reference assignment (safe from another thread, never blocks the loop).

    Args:
        stiffness: K_h [N/m].
        damping: B_h [N s/m].
        max_force: saturation of |F_h| [N] (None: unbounded).
    """

    def __init__(self, *, stiffness: float = 300.0, damping: float = 10.0, max_force: float | None = 20.0) -> None:
        for name, v in (("stiffness", stiffness), ("damping", damping)):
            if not np.isfinite(v) or v < 0:
                raise InvalidInput(f"{name}: must be finite and >= 0, got {v!r}")
        if max_force is not None and not max_force > 0:
            raise InvalidInput(f"max_force: must be > 0 [N] or None, got {max_force!r}")
        self.stiffness, self.damping, self.max_force = float(stiffness), float(damping), max_force
        self._target: np.ndarray | None = None

    @property
    def target(self) -> np.ndarray | None:
        """(m,) the point the hand pulls the handle to [m], or None (the hand lets go)."""
        return self._target

    @target.setter
    def target(self, x) -> None:
        if x is None:
            self._target = None
            return
        x = as_array("target", x, ndim_min=1)
        if x.ndim != 1:
            raise InvalidInput(f"target: expected a point (m,), got shape {x.shape}")
        self._target = x.copy()

    def force(self, t: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """F_h: (m,) [N] on the handle at x (m,) [m] moving at ẋ (m,) [m/s]."""
        xt = self.target
        if xt is None:
            return np.zeros_like(x)
        if xt.shape != np.shape(x):
            raise InvalidInput(f"target: {xt.shape[0]} coordinates for a handle with {np.shape(x)[0]}")
        F = self.stiffness * (xt - x) - self.damping * xdot
        if self.max_force is not None:
            nf = math.sqrt(float(F @ F))
            if nf > self.max_force:
                F *= self.max_force / nf
        return F
