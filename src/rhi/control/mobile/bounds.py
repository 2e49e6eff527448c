"""Joint bounds of a mobile manipulator and the local bounds and scalings its controllers enforce (thesis App. A, B).

Hard position, velocity and acceleration bounds (Table B.1), the local joint velocity
(eq. A.13) and acceleration (eqs. B.6–B.8) bounds one sample ahead, the task scaling of
Fig. B.4 and the base stopping acceleration (eq. B.20). The ``*_unchecked`` variants skip
input validation for the controllers' per-tick use.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rhi._validate import as_array
from rhi.devices.model import Device, device as load
from rhi.errors import InfeasibleLimits, InvalidInput, ModelError

#: Components below this magnitude count as zero in the scaling of Fig. B.4.
EPS = 1e-12


@dataclasses.dataclass(frozen=True, eq=False)
class JointBounds:
    """Hard joint bounds of position, velocity and acceleration (thesis Table B.1, eqs. A.13, B.6–B.8).

    Attributes:
        q_min, q_max: (n,) position bounds [rad or m]; ±inf for unbounded joints.
        dq_min, dq_max: (n,) velocity bounds [rad/s or m/s], finite, dq_min < 0 < dq_max.
        ddq_min, ddq_max: (n,) acceleration bounds [rad/s² or m/s²], finite, ddq_min < 0 < ddq_max.

    Raises:
        InvalidInput: NaN, wrong shapes or infinite velocity/acceleration bounds.
        InfeasibleLimits: a minimum above its maximum (naming the pair) or a velocity or
            acceleration range that does not contain zero.
    """

    q_min: np.ndarray
    q_max: np.ndarray
    dq_min: np.ndarray
    dq_max: np.ndarray
    ddq_min: np.ndarray
    ddq_max: np.ndarray
    #: the six bounds as Python lists (for the per-joint kernel of `acceleration_bounds_unchecked`)
    _lists: tuple[list[float], ...] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        arrs = {}
        for f in self._bound_fields():
            a = np.array(getattr(self, f.name), dtype=float, ndmin=1)
            if a.ndim != 1:
                raise InvalidInput(f"{f.name}: expected shape (n,), got {a.shape}")
            if np.isnan(a).any():
                raise InvalidInput(f"{f.name}: contains NaN")
            arrs[f.name] = a
        n = arrs["q_min"].shape[0]
        for name, a in arrs.items():
            if a.shape != (n,):
                raise InvalidInput(f"{name}: expected shape ({n},) like q_min, got {a.shape}")
        for lo, hi in (("q_min", "q_max"), ("dq_min", "dq_max"), ("ddq_min", "ddq_max")):
            bad = arrs[lo] > arrs[hi]
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise InfeasibleLimits(f"{lo} > {hi} at joint {i}: {arrs[lo][i]} > {arrs[hi][i]}")
        for lo, hi in (("dq_min", "dq_max"), ("ddq_min", "ddq_max")):
            if not (np.isfinite(arrs[lo]).all() and np.isfinite(arrs[hi]).all()):
                raise InvalidInput(f"{lo}/{hi}: must be finite")
            if (arrs[lo] >= 0).any() or (arrs[hi] <= 0).any():
                raise InfeasibleLimits(f"{lo}/{hi}: every range must contain zero strictly ({lo} < 0 < {hi})")
        for name, a in arrs.items():
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        object.__setattr__(self, "_lists", tuple(arrs[f.name].tolist() for f in self._bound_fields()))

    @classmethod
    def _bound_fields(cls) -> list[dataclasses.Field]:
        return [f for f in dataclasses.fields(cls) if f.init]

    @property
    def n(self) -> int:
        """Number of joints."""
        return self.q_min.shape[0]

    def contains(self, q, tol: float = 0.0) -> np.ndarray:
        """Whether positions q: (..., n) lie within [q_min − tol, q_max + tol]. Returns (...,) bool."""
        q = np.asarray(q, dtype=float)
        return np.all((q >= self.q_min - tol) & (q <= self.q_max + tol), axis=-1)


def joint_bounds(device: Device | str) -> JointBounds:
    """Position, velocity and acceleration bounds of a device (thesis Table B.1 for ``wmm``).

    Positions come from the `Device` limits, velocity and acceleration limits from its
    `Device.velocity_max` / `Device.acceleration_max` (symmetric; device.toml for bundled devices).

    Args:
        device: a `Device` or a bundled device's name (e.g. "wmm", "gen3").

    Raises:
        ModelError: the device declares no velocity/acceleration limits.
    """
    dev = load(device) if isinstance(device, str) else device
    if dev.velocity_max is None or dev.acceleration_max is None:
        raise ModelError(f"device: {dev.name} declares no velocity_max/acceleration_max")
    v, a = dev.velocity_max, dev.acceleration_max
    return JointBounds(dev.q_min, dev.q_max, -v, v, -a, a)


def check_dt(dt: float) -> float:
    """A sampling time T [s]: finite and > 0 (InvalidInput naming `dt` otherwise)."""
    dt = float(dt)
    if not math.isfinite(dt) or dt <= 0:
        raise InvalidInput(f"dt: sampling time must be finite and > 0, got {dt!r}")
    return dt


def acceleration_bounds(q, dq, bounds: JointBounds, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Local joint acceleration bounds Q̈_min ≤ q̈ ≤ Q̈_max from position, velocity and acceleration bounds (eqs. B.6–B.8).

    Q̈_min = max{2(Q_min − q − q̇T)/T², (V_min − q̇)/T, A_min} while q > Q_low, else A_max;
    Q̈_max = min{2(Q_max − q − q̇T)/T², (V_max − q̇)/T, A_max} while q < Q_up, else A_min;
    Q_low = Q_min − |q̇|q̇/(2A_max), Q_up = Q_max + |q̇|q̇/(2A_min) (the braking distance).
    The thesis prints "max" in B.8; the upper bound is the minimum (Flacco et al. [50]), as
    Fig. B.2 shows. Sampled at T, the switch at Q_up acts up to one sample late (the joint
    overshoots its bound by up to |q̇|T), so one more term keeps the state *viable*: after
    the sample the joint can still stop before its bound at full deceleration A, i.e.
    q⁺ + q̇⁺²/(2A) + AT²/8 ≤ Q_max (the sampled stopping distance); this term is inactive
    away from the bounds. An acceleration within the bounds, integrated over one sample as
    q⁺ = q + q̇T + q̈T²/2, q̇⁺ = q̇ + q̈T, keeps q⁺ and q̇⁺ within their bounds and the state
    viable. Where the requirements conflict (a joint already too fast to stop), braking
    wins: the bounds are returned ordered, Q̈_min ≤ Q̈_max.

    Args:
        q: (..., n) joint positions [rad or m].
        dq: (..., n) joint velocities [rad/s or m/s].
        bounds: hard bounds (n joints).
        dt: sampling time T [s].

    Returns:
        (Q̈_min, Q̈_max): each (..., n) [rad/s² or m/s²].
    """
    dt = check_dt(dt)
    q = as_array("q", q, shape_tail=(bounds.n,))
    dq = as_array("dq", dq, shape_tail=(bounds.n,))
    return acceleration_bounds_unchecked(q, dq, bounds, dt)


