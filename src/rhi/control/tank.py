"""The null-space energy tank: an explicit energy budget for the allocation and the null-space objectives.

Why. The null-space torque of a redundant haptic interface — the allocation's Z y under
saturation (ASCM, Algorithm 1) and the objectives' projected gradients −β N ∇ν (eqs. 6.6,
7.16) — is not the gradient of any potential: the projector N(q), the held set of ASCM, the
scaling β and the FME schedule all change with the state, so the null-space side of the
controller is an active source. In the §6.4 palpation set-up it puts joules into the
self-motion, which reach the hand through the joint stops and the velocity coupling of the
self-motion with the handle (`rhi.experiments.beyond.passivity` measures every source).

What. An energy tank (Ferraguti, Secchi and Fantuzzi, "A tank-based approach to impedance
control with variable stiffness", ICRA 2013; in the null space of a redundant robot as
Dietrich, Wu, Bussmann, Ott and Albu-Schäffer, "Passive hierarchical impedance control via
energy tanks", RA-L 2017) with two accounts, each a store [J] that meters, exactly under the
zero-order hold, the work of its share of the controller's null-space torque over each hold
interval (N = I − JᵀJ#ᵀ; a null-space torque puts no force at the handle, J#ᵀN = 0; g_N, the
null-space part of the gravity compensation, only cancels the plant's gravity and is left out):

    T(k) = min(T(k−1) − e(k−1)ᵀ(q(k) − q(k−1)), capacity),    T(0) = ``initial``.

- The *allocation's account* T_A meters e_A = N τ_a − g_N − α d: the allocation's null-space torque
  (ASCM's Z y, eq. 7.8, with the safety torques' part its held joints carry), and its damper.
- The *objectives' account* T_O meters the rest, e_O = N τ − g_N − e_A: the safety torques' shares
  in Algorithm 2 (the null-space damping −k_D q̇, which fills it, and the joint-limit barrier) and the
  objectives, which draw on it. So the objectives spend only what the damping has dissipated.

Each tick (`tank_blend`):

1. Book the last hold interval in both accounts (above).
2. The allocation's damper (Hannaford and Ryu's series passivity controller, on the allocation's
   account only): predict the coming interval's work of e_A as ``w(e) = ΔT eᵀq̇ + ½ ΔT² eᵀ M⁻¹ e``
   (the work of a held torque on the free mechanism, as in `rhi.control.passivity`). If it exceeds
   T_A, the damper −α d takes out the deficit, ``α = deficit / (ΔT q̇ᵀd)`` bounded by ``0.5 / ΔT``
   (H&R's sampled damper that does not overshoot) and by the room the torque box leaves; what is
   left is carried (T_A < 0). d (`damper_direction`) is the inertia-weighted self-motion damping
   N M q̇ projected onto the null-space torques that move no held joint's torque out of its limit:
   it puts no force at the handle, its power −α q̇ᵀd is never positive, and it may take torque off
   a held joint.
3. Scale the objectives' share (what Algorithm 2 adds with the objectives, run once with them
   and once without) by the largest λ ∈ [0, 1] with ``w(e_O0 + λ N(τ₁ − τ₀)) ≤ T_O`` that keeps
   the box (e_O0: the safety shares).
4. Send ``τ₀ − α d + λ (τ₁ − τ₀)`` and record each account's null-space torque for step 1.

The primary task torque (the rendered wall, its damping and compensation) and the allocation
are never scaled, nor are the safety torques (null-space damping, joint-limit barrier): their
held part is the same in τ₀ and τ₁, and their share in Algorithm 2 is (1 − λ) β₀ + λ β₁ (β₀,
β₁: Algorithm 2's box scaling without and with the objectives). With λ = 0 and the damper
idle the tick is exactly the tick without objectives; with λ = 1, the thesis's tick.

With ``allocation="gate"`` (`redistribution_gate`) step 2 is replaced: the allocation's account meters only
ASCM's redistribution, e_A = γ θ (N τ_ASCM − g_N) (the held safety torques go to the objectives' account), and
before the safety torques and Algorithm 2 the controller sends θ τ_ASCM + (1 − θ) τ_scaling with the largest
θ ∈ [0, 1] whose predicted work w(θ e_A) fits T_A: the redistribution spends only what its own negative work
put into the account. Where θ < 1 the task force lies between simple scaling's and ASCM's (the rendered force
gives way, as with simple scaling); the safety torques are added after it, unscaled.

What it guarantees, and what not. The objectives spend only what their account holds. The
allocation's account is kept ≥ 0 by a dissipative torque, not by scaling: where the damper
cannot take the whole deficit out — every null-space torque would push a held joint out of
its limit (the cone of step 2 is {0}), or the bound on α or the box stops it — the deficit is
carried (T_A < 0) and taken out in the next samples. The barrier draws on the objectives'
account (it is never scaled: a barrier that overdraws it leaves the objectives off until the
damping has refilled it). ``capacity`` bounds how much stored energy a later burst may release.
`rhi.experiments.beyond.passivity` measures every source from the plant's signals.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np

from rhi.control.saturation import scaling_alpha
from rhi.errors import InvalidInput

#: How the allocation's account is kept (`NullSpaceTank.allocation`).
TankAllocation = Literal["damper", "gate"]


@dataclasses.dataclass(frozen=True)
class NullSpaceTank:
    """Settings of the null-space energy tank (``ControllerConfig.tank``).

    Attributes:
        initial: T(0) [J], the energy the null space may spend before it has dissipated any.
        capacity: the most the tank holds [J] (energy fed beyond it is not stored).
        allocation: how the allocation's account is kept: "damper" (step 2 above: the deficit taken out by
            the allocation's damper, carried where the held joints block it) or "gate" (`redistribution_gate`:
            the allocation's redistribution itself spends only what its account holds).
    """

    initial: float = 0.0
    capacity: float = 0.05
    allocation: TankAllocation = "damper"

    def __post_init__(self) -> None:
        if self.allocation not in ("damper", "gate"):
            raise InvalidInput(f"tank.allocation: expected 'damper' or 'gate', got {self.allocation!r}")
        for name in ("initial", "capacity"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
                raise InvalidInput(f"tank.{name}: must be finite and >= 0 [J], got {v!r}")
        if self.initial > self.capacity:
            raise InvalidInput(f"tank.initial: {self.initial} J exceeds tank.capacity {self.capacity} J")


@dataclasses.dataclass
class TankState:
    """The tank's two accounts after a tick.

    Attributes:
        energy: T_O [J], the objectives' account (negative only when the safety shares alone drained it).
        allocation: T_A [J], the allocation's account (negative: a deficit the damper could not yet take out).
        scale: λ of the last tick, the factor on the objectives' torque (1: untouched).
        damping: α of the last tick, the allocation damper's rate [1/s] (0: idle).
        gate: θ of the last tick, the share of the allocation's redistribution sent (1: untouched; "gate" only).
        t: time of the last tick [s].
        position: (n,) q of the last tick [rad].
        effort: (2, n) the metered null-space torques e_O, e_A sent at the last tick [N m].
    """

    energy: float = 0.0
    allocation: float = 0.0
    scale: float = 1.0
    damping: float = 0.0
    gate: float = 1.0
    t: float = -math.inf
    position: np.ndarray | None = None
    effort: np.ndarray | None = None


#: A face of the damper's cone is used when the smallest eigenvalue of Q_AA exceeds FACE_TOL tr Q (conditioning).
FACE_TOL = 1e-6
#: How far [N m s] a damper direction may point out of the box at a held joint and still count as inward (rounding).
INWARD_TOL = 1e-12


def damper_direction(Q: np.ndarray, dq: np.ndarray, held: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The damper direction d (n,) [N m s]: H&R's inertia-weighted null-space damping, no held joint pushed out.

    Unconstrained, d = Q q̇ with Q = N M = M − JᵀΛJ (the null-space inertia: symmetric, positive
    semi-definite, J#ᵀQ = 0), so the damper −α d (α [1/s]) is Hannaford and Ryu's α M q̇ restricted
    to the self-motion: it puts no force at the handle and, sampled, slows the self-motion velocity
    by the factor α ΔT in every mode at once. At a held joint i the damper must not push τ_i further
    out (sign(τ_i) d_i ≥ 0): d is the projection of Q q̇ onto that polyhedral cone of null-space
    torques in the kinetic metric M⁻¹, found among the projections onto its faces {d_A = 0},
    ``d = Q q̇ − Q_{:A} Q_AA⁻¹ (Q q̇)_A`` (A ⊆ held): the feasible one of largest power q̇ᵀd, which is
    ‖d‖²_{M⁻¹} ≥ 0, so −α d only dissipates.

    Args:
        Q: (n, n) the null-space inertia N M [kg m²].
        dq: (n,) joint velocities [rad/s].
        held: (n,) bool, ASCM's held joints.
        tau: (n,) the torque whose held entries are at their limits [N m] (their signs say which way is out).
    """
    base = Q @ dq
    H = np.flatnonzero(held)
    tol = FACE_TOL * float(np.trace(Q))
    best, p_best = np.zeros(Q.shape[0]), 0.0
    for mask in range(1 << len(H)):
        A = [int(H[j]) for j in range(len(H)) if mask >> j & 1]
        d = base
        if A:
            G = Q[np.ix_(A, A)]
            if np.linalg.eigvalsh(G).min() <= tol:  # as many pinned entries as null-space directions, or nearly
                continue
            d = base - Q[:, A] @ np.linalg.solve(G, base[A])
        if any(math.copysign(1.0, tau[i]) * d[i] < -INWARD_TOL for i in H if int(i) not in A):
            continue
        p = float(dq @ d)
        if p > p_best:
            best, p_best = d, p
    return best


