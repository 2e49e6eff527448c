"""Kinematic control of the wheeled mobile manipulator (thesis App. A and App. B).

Two families of controllers for a mobile base carrying a redundant arm, both written for
the bundled ``wmm`` (Kinova Gen3 on a Mecanum base, ``rhi.device("wmm")``) but valid for
any device whose first ``n_base`` coordinates are the base pose and whose chain is serial:

* **App. A, velocity level** (`WeightedDistributionController`): the weighted
  pseudoinverse J† = W_x Jᵀ(J W_x Jᵀ)⁻¹ of the wheel-velocity Jacobian J = [J_b P, J_m]
  (eqs. A.5, A.11) with the motion-distribution weight γ (A.12–A.15) driven by the arm's
  local velocity limits (A.13); directional manipulability DM (A.8) enhanced in Cartesian
  space (A.17–A.18) or in the null space (A.19–A.20). The "traditional" baseline is the
  plain pseudoinverse J⁺ (§A.4.2).
* **App. B, acceleration level** (`AMDController`): adaptive motion distribution
  (eq. B.9), a saturation-in-the-null-space loop over the joint acceleration bounds
  (B.6–B.8) that keeps the base disabled until the arm alone cannot do the task or is
  near a singularity (σ_min(J_m) < σ_m,min), with the task scaling α and tertiary scaling
  β of Fig. B.4, the tertiary singularity-avoidance objective H = det(J_m J_mᵀ)
  (B.10–B.18) and the base stopping transition (B.20). The "traditional" baseline
  (`PinvAccelController`, §B.4.3) is J⁺(ẍ − J̇q̇) + (I − J⁺J) q̈_A.

Everything below the controllers is a pure function on arrays. Derivative conventions:
``dJ[..., i, j, k] = ∂J_ij/∂q_k`` and ``d2J[..., i, j, k, l] = ∂²J_ij/∂q_k∂q_l``.

Frames: J_m is the position Jacobian of the arm columns expressed in the world frame (as
``Device.jacobian`` returns it), so a world direction u needs no rotation J_I⁻¹ (§A.4.3
writes u = J_I⁻¹[1, 0, 0]ᵀ for J_m in the base frame; the two are the same DM).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np
import pinocchio as pin

from rhi._validate import all_finite, as_array, unit_vector
from rhi.device import Device
from rhi.device import device as load
from rhi.errors import InfeasibleLimits, InvalidInput, ModelError
from rhi.mobile_base import BASE_JOINTS, mecanum_map, wheel_geometry

_EPS = 1e-12

#: App. A.4.3: W_τ = diag(1, 1, 1, 1, 2.5, 2.5, 2.5) = diag(1/τ_lim) with τ_lim below.
W_TAU_LIMITS = (1.0, 1.0, 1.0, 1.0, 0.4, 0.4, 0.4)


# =========================================================================== bounds
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

    def __post_init__(self) -> None:
        arrs = {}
        for f in dataclasses.fields(self):
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
        object.__setattr__(self, "_lists", tuple(arrs[f.name].tolist() for f in dataclasses.fields(self)))

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


def _dt(dt: float) -> float:
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
    dt = _dt(dt)
    q = as_array("q", q, shape_tail=(bounds.n,))
    dq = as_array("dq", dq, shape_tail=(bounds.n,))
    return _acc_bounds(q, dq, bounds, dt)


def _acc_bounds(q, dq, b: JointBounds, T: float) -> tuple[np.ndarray, np.ndarray]:
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
    """`_acc_bounds` for one configuration, joint by joint in Python floats (n ≈ 10: faster than NumPy calls)."""
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
    dt = _dt(dt)
    q = as_array("q", q, shape_tail=(bounds.n,))
    return _vel_bounds(q, bounds, dt)


def _vel_bounds(q, b: JointBounds, T: float) -> tuple[np.ndarray, np.ndarray]:
    with np.errstate(invalid="ignore"):
        d_lo = np.maximum(q - b.q_min, 0.0)
        d_hi = np.maximum(b.q_max - q, 0.0)
        lo = np.maximum(np.maximum(-d_lo / T, b.dq_min), -np.sqrt(2.0 * b.ddq_max * d_lo))
        hi = np.minimum(np.minimum(d_hi / T, b.dq_max), np.sqrt(-2.0 * b.ddq_min * d_hi))
    return np.minimum(lo, 0.0), np.maximum(hi, 0.0)


def scale_factor(a, c, lo, hi, active=None) -> tuple[float, int]:
    """Largest task scaling s ∈ [0, 1] with lo ≤ c + s a ≤ hi on the active joints (thesis Fig. B.4).

    λ = a is the joint acceleration the (scalable) task requires, ξ = c what the other
    commands already consume; ρ = (bound − ξ)/λ is each joint's residual capability ratio
    and Φ = min ρ; the scaling is min(Φ, 1) (0 if even s = 0 violates a bound).

    Args:
        a: (n,) scalable part λ.
        c: (n,) fixed part ξ.
        lo, hi: (n,) bounds.
        active: (n,) bool, joints that take part (default all).

    Returns:
        (s, i): the scaling and the most critical joint (smallest ratio; -1 if none limits s).
    """
    a = np.asarray(a, dtype=float)
    n = a.shape[0]
    act = [True] * n if active is None else np.asarray(active, bool).tolist()
    return _scale(a.tolist(), np.asarray(c, dtype=float).tolist(), np.asarray(lo, dtype=float).tolist(),
                  np.asarray(hi, dtype=float).tolist(), act)


def _scale(a: list, c: list, lo: list, hi: list, act: list) -> tuple[float, int]:
    """`scale_factor` on Python lists (n ≈ 10: faster than NumPy's per-call overhead)."""
    s_hi, i_hi = math.inf, -1
    s_lo, i_lo = -math.inf, -1
    for i, (ai, ci, li, hi_) in enumerate(zip(a, c, lo, hi)):
        if not act[i]:
            continue
        if ai > _EPS:
            up, dn = (hi_ - ci) / ai, (li - ci) / ai
        elif ai < -_EPS:
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
    if s_lo > s and (s_lo - s) * abs(a[i_lo]) > 1e-12:  # even the largest admissible scaling leaves a joint out
        return 0.0, i_lo
    if s < 0.0:
        return 0.0, i_hi
    return s, (i_hi if math.isfinite(s_hi) else -1)


# ======================================================= weighted motion distribution (App. A)
def motion_weights(gamma: float, n_base: int, n_arm: int) -> np.ndarray:
    """Diagonal of the motion-distribution weight W_x = diag(γ I_b, (1 − γ) I_m) (thesis eq. A.12).

    Args:
        gamma: γ ∈ [0, 1]: 0 gives all motion to the arm, 1 all to the base.
        n_base: b, number of base inputs (4 wheels for the Mecanum base).
        n_arm: m, number of arm joints.

    Returns:
        (b + m,) diagonal of W_x.
    """
    g = float(gamma)
    if not 0.0 <= g <= 1.0:
        raise InvalidInput(f"gamma: must lie in [0, 1], got {gamma!r}")
    return np.concatenate([np.full(n_base, g), np.full(n_arm, 1.0 - g)])


def weighted_pinv_psd(J, w) -> np.ndarray:
    """Weighted pseudoinverse J† = W Jᵀ(J W Jᵀ)⁻¹ with a diagonal W ⪰ 0 (thesis eq. A.11).

    Computed as W^½ (J W^½)⁺, which equals the thesis's formula wherever J W Jᵀ is
    invertible and stays defined where it is not (γ = 1 leaves only the base, which cannot
    move the end-effector vertically: that component is then dropped in the least-squares
    sense instead of dividing by zero).

    Args:
        J: (..., r, n) Jacobian.
        w: (..., n) diagonal of W, entries ≥ 0.

    Returns:
        (..., n, r) J†, with J J† = I where J W Jᵀ has full rank.
    """
    J = as_array("J", J, ndim_min=2)
    w = as_array("w", w, shape_tail=(J.shape[-1],))
    if (w < 0).any():
        raise InvalidInput("w: weights must be >= 0")
    s = np.sqrt(w)
    return s[..., :, None] * np.linalg.pinv(J * s[..., None, :], rcond=1e-10)


def distribution_ratio(dq_m, dq_min, dq_max) -> np.ndarray:
    """η = max_i |q̇_m,i| / |Q̇_bound,i|, the arm's use of its velocity limits (thesis eq. A.15).

    Each joint is compared with the bound in the direction it moves (the thesis's formula
    takes both bounds; with symmetric limits away from a position bound they agree, and
    near one the side the joint moves away from must not count). A joint moving toward a
    zero bound gives η = inf.

    Args:
        dq_m: (..., m) arm joint velocities [rad/s].
        dq_min, dq_max: (..., m) local bounds of eq. A.13 [rad/s].

    Returns:
        (...,) η ≥ 0.
    """
    dq_m = np.asarray(dq_m, dtype=float)
    bound = np.where(dq_m >= 0, dq_max, -np.asarray(dq_min, dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(np.abs(dq_m) > 0, np.abs(dq_m) / np.abs(bound), 0.0)
    return np.max(r, axis=-1)


def distribution_gamma(eta, epsilon: float) -> np.ndarray:
    """γ = 0 if η ≤ ε, η if ε < η ≤ 1, 1 if η > 1 (thesis eq. A.14).

    Args:
        eta: (...,) η of eq. A.15.
        epsilon: ε ∈ [0, 1), largest η the arm handles alone.
    """
    eps = float(epsilon)
    if not 0.0 <= eps < 1.0:
        raise InvalidInput(f"epsilon: must lie in [0, 1), got {epsilon!r}")
    eta = np.asarray(eta, dtype=float)
    return np.where(eta <= eps, 0.0, np.minimum(eta, 1.0))


# ============================================================ directional manipulability (A.8–A.10)
def _dm_parts(J, u, torque_max):
    J = as_array("J", J, ndim_min=2)
    u = unit_vector("u", u, J.shape[-2])
    t = as_array("torque_max", torque_max)
    if (t <= 0).any():
        raise InvalidInput("torque_max: every entry must be > 0")
    w2 = np.broadcast_to(1.0 / t**2, J.shape[:-2] + (J.shape[-1],))
    v = np.einsum("...ij,...i->...j", J, u)  # Jᵀu
    s = np.einsum("...j,...j,...j->...", v, w2, v)  # uᵀ J W² Jᵀ u
    if (s <= 0).any():
        raise InvalidInput("J: Jᵀu = 0, the directional manipulability is unbounded (singular along u)")
    return J, u, w2, v, s


def dm_value(J, u, torque_max) -> np.ndarray:
    """Directional manipulability H₂ = [uᵀ J W_τᵀ W_τ Jᵀ u]^(-1/2), W_τ = diag(1/τ_lim) (thesis eq. A.8).

    Same number as `rhi.metrics.directional_manipulability`; here it raises where Jᵀu = 0
    instead of returning inf, since its gradient is then undefined.

    Args:
        J: (..., r, m) arm position Jacobian [m/rad].
        u: (..., r) direction (normalised internally).
        torque_max: (m,) τ_lim [N m]; App. A.4.3 uses `W_TAU_LIMITS`.

    Returns:
        (...,) H₂ [N].
    """
    return _dm_parts(J, u, torque_max)[4] ** -0.5


def dm_gradient(J, dJ, u, torque_max) -> np.ndarray:
    """Joint-space gradient of the directional manipulability (thesis eq. A.9).

    ∂H₂/∂q_k = −½ s^(−3/2) ∂s/∂q_k = −H₂³ uᵀ ∂J/∂q_k W² Jᵀ u, with s = uᵀ J W² Jᵀ u
    (u constant). Eq. A.9 prints the factor as H₂^(−3/2); with H₂ = s^(−1/2) the chain
    rule gives s^(−3/2) = H₂³, which is what finite differences confirm.

    Args:
        J: (..., r, m) arm Jacobian.
        dJ: (..., r, m, m) ∂J/∂q.
        u: (..., r) direction.
        torque_max: (m,) τ_lim [N m].

    Returns:
        (..., m) ∇_{q_m} H₂ [N/rad].
    """
    J, u, w2, v, s = _dm_parts(J, u, torque_max)
    dJ = as_array("dJ", dJ, shape_tail=J.shape[-2:] + (J.shape[-1],))
    ds = 2.0 * np.einsum("...i,...ijk,...j->...k", u, dJ, w2 * v)
    return -0.5 * s[..., None] ** -1.5 * ds


def dm_cartesian_gradient(J, dJ, u, torque_max) -> np.ndarray:
    """Cartesian gradient ∇_x H₂ = ∇_{q_m} H₂ J_m⁺ (thesis eq. A.10).

    The change of H₂ per unit end-effector displacement when the arm follows it with the
    minimum-norm joint motion q̇_m = J_m⁺ ẋ.

    Args:
        J: (..., r, m) arm Jacobian (full row rank).
        dJ: (..., r, m, m) ∂J/∂q.
        u: (..., r) direction.
        torque_max: (m,) τ_lim [N m].

    Returns:
        (..., r) ∇_x H₂ [N/m].
    """
    g = dm_gradient(J, dJ, u, torque_max)
    return np.einsum("...k,...kr->...r", g, np.linalg.pinv(np.asarray(J, dtype=float)))


# ================================================= manipulability det(J Jᵀ): B.14–B.18
_CHAIN_INDEX: dict[int, tuple[np.ndarray, ...]] = {}
# (a @ _E9).reshape(3, 3) = [a]×, the cross-product matrix: [a]×_ik = Σ_j ε_ijk a_j
_LEVI = np.zeros((3, 3, 3))
for _i, _j, _k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
    _LEVI[_i, _j, _k], _LEVI[_i, _k, _j] = 1.0, -1.0
_E9 = np.ascontiguousarray(_LEVI.transpose(1, 0, 2).reshape(3, 9))


def _chain_index(n: int) -> tuple[np.ndarray, ...]:
    """Index arrays of `chain_jacobian_derivatives` for n joints (cached)."""
    if n not in _CHAIN_INDEX:
        idx = np.arange(n)
        S = np.minimum.outer(idx, idx)
        T = np.maximum.outer(idx, idx)
        j, k, l_ = np.meshgrid(idx, idx, idx, indexing="ij")
        s, t = S[j, k], T[j, k]
        before = (idx[:, None] < idx[None, :]).astype(float)
        _CHAIN_INDEX[n] = (S, T, l_, s, t, np.minimum(t, l_), np.maximum(t, l_), before)
    return _CHAIN_INDEX[n]


def _skew(A: np.ndarray) -> np.ndarray:
    """Cross-product matrices of the columns of A: (..., 3, n) -> (..., n, 3, 3)."""
    return (np.swapaxes(A, -1, -2) @ _E9).reshape(A.shape[:-2] + (A.shape[-1], 3, 3))


def chain_jacobian_derivatives(J6, *, second: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """∂J/∂q and ∂²J/∂q² of a serial chain's position Jacobian from its 6-D Jacobian.

    For 1-DoF joints in chain order with world angular columns a_j (0 for a prismatic
    joint) and linear columns v_j of the end-effector point: ∂a_j/∂q_k = a_k × a_j (k < j),
    ∂v_j/∂q_k = a_s × v_t with s = min(j, k), t = max(j, k); differentiating once more
    gives ∂²v_j/∂q_k∂q_l = [l < s](a_l × a_s) × v_t + a_s × (a_min(t,l) × v_max(t,l)).

    Args:
        J6: (..., 6, n) [linear; angular] Jacobian of the end-effector point in world-aligned axes.
        second: also return the second derivatives.

    Returns:
        (dJ, d2J): (..., 3, n, n) and (..., 3, n, n, n) (None if not `second`).
    """
    J6 = as_array("J6", J6, ndim_min=2)
    if J6.shape[-2] != 6:
        raise InvalidInput(f"J6: expected shape (..., 6, n), got {J6.shape}")
    V, A = J6[..., :3, :], J6[..., 3:, :]
    S, T, L, s, t, tl_lo, tl_hi, before = _chain_index(J6.shape[-1])
    SkA = _skew(A)  # (..., n, 3, 3)
    C = np.swapaxes(SkA @ V[..., None, :, :], -1, -2)  # C[..., s, t, :] = a_s × v_t
    dJ = np.moveaxis(C[..., S, T, :], -1, -3)  # (..., 3, j, k)
    if not second:
        return dJ, None
    AA = np.swapaxes(SkA @ A[..., None, :, :], -1, -2) * before[:, :, None]  # [..., l, s, :] = a_l × a_s, l < s
    Vt, At = np.swapaxes(V, -1, -2), np.swapaxes(A, -1, -2)  # (..., n, 3)
    d2V = np.cross(AA[..., L, s, :], Vt[..., t, :]) + np.cross(At[..., s, :], C[..., tl_lo, tl_hi, :])
    return dJ, np.moveaxis(d2V, -1, -4)


def _sym3(P: np.ndarray) -> tuple[float, np.ndarray | None, float, float]:
    """det, inverse (None if singular), smallest and largest eigenvalue of a symmetric 3×3 matrix (closed forms)."""
    (a, b, c), (_, d, e), (_, _, f) = P.tolist()
    A0, A1, A2 = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A0 + b * A1 + c * A2
    # eigenvalues: trigonometric solution of the characteristic cubic
    p1 = b * b + c * c + e * e
    qm = (a + d + f) / 3.0
    a_, d_, f_ = a - qm, d - qm, f - qm
    p2 = a_ * a_ + d_ * d_ + f_ * f_ + 2.0 * p1
    if p2 <= 1e-300:
        lmin = lmax = qm
    else:
        p = math.sqrt(p2 / 6.0)
        detB = (a_ * (d_ * f_ - e * e) - b * (b * f_ - e * c) + c * (b * e - d_ * c)) / p**3
        phi = math.acos(min(1.0, max(-1.0, 0.5 * detB))) / 3.0
        lmax = qm + 2.0 * p * math.cos(phi)
        lmin = qm + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    if not det > 0:
        return det, None, lmin, lmax
    B4, B5 = a * f - c * c, b * c - a * e
    inv = np.array([[A0, A1, A2], [A1, B4, B5], [A2, B5, a * d - b * b]]) / det
    return det, inv, lmin, lmax


def _gram_inverse(JS: np.ndarray, rank_tol: float) -> np.ndarray | None:
    """(JS JSᵀ)⁻¹, or None where JS is rank deficient (λ_min ≤ rank_tol λ_max)."""
    G = JS @ JS.T
    if G.shape == (3, 3):
        _, inv, lmin, lmax = _sym3(G)
        return inv if inv is not None and lmin > rank_tol * max(lmax, _EPS) else None
    ev = np.linalg.eigvalsh(G)
    return np.linalg.inv(G) if ev[0] > rank_tol * max(ev[-1], _EPS) else None


def _det_terms(J6m: np.ndarray, dqm: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, float]:
    """H = det(J Jᵀ), ∇H (B.14), the Hessian-vector product ∇²H q̇ (B.18 contracted) and σ_min(J).

    ∇²H q̇ is d/dt ∇H along q̇, evaluated in O(m²) with ∂J/∂q (cross products) and its time
    derivative ∂J̇/∂q_k = (ω_s × a_s) × v_t + a_s × J̇_t (ω_s = Σ_{l<s} a_l q̇_l), the same
    numbers as `manipulability_det_hessian` @ q̇ without the m³ tensor.

    Args:
        J6m: (6, m) [linear; angular] Jacobian of the arm columns.
        dqm: (m,) arm joint velocities.
    """
    V, A = J6m[:3], J6m[3:]
    m = V.shape[1]
    S, T = _chain_index(m)[:2]
    SkA = (A.T @ _E9).reshape(m, 3, 3)
    D = (SkA @ V)[S, :, T]  # (j, k, 3): ∂v_j/∂q_k
    Jd = (dqm @ D).T  # J̇ (3, m)
    aq = A * dqm
    Om = np.cumsum(aq, axis=1) - aq  # ω_s, angular velocity of the link before joint s
    Ad = (SkA @ Om.T[:, :, None])[:, :, 0].T  # a_s × ω_s = −ȧ_s, (3, m)
    Dd = (SkA @ Jd - (Ad.T @ _E9).reshape(m, 3, 3) @ V)[S, :, T]  # d/dt ∂v_j/∂q_k
    Psi = V @ V.T
    det, G, lam, _ = _sym3(Psi)
    if G is None:
        raise InvalidInput("J: J_m J_mᵀ is singular (the arm is at a singular configuration)")
    W = G @ V  # Ψ⁻¹J
    Dk = D.transpose(1, 0, 2).reshape(m, 3 * m)
    Wf = W.T.ravel()
    gt = Dk @ Wf  # tr(Ψ⁻¹ ∂_kJ Jᵀ)
    Pd = Jd @ V.T
    Pd = Pd + Pd.T  # Ψ̇
    Wd = G @ (Jd - Pd @ W)
    gdot = Dk @ Wd.T.ravel() + Dd.transpose(1, 0, 2).reshape(m, 3 * m) @ Wf
    trd = float(G.ravel() @ Pd.ravel())
    grad = 2.0 * det * gt
    hvp = 2.0 * det * (trd * gt + gdot)
    return det, grad, hvp, math.sqrt(max(lam, 0.0))


def manipulability_det(J) -> np.ndarray:
    """H = det(J Jᵀ) = w², the squared Yoshikawa manipulability (thesis §B.3.2).

    Args:
        J: (..., r, m) Jacobian.

    Returns:
        (...,) H.
    """
    J = as_array("J", J, ndim_min=2)
    return np.linalg.det(J @ np.swapaxes(J, -1, -2))


def manipulability_det_gradient(J, dJ) -> np.ndarray:
    """∇H = det(Ψ) tr[Ψ⁻¹(∂J Jᵀ + J ∂Jᵀ)], Ψ = J Jᵀ (thesis eq. B.14).

    Args:
        J: (..., r, m) Jacobian of full row rank.
        dJ: (..., r, m, m) ∂J/∂q.

    Returns:
        (..., m) ∇_q H.
    """
    J = as_array("J", J, ndim_min=2)
    dJ = as_array("dJ", dJ, shape_tail=J.shape[-2:] + (J.shape[-1],))
    Psi = J @ np.swapaxes(J, -1, -2)
    W = np.linalg.solve(Psi, J)  # Ψ⁻¹J, (..., r, m)
    # tr(Ψ⁻¹ ∂_kΨ) = 2 Σ_aj (Ψ⁻¹J)_aj ∂_k J_aj
    g = 2.0 * np.einsum("...aj,...ajk->...k", W, dJ)
    return np.linalg.det(Psi)[..., None] * g


def manipulability_det_hessian(J, dJ, d2J) -> np.ndarray:
    """∇²H of H = det(J Jᵀ) (thesis eqs. B.15–B.18).

    ∂_pq H = det Ψ [tr(Ψ⁻¹∂_qΨ) tr(Ψ⁻¹∂_pΨ) − tr(Ψ⁻¹∂_qΨ Ψ⁻¹∂_pΨ) + tr(Ψ⁻¹∂_pqΨ)] with
    ∂_pqΨ = ∂_pqJ Jᵀ + ∂_pJ ∂_qJᵀ + ∂_qJ ∂_pJᵀ + J ∂_pqJᵀ (B.15, B.17).

    Args:
        J: (..., r, m) Jacobian of full row rank.
        dJ: (..., r, m, m) ∂J/∂q.
        d2J: (..., r, m, m, m) ∂²J/∂q².

    Returns:
        (..., m, m) symmetric Hessian.
    """
    J = as_array("J", J, ndim_min=2)
    r, m = J.shape[-2:]
    dJ = as_array("dJ", dJ, shape_tail=(r, m, m))
    d2J = as_array("d2J", d2J, shape_tail=(r, m, m, m))
    batch = J.shape[:-2]
    Psi = J @ np.swapaxes(J, -1, -2)
    G = np.linalg.inv(Psi)
    dJk = np.moveaxis(dJ, -1, -3)  # (..., m_k, r, m)
    P1 = dJk @ np.swapaxes(J, -1, -2)[..., None, :, :]  # ∂_kJ Jᵀ: (..., m, r, r)
    dPsi = P1 + np.swapaxes(P1, -1, -2)
    M = G[..., None, :, :] @ dPsi  # Ψ⁻¹ ∂_kΨ
    t1 = np.trace(M, axis1=-2, axis2=-1)  # (..., m)
    Mf = M.reshape(batch + (m, r * r))
    t2 = Mf @ np.swapaxes(np.swapaxes(M, -1, -2).reshape(batch + (m, r * r)), -1, -2)  # tr(M_p M_q)
    W = (G @ J).reshape(batch + (1, r * m))
    t3 = (W @ d2J.reshape(batch + (r * m, m * m))).reshape(batch + (m, m))
    K = (G @ dJ.reshape(batch + (r, m * m))).reshape(batch + (r * m, m))
    t3 = 2.0 * t3 + 2.0 * np.swapaxes(K, -1, -2) @ dJ.reshape(batch + (r * m, m))
    det = np.linalg.det(Psi)[..., None, None]
    return det * (t1[..., :, None] * t1[..., None, :] - t2 + t3)


# =============================================================== AMD building blocks (B.9–B.20)
def auxiliary_projector(P_N, active) -> np.ndarray:
    """P_A = [I − ((I − S) P_N)⁺] P_N (thesis eq. B.10).

    Projects onto the motions that leave the task unchanged (J P_A = 0) and do not move
    the saturated or disabled joints ((I − S) P_A = 0). Computed with the inactive rows
    D only: ((I − S) P_N)⁺ P_N = P_N[:, D] (P_N[D, D])⁺ P_N[D, :] (P_N symmetric idempotent).

    Args:
        P_N: (n, n) orthogonal null-space projector I − J⁺J.
        active: (n,) bool diagonal of the selection matrix S.

    Returns:
        (n, n) P_A.
    """
    P_N = np.asarray(P_N, dtype=float)
    D = np.flatnonzero(~np.asarray(active, bool))
    if D.size == 0:
        return P_N.copy()
    B = P_N[:, D]
    return P_N - B @ np.linalg.pinv(P_N[np.ix_(D, D)], rcond=1e-10, hermitian=True) @ B.T


def tertiary_acceleration(grad, hess, dq_m, gamma1: float, gamma2: float, n_base: int) -> np.ndarray:
    """q̈_A = [0; γ₁ ∇²H q̇_m + γ₂(γ₁ ∇Hᵀ − q̇_m)] (thesis eq. B.13): d/dt of q̇_N = γ₁ [0; ∇Hᵀ] (B.12) plus tracking of it.

    Args:
        grad: (m,) ∇_{q_m} H.
        hess: (m, m) ∇²_{q_m} H.
        dq_m: (m,) arm joint velocities [rad/s].
        gamma1, gamma2: positive gains (thesis: 5, 0.5).
        n_base: number of base coordinates (zero entries).

    Returns:
        (n_base + m,) q̈_A [rad/s²].
    """
    out = np.zeros(n_base + len(dq_m))
    out[n_base:] = gamma1 * (hess @ dq_m) + gamma2 * (gamma1 * grad - dq_m)
    return out


@dataclasses.dataclass(frozen=True)
class SNSResult:
    """Outcome of `sns_acceleration`.

    Attributes:
        ddq: (n,) joint accelerations q̈_amd [rad/s² or m/s²].
        alpha: task scaling α ∈ [0, 1] (1: the task is met exactly).
        active: (n,) bool diagonal of S (joints that take part in the task).
        feasible: whether the unscaled task fits the bounds with the enabled joints.
        gram_inv: (r, r) (J_S J_Sᵀ)⁻¹ of the active columns J_S, or None.
    """

    ddq: np.ndarray
    alpha: float
    active: np.ndarray
    feasible: bool
    gram_inv: np.ndarray | None = None


def sns_acceleration(J, b, ddx, lo, hi, enabled, fixed, *, rank_tol: float = 1e-6) -> SNSResult:
    """Adaptive motion distribution q̈ = (JS)⁺(α ẍ − J̇q̇) + [I − (JS)⁺J] q̈_N (thesis eq. B.9).

    Saturation in the null space [51]: start with the enabled joints active and every
    other joint at its `fixed` acceleration; while an active joint leaves [lo, hi], put the
    most critical one (smallest residual ratio, Fig. B.4) at the bound it exceeds
    (S_ii = 0, q̈_N,i = bound) and recompute. If the active joints cannot realise the task
    (rank(JS) < r) the task is infeasible for the enabled joints: the largest scaling α
    met on the way is used with its selection.

    Args:
        J: (r, n) Jacobian.
        b: (r,) drift J̇q̇ [m/s²].
        ddx: (r,) desired task acceleration ẍ [m/s²].
        lo, hi: (n,) acceleration bounds (B.6–B.8).
        enabled: (n,) bool, joints allowed to take part (the base is disabled initially).
        fixed: (n,) accelerations of the joints that are not enabled.
        rank_tol: J_S counts as rank deficient where λ_min(J_S J_Sᵀ) ≤ rank_tol λ_max, i.e.
            σ_min/σ_max ≤ 1e-3 by default: nearly singular active sets buy a negligible
            scaling with huge, ill-conditioned joint accelerations.

    Returns:
        `SNSResult`; J q̈ = α ẍ − J̇q̇ holds whenever α > 0 or feasible.
    """
    r, n = J.shape
    active = np.array(enabled, dtype=bool)
    qN = np.where(active, 0.0, fixed)
    lo_l, hi_l = lo.tolist(), hi.tolist()
    best_s, best = -1.0, None
    for _ in range(n + 1):
        idx = np.flatnonzero(active)
        if idx.size < r:
            break
        JS = J[:, idx]
        Ginv = _gram_inverse(JS, rank_tol)
        if Ginv is None:
            break
        G = JS @ JS.T
        rhs = -b - J @ qN
        ya, yc = Ginv @ ddx, Ginv @ rhs
        ya += Ginv @ (ddx - G @ ya)  # one step of iterative refinement: the closed-form inverse
        yc += Ginv @ (rhs - G @ yc)  # loses digits on nearly rank-deficient J_S
        a = np.zeros(n)
        a[idx] = JS.T @ ya
        c = qN.copy()
        c[idx] += JS.T @ yc
        al, cl = a.tolist(), c.tolist()
        s, crit = _scale(al, cl, lo_l, hi_l, active.tolist())
        if s >= 1.0:
            return SNSResult(np.minimum(np.maximum(a + c, lo), hi), 1.0, active, True, Ginv)
        if s > best_s:
            best_s, best = s, (a, c, active.copy(), Ginv)
        if crit < 0:
            break
        qN[crit] = hi_l[crit] if al[crit] + cl[crit] > hi_l[crit] else lo_l[crit]
        active[crit] = False
    if best is None:
        return SNSResult(np.clip(qN, lo, hi), 0.0, active, False, None)
    a, c, act, Ginv = best
    return SNSResult(np.clip(c + best_s * a, lo, hi), best_s, act, False, Ginv)


def base_stop_acceleration(dq_b, ddq_min, ddq_max, dt: float) -> np.ndarray:
    """Stopping acceleration of a disabled base (thesis eq. B.20, sampled).

    Each base coordinate decelerates at its acceleration bound (A_min,b while V_b > 0,
    A_max,b while V_b < 0) until it stops at t_f = t₀ + |V_b/A| and stays at rest; the
    last sample is shortened so that the velocity lands on zero instead of overshooting.

    Args:
        dq_b: (n_b,) current base velocity [m/s, rad/s].
        ddq_min, ddq_max: (n_b,) base acceleration bounds A_min,b < 0 < A_max,b.
        dt: sampling time [s].

    Returns:
        (n_b,) q̈_b,trans.
    """
    dq_b = np.asarray(dq_b, dtype=float)
    return np.minimum(np.maximum(-dq_b / _dt(dt), ddq_min), ddq_max)


# ==================================================================== kinematics helper
class WMMKinematics:
    """End-effector position, Jacobians and their derivatives of a serial mobile manipulator.

    One Pinocchio call per configuration gives the 6-D world-aligned Jacobian; the
    position Jacobian's derivatives follow from it by cross products
    (`chain_jacobian_derivatives`), the drift J̇q̇ from the frame's classical acceleration.

    Args:
        device: a device whose chain coordinates are its motor coordinates (A = I, b = 0)
            and whose joints form one serial chain (e.g. ``wmm``, ``gen3``).
    """

    def __init__(self, device: Device) -> None:
        if device.A.shape[0] != device.A.shape[1] or not np.allclose(device.A, np.eye(device.n)) or np.any(device.b):
            raise ModelError(f"device: {device.name} has an actuation map; WMMKinematics needs chain coordinates")
        parents = list(device.model.parents)
        if parents[1:] != list(range(len(parents) - 1)):
            raise ModelError(f"device: {device.name} is not a serial chain")
        self.device = device
        self.model = device.model
        self.data = device.model.createData()
        self.fid = device.model.getFrameId(device.ee_frame)
        self._zero = np.zeros(device.n)

    def jacobian6(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, J6): end-effector position (3,) [m] and [linear; angular] world-aligned Jacobian (6, n)."""
        J6 = pin.computeFrameJacobian(self.model, self.data, q, self.fid, pin.LOCAL_WORLD_ALIGNED)
        return self.data.oMf[self.fid].translation.copy(), J6

    def drift(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """J̇q̇: (3,) [m/s²], the end-effector acceleration at q̈ = 0."""
        pin.forwardKinematics(self.model, self.data, q, dq, self._zero)
        return pin.getFrameClassicalAcceleration(self.model, self.data, self.fid, pin.LOCAL_WORLD_ALIGNED).linear.copy()


def _finite(name: str, v, n: int) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (n,):
        raise InvalidInput(f"{name}: expected shape ({n},), got {a.shape}")
    if not all_finite(a):
        raise InvalidInput(f"{name}: contains NaN or inf")
    return a


def _check_base(device: Device, n_base: int) -> None:
    if n_base != len(BASE_JOINTS) or tuple(device.joint_names[:n_base]) != BASE_JOINTS or device.n <= n_base:
        raise InvalidInput(
            f"device: expected coordinates starting with {list(BASE_JOINTS)} and an arm, got {device.joint_names}"
        )


# ================================================================ App. B: AMD controller
@dataclasses.dataclass(frozen=True)
class AMDConfig:
    """Parameters of the adaptive motion distribution controller (thesis §B.3, §B.4.2).

    Attributes:
        dt: sampling time T of eqs. B.7–B.8 [s].
        kp: K_p of ẍ = ẍ_d + K_d(ẋ_d − ẋ) + K_p(x_d − x) [1/s²] (thesis 20).
        kd: K_d [1/s] (thesis 10).
        sigma_min: σ_m,min: the base is activated while σ_min(J_m) < sigma_min [m/rad] (thesis 0.15).
        sigma_release: the base is released only once σ_min(J_m) ≥ sigma_release
            (default: sigma_min, the thesis's single threshold).
        gamma1, gamma2: gains of the tertiary objective (B.12–B.13) (thesis 5, 0.5).
        singularity_avoidance: base activation near singularity + tertiary objective (§B.4.2);
            False gives the plain AMD of Fig. B.7.
        bounds: joint bounds; None: the device's (`joint_bounds`).
    """

    dt: float = 0.005
    kp: float = 20.0
    kd: float = 10.0
    sigma_min: float = 0.15
    sigma_release: float | None = None
    gamma1: float = 5.0
    gamma2: float = 0.5
    singularity_avoidance: bool = True
    bounds: JointBounds | None = None

    def __post_init__(self) -> None:
        _dt(self.dt)
        for name in ("kp", "kd", "sigma_min", "gamma1", "gamma2"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0:
                raise InvalidInput(f"{name}: must be finite and >= 0, got {v!r}")
        if self.sigma_release is not None and not self.sigma_release >= self.sigma_min:
            raise InfeasibleLimits(f"sigma_release: must be >= sigma_min, got {self.sigma_release!r}")


@dataclasses.dataclass
class AMDState:
    """Explicit state of `AMDController`.

    Attributes:
        t: time of the last step [s].
        base_active: whether the base took part in the last step.
        stop_t0: start t₀ of the current base stopping transition (B.20) [s], or None.
        stop_v: (n_b,) base velocity V_b when it was released [m/s, rad/s].
        steps: number of steps.
    """

    t: float = -math.inf
    base_active: bool = False
    stop_t0: float | None = None
    stop_v: np.ndarray | None = None
    steps: int = 0


@dataclasses.dataclass(frozen=True)
class AccelCommand:
    """One acceleration-level command.

    Attributes:
        ddq: (n,) joint accelerations [m/s², rad/s²] (base coordinates first).
        ddx: (r,) commanded task acceleration ẍ before scaling [m/s²].
        x: (r,) end-effector position from the kinematics [m].
        alpha: task scaling α.
        beta: tertiary scaling β.
        active: (n,) bool selection S.
        base_active: whether the base was enabled.
        sigma: σ_min(J_m) [m/rad].
        lo, hi: (n,) acceleration bounds used (B.6–B.8).
    """

    ddq: np.ndarray
    ddx: np.ndarray
    x: np.ndarray
    alpha: float
    beta: float
    active: np.ndarray
    base_active: bool
    sigma: float
    lo: np.ndarray
    hi: np.ndarray


class _AccelBase:
    """Shared parts of the acceleration-level controllers."""

    def __init__(self, device: Device, config, n_base: int = 3) -> None:
        _check_base(device, n_base)
        self.device = device
        self.config = config
        self.n_base = n_base
        self.bounds = config.bounds if config.bounds is not None else joint_bounds(device)
        if self.bounds.n != device.n:
            raise InvalidInput(f"bounds: expected {device.n} joints, got {self.bounds.n}")
        self.kin = WMMKinematics(device)
        self._arm = slice(n_base, device.n)

    def _inputs(self, q, dq, x_des, dx_des, ddx_des):
        n = self.device.n
        q = _finite("q", q, n)
        dq = _finite("dq", dq, n)
        x_des = _finite("x_des", x_des, 3)
        dx_des = _finite("dx_des", dx_des, 3)
        ddx_des = _finite("ddx_des", ddx_des, 3)
        return q, dq, x_des, dx_des, ddx_des

    def _task(self, q, dq, x_des, dx_des, ddx_des):
        x, J6 = self.kin.jacobian6(q)
        J = J6[:3]
        b = self.kin.drift(q, dq)
        c = self.config
        ddx = ddx_des + c.kd * (dx_des - J @ dq) + c.kp * (x_des - x)
        return x, J6, J, b, ddx

    def _tertiary(self, J6, dq):
        """q̈_A of eq. B.13 for H = det(J_m J_mᵀ), with the analytic gradient and Hessian (B.14–B.18)."""
        c, nb = self.config, self.n_base
        _, grad, hvp, _ = _det_terms(J6[:, nb:], dq[nb:])
        out = np.zeros(self.device.n)
        out[nb:] = c.gamma1 * hvp + c.gamma2 * (c.gamma1 * grad - dq[nb:])
        return out


class AMDController(_AccelBase):
    """Adaptive motion distribution with singularity avoidance (thesis §B.3, Figs. B.3–B.4, eq. B.19).

    Each step: (1) the task acceleration ẍ = ẍ_d + K_d(ẋ_d − ẋ) + K_p(x_d − x) and the
    joint acceleration bounds (B.6–B.8); (2) if σ_min(J_m) ≥ σ_m,min (or avoidance is off)
    the arm alone tries the task by saturation in the null space (B.9) with the base held
    at its stopping acceleration (B.20); (3) if that is infeasible, or the arm is near a
    singularity, the base is enabled and B.9 is solved over every joint, scaling the task
    by α if needed; (4) the tertiary objective q̈_t = β P_A q̈_A (B.10–B.13) is added with
    the β of Fig. B.4 (eq. B.19).

    Args:
        device: the mobile manipulator (``rhi.device("wmm")``); q = [x_b, y_b, θ_b, q_m].
        config: parameters.
        state: initial state (default fresh).
    """

    def __init__(self, device: Device, config: AMDConfig | None = None, state: AMDState | None = None) -> None:
        super().__init__(device, config or AMDConfig())
        self.state = state or AMDState()
        n, nb = device.n, self.n_base
        self._arm_mask = np.arange(n) >= nb
        self._all_mask = np.ones(n, bool)
        self._zeros = np.zeros(n)

    def reset(self) -> None:
        """Fresh state."""
        self.state = AMDState()

    def step(self, t: float, q, dq, x_des, dx_des, ddx_des) -> AccelCommand:
        """One control step.

        Args:
            t: time [s].
            q: (n,) configuration (x_b, y_b, θ_b, q_m) [m, m, rad, rad].
            dq: (n,) joint velocities (the commanded, integrated ones) [m/s, rad/s].
            x_des, dx_des, ddx_des: (3,) desired end-effector position [m], velocity [m/s],
                acceleration [m/s²] (world frame).

        Returns:
            `AccelCommand`; integrate q̈ over one sample (q̇⁺ = q̇ + q̈T) to keep every bound.
        """
        q, dq, x_des, dx_des, ddx_des = self._inputs(q, dq, x_des, dx_des, ddx_des)
        c, st, nb, n = self.config, self.state, self.n_base, self.device.n
        x, J6, J, b, ddx = self._task(q, dq, x_des, dx_des, ddx_des)
        lo, hi = _acc_bounds(q, dq, self.bounds, c.dt)
        _, grad, hvp, sigma = _det_terms(J6[:, nb:], dq[nb:])
        release = c.sigma_min if c.sigma_release is None else c.sigma_release
        threshold = release if st.base_active else c.sigma_min
        near_singular = c.singularity_avoidance and sigma < threshold
        res = None
        if not near_singular:
            fixed = np.zeros(n)
            fixed[:nb] = base_stop_acceleration(dq[:nb], lo[:nb], hi[:nb], c.dt)
            res = sns_acceleration(J, b, ddx, lo, hi, self._arm_mask, fixed)
            if not res.feasible:
                res = None
        base_active = res is None
        if base_active:
            res = sns_acceleration(J, b, ddx, lo, hi, self._all_mask, self._zeros)
            st.stop_t0, st.stop_v = None, None
        elif st.base_active or (st.stop_t0 is None and np.any(dq[:nb] != 0)):
            st.stop_t0, st.stop_v = t, dq[:nb].copy()  # B.20: t₀ and V_b
        ddq, beta = res.ddq, 0.0
        if c.singularity_avoidance and res.gram_inv is not None:
            # q̈_t = β P_A q̈_A (B.10–B.11). P_A is the orthogonal projector onto the motions of the
            # active joints that leave the task unchanged: P_A q̈_A = (I − J_S⁺J_S) q̈_A,S on the
            # active joints and 0 elsewhere, the same matrix as B.10 (see auxiliary_projector).
            act = res.active
            ddq_A = c.gamma1 * hvp + c.gamma2 * (c.gamma1 * grad - dq[nb:])  # B.13, arm part
            lam = np.zeros(n)
            lam[nb:] = ddq_A
            lam[~act] = 0.0
            JS = J[:, act]
            lam[act] -= JS.T @ (res.gram_inv @ (JS @ lam[act]))
            beta, _ = _scale(lam.tolist(), ddq.tolist(), lo.tolist(), hi.tolist(), [True] * n)
            ddq = np.minimum(np.maximum(ddq + beta * lam, lo), hi)  # B.19
        st.base_active, st.t = base_active, t
        st.steps += 1
        return AccelCommand(ddq, ddx, x, res.alpha, beta, res.active, base_active, sigma, lo, hi)


# ================================================================ App. B: traditional baseline
@dataclasses.dataclass(frozen=True)
class PinvAccelConfig:
    """The "traditional" acceleration-level controller of §B.4.3.

    Attributes:
        dt, kp, kd, gamma1, gamma2: as in `AMDConfig`.
        manipulability: add (I − J⁺J) q̈_A with q̈_A of eq. B.13 (thesis: yes).
        limit: what keeps the command within the joint acceleration bounds (B.6–B.8),
            which the thesis's baseline does not consider: "clip" each joint (what a robot
            driver does) or "none".
        bounds: joint bounds; None: the device's.
    """

    dt: float = 0.005
    kp: float = 20.0
    kd: float = 10.0
    gamma1: float = 5.0
    gamma2: float = 0.5
    manipulability: bool = True
    limit: Literal["clip", "none"] = "clip"
    bounds: JointBounds | None = None

    def __post_init__(self) -> None:
        _dt(self.dt)
        if self.limit not in ("clip", "none"):
            raise InvalidInput(f"limit: expected 'clip' or 'none', got {self.limit!r}")


class PinvAccelController(_AccelBase):
    """q̈ = J⁺(ẍ − J̇q̇) + (I − J⁺J) q̈_A with the plain pseudoinverse J⁺ = Jᵀ(JJᵀ)⁻¹ (thesis §B.4.3).

    Args:
        device: the mobile manipulator.
        config: parameters.
    """

    def __init__(self, device: Device, config: PinvAccelConfig | None = None) -> None:
        super().__init__(device, config or PinvAccelConfig())
        self.clipped = 0

    def reset(self) -> None:
        """Fresh state (clip counter)."""
        self.clipped = 0

    def step(self, t: float, q, dq, x_des, dx_des, ddx_des) -> AccelCommand:
        """One control step (arguments as `AMDController.step`)."""
        q, dq, x_des, dx_des, ddx_des = self._inputs(q, dq, x_des, dx_des, ddx_des)
        c, n = self.config, self.device.n
        x, J6, J, b, ddx = self._task(q, dq, x_des, dx_des, ddx_des)
        Jp = np.linalg.pinv(J)
        ddq = Jp @ (ddx - b)
        if c.manipulability:
            ddq = ddq + (np.eye(n) - Jp @ J) @ self._tertiary(J6, dq)
        lo, hi = _acc_bounds(q, dq, self.bounds, c.dt)
        if c.limit == "clip":
            out = np.clip(ddq, lo, hi)
            self.clipped += int(np.any(out != ddq))
            ddq = out
        Jm = J[:, self.n_base:]
        sigma = float(np.sqrt(max(np.linalg.eigvalsh(Jm @ Jm.T)[0], 0.0)))
        return AccelCommand(ddq, ddx, x, 1.0, 1.0, np.ones(n, bool), True, sigma, lo, hi)


# ========================================================= App. A: velocity-level controller
@dataclasses.dataclass(frozen=True)
class DMConfig:
    """Directional manipulability enhancement (thesis §A.3.1, §A.3.3, §A.4.3).

    Attributes:
        u: (3,) world direction of the force to enhance (normalised).
        torque_limits: (m,) τ_lim of W_τ = diag(1/τ_lim) [N m] (thesis: W_τ = diag(1,1,1,1,2.5,2.5,2.5)).
        k_c: Cartesian gain k_C of eq. A.18 (thesis 0.01).
        k_n: null-space gain k_N of eq. A.20 (thesis k_H = 0.2).
        axes: Cartesian components optimised by eq. A.18 (thesis: "z" only); the others get 0.
        x_min, x_max: (len(axes),) position bounds of those components [m] (thesis z ∈ [0.36, 0.56]).
    """

    u: tuple[float, ...] = (0.0, 0.0, 1.0)
    torque_limits: tuple[float, ...] = W_TAU_LIMITS
    k_c: float = 0.01
    k_n: float = 0.2
    axes: str = "z"
    x_min: tuple[float, ...] = (0.36,)
    x_max: tuple[float, ...] = (0.56,)

    def __post_init__(self) -> None:
        object.__setattr__(self, "u", tuple(unit_vector("u", self.u, 3)))
        t = as_array("torque_limits", self.torque_limits, ndim_min=1)
        if (t <= 0).any():
            raise InvalidInput("torque_limits: every entry must be > 0")
        if not self.axes or any(a not in "xyz" for a in self.axes) or len(set(self.axes)) != len(self.axes):
            raise InvalidInput(f"axes: expected distinct axes from 'xyz', got {self.axes!r}")
        lo = as_array("x_min", self.x_min, shape_tail=(len(self.axes),))
        hi = as_array("x_max", self.x_max, shape_tail=(len(self.axes),))
        if (lo > hi).any():
            raise InfeasibleLimits(f"x_min > x_max: {lo.tolist()} > {hi.tolist()}")
        for name in ("k_c", "k_n"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0:
                raise InvalidInput(f"{name}: must be finite and >= 0, got {v!r}")


@dataclasses.dataclass(frozen=True)
class WeightedConfig:
    """Parameters of the App. A velocity-level controller.

    Attributes:
        dt: sampling time T of eq. A.13 [s].
        k_x: K_x of eq. A.19 [1/s] (thesis 10).
        epsilon: ε of eq. A.14 (thesis 0.2).
        distribution: "weighted" (W_x with adaptive γ, eqs. A.11–A.15), "pinv" (the
            traditional plain pseudoinverse J⁺ of the wheel-speed Jacobian, §A.4.2) or
            "pinv_generalized" (J_q⁺ of the generalized Jacobian [J_b, J_m], base in m/s and
            rad/s, mapped to the wheels by P⁺: the pseudoinverse's split depends on the base's units).
        null_space: projector of the DM null-space stage (see
            `WeightedDistributionController._null_motion`): "generalized" (default; reproduces
            the thesis's §A.4.3 numbers) or "weighted" (eq. A.19 as printed).
        dm: directional manipulability enhancement, or None.
        bounds: joint bounds of the generalized coordinates [x_b, y_b, θ_b, q_m]; None: the device's.
        geometry: Mecanum geometry {wheel_radius, half_length, half_width} [m]; None: the device's.
    """

    dt: float = 0.01
    k_x: float = 10.0
    epsilon: float = 0.2
    distribution: Literal["weighted", "pinv", "pinv_generalized"] = "weighted"
    null_space: Literal["generalized", "weighted"] = "generalized"
    dm: DMConfig | None = None
    bounds: JointBounds | None = None
    geometry: dict | None = None

    def __post_init__(self) -> None:
        _dt(self.dt)
        if self.distribution not in ("weighted", "pinv", "pinv_generalized"):
            raise InvalidInput(
                f"distribution: expected 'weighted', 'pinv' or 'pinv_generalized', got {self.distribution!r}")
        if self.null_space not in ("generalized", "weighted"):
            raise InvalidInput(f"null_space: expected 'generalized' or 'weighted', got {self.null_space!r}")
        if not math.isfinite(self.k_x) or self.k_x < 0:
            raise InvalidInput(f"k_x: must be finite and >= 0, got {self.k_x!r}")
        distribution_gamma(0.0, self.epsilon)  # validates epsilon


@dataclasses.dataclass(frozen=True)
class VelocityCommand:
    """One velocity-level command of the App. A controller.

    Attributes:
        v: (b + m,) [wheel speeds (4) [rad/s]; arm joint rates [rad/s]] (eq. A.5).
        dq: (n,) generalized velocities (ẋ_b, ẏ_b, θ̇_b, q̇_m) = (P v_b; v_m) [m/s, rad/s].
        x: (3,) end-effector position from the kinematics [m].
        gamma: motion-distribution weight γ (A.14).
        eta: η of eq. A.15 (arm-only demand).
        dm: directional manipulability H₂ of the arm (NaN without a DMConfig) [N].
        clipped: whether a velocity bound had to be enforced on the command.
    """

    v: np.ndarray
    dq: np.ndarray
    x: np.ndarray
    gamma: float
    eta: float
    dm: float
    clipped: bool


class WeightedDistributionController:
    """Weighted-pseudoinverse motion distribution with DM enhancement (thesis §A.3, eqs. A.11–A.20).

    Tracking (A.19 with v_n = 0): v = J†(ẋ_d + K_x(x_d − x)). γ comes from the arm-only
    solution (γ = 0): η (A.15) compares its arm rates with the local bounds of A.13, and
    γ (A.14) then weights the distribution (A.12). Stages:

    * ``"track"``: trajectory tracking only;
    * ``"dm_cartesian"``: v = J† v_c with v_c,i = k_C [∇_x H₂]_i inside the position bounds
      of the optimised axes, 0 otherwise (A.17–A.18);
    * ``"dm_null"``: tracking plus (I − J†J) v_n, v_n = k_N [0; ∇_{q_m}H₂ᵀ] (A.19–A.20).

    The command is finally kept within the arm's local velocity bounds (A.13) and the
    base's velocity bounds (Table B.1) by clipping, which `VelocityCommand.clipped` reports.

    Args:
        device: the mobile manipulator (``rhi.device("wmm")``).
        config: parameters.
    """

    def __init__(self, device: Device, config: WeightedConfig | None = None) -> None:
        _check_base(device, 3)
        self.device = device
        self.config = config or WeightedConfig()
        self.bounds = self.config.bounds if self.config.bounds is not None else joint_bounds(device)
        if self.bounds.n != device.n:
            raise InvalidInput(f"bounds: expected {device.n} joints, got {self.bounds.n}")
        self.geometry = dict(self.config.geometry or wheel_geometry(device.name))
        mecanum_map(0.0, **self.geometry)  # validates the geometry
        self.kin = WMMKinematics(device)
        self.n_wheels = 4
        self.m = device.n - 3
        dm = self.config.dm
        if dm is not None and len(dm.torque_limits) != self.m:
            raise InvalidInput(f"dm.torque_limits: expected {self.m} entries, got {len(dm.torque_limits)}")

    def jacobian(self, q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, J, P): position (3,) [m], WMM Jacobian J = [J_b P, J_m] (3, 4 + m) (eq. A.5), P (3, 4) (eq. A.21)."""
        q = _finite("q", q, self.device.n)
        x, J6 = self.kin.jacobian6(q)
        P = mecanum_map(q[2], **self.geometry)
        return x, np.concatenate([J6[:3, :3] @ P, J6[:3, 3:]], axis=1), P

    def dm(self, q) -> float:
        """H₂ of the arm at q (A.8) for the configured direction [N]."""
        if self.config.dm is None:
            raise InvalidInput("config.dm: no DMConfig given")
        _, J6 = self.kin.jacobian6(_finite("q", q, self.device.n))
        return float(dm_value(J6[:3, 3:], self.config.dm.u, self.config.dm.torque_limits))

    def _dm_terms(self, J6):
        d = self.config.dm
        J6m = J6[:, 3:]
        dJ, _ = chain_jacobian_derivatives(J6m, second=False)
        Jm = J6m[:3]
        g = dm_gradient(Jm, dJ, d.u, d.torque_limits)
        return float(dm_value(Jm, d.u, d.torque_limits)), g, Jm

    def _null_motion(self, J, J6, P, Jp, grad_arm) -> np.ndarray:
        """(I − J†J) v_n, v_n = [0; k_N ∇_{q_m}H₂ᵀ] (eqs. A.19–A.20), as [wheel speeds; arm rates].

        ``null_space="weighted"``: the projector of the distribution's own J† (eq. A.19 as
        printed; at γ = 0 that J† has no base rows and the base cannot move).
        ``"generalized"``: the orthogonal projector of the generalized Jacobian
        J_q = [J_b, J_m] (eq. A.7 with Q = I), whose base motion is sent to the wheels as
        P⁺ q̇_b; the base then moves with the arm's self-motion.
        """
        if self.config.null_space == "weighted":
            v = np.concatenate([np.zeros(self.n_wheels), grad_arm])
            return v - Jp @ (J @ v)
        Jq = J6[:3]
        vq = np.concatenate([np.zeros(3), grad_arm])
        Gi = _gram_inverse(Jq, 0.0)
        vq = vq - Jq.T @ (Gi @ (Jq @ vq)) if Gi is not None else vq - np.linalg.pinv(Jq) @ (Jq @ vq)
        return np.concatenate([np.linalg.pinv(P) @ vq[:3], vq[3:]])

    def step(self, t: float, q, x_des=None, dx_des=None, *, stage: str = "track") -> VelocityCommand:
        """One control step.

        Args:
            t: time [s] (unused by the law; kept for a uniform controller interface).
            q: (n,) configuration [x_b, y_b, θ_b, q_m].
            x_des, dx_des: (3,) desired position [m] and velocity [m/s] (not used by "dm_cartesian").
            stage: "track", "dm_cartesian" or "dm_null".

        Returns:
            `VelocityCommand`.
        """
        c = self.config
        if stage not in ("track", "dm_cartesian", "dm_null"):
            raise InvalidInput(f"stage: expected 'track', 'dm_cartesian' or 'dm_null', got {stage!r}")
        if stage != "track" and c.dm is None:
            raise InvalidInput(f"stage: {stage!r} needs config.dm")
        q = _finite("q", q, self.device.n)
        x, J6 = self.kin.jacobian6(q)
        P = mecanum_map(q[2], **self.geometry)
        J = np.concatenate([J6[:3, :3] @ P, J6[:3, 3:]], axis=1)
        nw, m = self.n_wheels, self.m
        h = math.nan
        grad = None
        if stage == "dm_cartesian":
            h, g, Jm = self._dm_terms(J6)
            gx = g @ np.linalg.pinv(Jm)  # A.10
            dx = np.zeros(3)
            d = c.dm
            for i, ax in enumerate(d.axes):
                k = "xyz".index(ax)
                if d.x_min[i] <= x[k] <= d.x_max[i]:
                    dx[k] = d.k_c * gx[k]  # A.18
        else:
            x_des = _finite("x_des", x_des, 3)
            dx_des = _finite("dx_des", dx_des, 3)
            dx = dx_des + c.k_x * (x_des - x)
            if stage == "dm_null":
                h, g, _ = self._dm_terms(J6)
                grad = c.dm.k_n * g  # v_n of A.20 (arm part)
            elif c.dm is not None:
                h = float(dm_value(J6[:3, 3:], c.dm.u, c.dm.torque_limits))
        vlo, vhi = _vel_bounds(q, self.bounds, c.dt)
        gamma, eta = math.nan, math.nan
        if c.distribution == "pinv":
            Jp = np.linalg.pinv(J)
        elif c.distribution == "pinv_generalized":
            Jp = np.vstack([np.linalg.pinv(P) @ np.eye(3, self.device.n), np.eye(self.device.n)[3:]]) @ np.linalg.pinv(J6[:3])
        else:
            J0 = weighted_pinv_psd(J, motion_weights(0.0, nw, m))
            v0 = J0 @ dx
            if grad is not None:
                v0 = v0 + self._null_motion(J, J6, P, J0, grad)
            eta = float(distribution_ratio(v0[nw:], vlo[3:], vhi[3:]))
            gamma = float(distribution_gamma(eta, c.epsilon))
            Jp = J0 if gamma == 0.0 else weighted_pinv_psd(J, motion_weights(gamma, nw, m))
        v = Jp @ dx
        if grad is not None:
            v = v + self._null_motion(J, J6, P, Jp, grad)  # A.19
        # enforce the bounds: arm rates (A.13), base generalized velocity (Table B.1)
        v_arm = np.clip(v[nw:], vlo[3:], vhi[3:])
        dqb = P @ v[:nw]
        ratio = np.max(np.abs(dqb) / np.maximum(np.abs(np.where(dqb >= 0, vhi[:3], vlo[:3])), _EPS))
        clipped = bool(np.any(v_arm != v[nw:]) or ratio > 1.0)
        if ratio > 1.0:
            v[:nw] /= ratio
            dqb = dqb / ratio
        v[nw:] = v_arm
        return VelocityCommand(v, np.concatenate([dqb, v_arm]), x, gamma, eta, h, clipped)