def acceleration_bounds_unchecked(q, dq, b: JointBounds, T: float) -> tuple[np.ndarray, np.ndarray]:
    """`acceleration_bounds` without input checks (q, dq finite arrays of n joints, T > 0)."""
    if q.ndim == 1 and dq.ndim == 1:
        return _acc_bounds_1d(q, dq, b, T)
    with np.errstate(invalid="ignore", divide="ignore"):
        brake = np.abs(dq) * dq
        q_low = b.q_min - brake / (2.0 * b.ddq_max)
        q_up = b.q_max + brake / (2.0 * b.ddq_min)
        lo = np.maximum(np.maximum(2.0 * (b.q_min - q - dq * T) / T**2, (b.dq_min - dq) / T), b.ddq_min)
        hi = np.minimum(np.minimum(2.0 * (b.q_max - q - dq * T) / T**2, (b.dq_max - dq) / T), b.ddq_max)
        # discrete braking viability: after this sample the joint must still be able to stop
        # before its bound at full deceleration A (stopping distance v²/2A + AT²/8 when sampled)
        A_up, A_lo = -b.ddq_min, b.ddq_max
        r_up = b.q_max - q - 0.5 * dq * T - A_up * T * T / 8.0
        r_lo = q - b.q_min + 0.5 * dq * T - A_lo * T * T / 8.0
        v_up = -A_up * T + np.sqrt(A_up * A_up * T * T + 2.0 * A_up * np.maximum(r_up, 0.0))
        v_lo = -A_lo * T + np.sqrt(A_lo * A_lo * T * T + 2.0 * A_lo * np.maximum(r_lo, 0.0))
        hi = np.minimum(hi, np.where(r_up >= 0, (v_up - dq) / T, b.ddq_min))
        lo = np.maximum(lo, np.where(r_lo >= 0, (-v_lo - dq) / T, b.ddq_max))
    lo = np.where(q > q_low, lo, b.ddq_max)
    hi = np.where(q < q_up, hi, b.ddq_min)
    # the hard acceleration bounds always hold; conflicting requirements (a joint already too
    # fast to stop before its bound): braking at the acceleration bound wins
    lo = np.clip(lo, b.ddq_min, b.ddq_max)
    hi = np.clip(hi, b.ddq_min, b.ddq_max)
    bad = lo > hi
    if np.any(bad):
        mid = np.where(q - b.q_min < b.q_max - q, lo, hi)
        lo = np.where(bad, mid, lo)
        hi = np.where(bad, mid, hi)
    return lo, hi