def hold_work(e: np.ndarray, v: np.ndarray, Minv: np.ndarray, dt: float) -> float:
    """w(e) = ΔT eᵀv + ½ ΔT² eᵀ M⁻¹ e: work [J] of the effort e held for ΔT on a free port moving at v."""
    return dt * float(e.dot(v)) + 0.5 * dt * dt * float(e.dot(Minv.dot(e)))


def largest_scale(E: float, base: np.ndarray, part: np.ndarray, v: np.ndarray, Minv: np.ndarray, dt: float) -> float:
    """The largest λ ∈ [0, 1] with w(base + λ part) ≤ E (0 when even λ = 0 exceeds E).

    w(base + λ part) = A λ² + B λ + C is convex in λ, so the bound is its larger root.
    """
    A = 0.5 * dt * dt * float(part.dot(Minv.dot(part)))
    B = dt * float(part.dot(v)) + dt * dt * float(part.dot(Minv.dot(base)))
    C = hold_work(base, v, Minv, dt) - E
    if A + B + C <= 0.0:
        return 1.0
    if C >= 0.0:
        return 0.0
    lam = (-B + math.sqrt(max(B * B - 4.0 * A * C, 0.0))) / (2.0 * A) if A > 0.0 else -C / B
    return min(max(lam, 0.0), 1.0)