def _acc_bounds_1d(q: np.ndarray, dq: np.ndarray, b: JointBounds, T: float) -> tuple[np.ndarray, np.ndarray]:
    """`acceleration_bounds_unchecked` for one configuration, joint by joint in Python floats (n ≈ 10: faster than NumPy)."""
    lo_out, hi_out = [], []
    T2 = T * T
    for qi, vi, qmin, qmax, vmin, vmax, amin, amax in zip(q.tolist(), dq.tolist(), *b._lists):
        lo = max(2.0 * (qmin - qi - vi * T) / T2 if qmin > -math.inf else -math.inf, (vmin - vi) / T, amin)
        hi = min(2.0 * (qmax - qi - vi * T) / T2 if qmax < math.inf else math.inf, (vmax - vi) / T, amax)
        if qmax < math.inf:  # viability: still able to stop before Q_max after this sample
            A = -amin
            r = qmax - qi - 0.5 * vi * T - A * T2 / 8.0
            hi = min(hi, (-A * T + math.sqrt(A * A * T2 + 2.0 * A * r) - vi) / T if r >= 0 else amin)
            if qi >= qmax + abs(vi) * vi / (2.0 * amin):  # q ≥ Q_up (B.8)
                hi = amin
        if qmin > -math.inf:
            A = amax
            r = qi - qmin + 0.5 * vi * T - A * T2 / 8.0
            lo = max(lo, (A * T - math.sqrt(A * A * T2 + 2.0 * A * r) - vi) / T if r >= 0 else amax)
            if qi <= qmin - abs(vi) * vi / (2.0 * amax):  # q ≤ Q_low (B.7)
                lo = amax
        lo = min(max(lo, amin), amax)
        hi = min(max(hi, amin), amax)
        if lo > hi:  # braking wins
            lo = hi = lo if qi - qmin < qmax - qi else hi
        lo_out.append(lo)
        hi_out.append(hi)
    return np.array(lo_out), np.array(hi_out)