def redistribution_gate(tank: NullSpaceTank, s: TankState, t: float, q: np.ndarray, dq: np.ndarray, Minv: np.ndarray,
                        e: np.ndarray) -> float:
    """θ ∈ [0, 1]: the share of the allocation's redistribution e = N τ_ASCM − g_N its account pays for (``"gate"``).

    The largest θ whose predicted work over the coming interval, w(θ e) (`hold_work`), fits T_A as step 1
    will book it at this tick; 0 where no interval is known yet (the first tick) and e is not zero.
    The controller then sends θ τ_ASCM + (1 − θ) τ_scaling (`rhi.control.allocation.scaling`):
    both in the box, the task force between simple scaling's and ASCM's, the null-space torque θ e.

    Args:
        tank: the settings.
        s: the tank's state (read, not advanced: `tank_blend` books and records).
        t: time [s].
        q: (n,) joint positions [rad].
        dq: (n,) joint velocities [rad/s].
        Minv: (n, n) M⁻¹.
        e: (n,) the redistribution's null-space torque [N m].
    """
    T_A = s.allocation
    if s.position is not None and s.effort is not None:
        T_A = min(T_A - float(s.effort[1].dot(q - s.position)), tank.capacity)
    dt = t - s.t
    if not (dt > 0.0 and math.isfinite(dt)):
        return 0.0 if np.any(e != 0.0) else 1.0
    return largest_scale(T_A, np.zeros_like(e), e, dq, Minv, dt)


def tank_blend(tank: NullSpaceTank, s: TankState, t: float, q: np.ndarray, dq: np.ndarray, J: np.ndarray,
               Jsharp: np.ndarray, Minv: np.ndarray, g_null: np.ndarray, tau_a: np.ndarray, tau0: np.ndarray,
               tau1: np.ndarray, d: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Book the last interval, damp the allocation's deficit, choose λ: the torque to send (n,) [N m] (steps 1–4).

    Args:
        tank: the settings.
        s: the tank's state, advanced.
        t: time [s].
        q: (n,) joint positions [rad].
        dq: (n,) joint velocities [rad/s].
        J: (m, n) task Jacobian.
        Jsharp: (n, m) its dynamically consistent inverse J#.
        Minv: (n, n) M⁻¹.
        g_null: (n,) the null-space part of the gravity compensation in the torque [N m] (zeros without).
        tau_a: (n,) the allocation's torque (the task, the allocation's null-space torque and, with the
            allocation's damper, the safety torques' held part, before Algorithm 2) [N m].
        tau0: (n,) the tick's torque without the objectives [N m], in the box.
        tau1: (n,) the tick's torque with them [N m], in the box.
        d: (n,) the damper's direction (`damper_direction`) [N m s].
        lo: (n,) lower torque limits [N m].
        hi: (n,) upper torque limits [N m].
    """
    if s.position is not None and s.effort is not None:  # 1. each account books its held torque's exact work
        dqk = q - s.position
        s.energy = min(s.energy - float(s.effort[0].dot(dqk)), tank.capacity)
        s.allocation = min(s.allocation - float(s.effort[1].dot(dqk)), tank.capacity)
    dt = t - s.t

    def null(tau: np.ndarray) -> np.ndarray:  # N τ, N = I − JᵀJ#ᵀ
        return tau - J.T.dot(Jsharp.T.dot(tau))

    lam, s.damping = 0.0, 0.0
    tau = tau0
    e_a = null(tau_a) - g_null
    if dt > 0.0 and math.isfinite(dt):
        deficit = hold_work(e_a, dq, Minv, dt) - s.allocation
        p = float(dq.dot(d))  # ‖d‖²_{M⁻¹} ≥ 0: the damper −α d dissipates α p
        # 2. the allocation's damper on its account's deficit, in the box room left
        if deficit > 0.0 and p > 0.0 and tank.allocation == "damper":
            s.damping = min(deficit / (dt * p), 0.5 / dt)
            sigma = scaling_alpha(-s.damping * d, tau0, lo=lo, hi=hi)
            s.damping = 0.0 if sigma is None else s.damping * sigma
            tau = tau0 - s.damping * d
        diff = tau1 - tau0  # 3. the objectives' share, by what their account holds and the box leaves
        lam = largest_scale(s.energy, null(tau0) - g_null - e_a, null(diff), dq, Minv, dt)
        room = scaling_alpha(diff, tau, lo=lo, hi=hi) if lam > 0.0 else 0.0
        lam = min(lam, 0.0 if room is None else room)
    tau = np.minimum(np.maximum(tau + lam * (tau1 - tau0), lo), hi)
    e_a = e_a - s.damping * null(d)  # 4. recorded: the allocation's account holds its damper, the other the rest
    s.scale, s.t, s.position = lam, t, np.array(q, dtype=float)
    s.effort = np.array([null(tau) - g_null - e_a, e_a])
    return tau


__all__ = ["FACE_TOL", "INWARD_TOL", "NullSpaceTank", "TankState", "damper_direction", "hold_work", "largest_scale",
           "TankAllocation", "redistribution_gate", "tank_blend"]