def velocity_bounds(q, bounds: JointBounds, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Local joint velocity bounds Q̇_min(q) ≤ q̇ ≤ Q̇_max(q) (thesis eq. A.13, after Flacco et al. [51]).

    Q̇_min = max{(Q_min − q)/T, V_min, −√(2 A_max (q − Q_min))},
    Q̇_max = min{(Q_max − q)/T, V_max, √(2 |A_min| (Q_max − q))}: the velocity from which
    the joint can still stop at its position bound with its acceleration bound.

    Args:
        q: (..., n) joint positions [rad or m].
        bounds: hard bounds.
        dt: sampling time T [s].

    Returns:
        (Q̇_min, Q̇_max): each (..., n) [rad/s or m/s], Q̇_min ≤ 0 ≤ Q̇_max.
    """
    dt = check_dt(dt)
    q = as_array("q", q, shape_tail=(bounds.n,))
    return velocity_bounds_unchecked(q, bounds, dt)


def velocity_bounds_unchecked(q, b: JointBounds, T: float) -> tuple[np.ndarray, np.ndarray]:
    """`velocity_bounds` without input checks."""
    with np.errstate(invalid="ignore"):
        d_lo = np.maximum(q - b.q_min, 0.0)
        d_hi = np.maximum(b.q_max - q, 0.0)
        lo = np.maximum(np.maximum(-d_lo / T, b.dq_min), -np.sqrt(2.0 * b.ddq_max * d_lo))
        hi = np.minimum(np.minimum(d_hi / T, b.dq_max), np.sqrt(-2.0 * b.ddq_min * d_hi))
    return np.minimum(lo, 0.0), np.maximum(hi, 0.0)


def scale_factor(a, c, *, lo, hi, active=None) -> tuple[float, int]:
    """Largest task scaling s ∈ [0, 1] with lo ≤ c + s a ≤ hi on the active joints (thesis Fig. B.4).

    λ = a is the joint acceleration the (scalable) task requires, ξ = c what the other
    commands already consume; ρ = (bound − ξ)/λ is each joint's residual capability ratio
    and Φ = min ρ; the scaling is min(Φ, 1) (0 if even s = 0 violates a bound).

    Args:
        a: (n,) scalable part λ.
        c: (n,) fixed part ξ.
        lo: (n,) lower bounds.
        hi: (n,) upper bounds.
        active: (n,) bool, joints that take part (default all).

    Returns:
        (s, i): the scaling and the most critical joint (smallest ratio; -1 if none limits s).
    """
    a = np.asarray(a, dtype=float)
    n = a.shape[0]
    act = [True] * n if active is None else np.asarray(active, bool).tolist()
    return scale_factor_lists(a.tolist(), np.asarray(c, dtype=float).tolist(), lo=np.asarray(lo, dtype=float).tolist(),
                              hi=np.asarray(hi, dtype=float).tolist(), act=act)


def scale_factor_lists(a: list, c: list, *, lo: list, hi: list, act: list) -> tuple[float, int]:
    """`scale_factor` on Python lists (n ≈ 10: faster than NumPy's per-call overhead)."""
    s_hi, i_hi = math.inf, -1
    s_lo, i_lo = -math.inf, -1
    for i, (ai, ci, li, hi_) in enumerate(zip(a, c, lo, hi)):
        if not act[i]:
            continue
        if ai > EPS:
            up, dn = (hi_ - ci) / ai, (li - ci) / ai
        elif ai < -EPS:
            up, dn = (li - ci) / ai, (hi_ - ci) / ai
        else:
            if ci > hi_ + 1e-12 or ci < li - 1e-12:  # a fixed part out of bounds that scaling cannot fix
                return 0.0, i
            continue
        if up < s_hi:
            s_hi, i_hi = up, i
        if dn > s_lo:
            s_lo, i_lo = dn, i
    s = min(1.0, s_hi)
    if s < 0.0:  # the smallest ratio first (Fig. B.4): no s ≥ 0 brings that joint within its bounds
        return 0.0, i_hi
    if s_lo > s and (s_lo - s) * abs(a[i_lo]) > 1e-12:  # even the largest admissible scaling leaves a joint out
        return 0.0, i_lo
    return s, (i_hi if math.isfinite(s_hi) else -1)


def base_stop_acceleration(dq_b, ddq_min, ddq_max, dt: float) -> np.ndarray:
    """Stopping acceleration of a disabled base (thesis eq. B.20, sampled).

    Each base coordinate decelerates at its acceleration bound (A_min,b while V_b > 0,
    A_max,b while V_b < 0) until it stops at t_f = t₀ + |V_b/A| and stays at rest; the
    last sample is shortened so that the velocity lands on zero instead of overshooting.

    Args:
        dq_b: (n_b,) current base velocity [m/s, rad/s].
        ddq_min: (n_b,) base acceleration lower bounds A_min,b < 0.
        ddq_max: (n_b,) base acceleration upper bounds A_max,b > 0.
        dt: sampling time [s].

    Returns:
        (n_b,) q̈_b,trans.
    """
    dq_b = np.asarray(dq_b, dtype=float)
    return np.minimum(np.maximum(-dq_b / check_dt(dt), ddq_min), ddq_max)
