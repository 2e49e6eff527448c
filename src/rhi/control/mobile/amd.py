"""Adaptive motion distribution (AMD) of a mobile manipulator at the acceleration level (thesis App. B).

`AMDController`: a saturation-in-the-null-space loop over the joint acceleration bounds
(B.6–B.9) keeps the base disabled until the arm alone cannot do the task or is near a
singularity (σ_min(J_m) < σ_m,min), with the task scaling α and tertiary scaling β of
Fig. B.4, the tertiary singularity-avoidance objective H = det(J_m J_mᵀ) projected by the
auxiliary projector P_A (B.10–B.18) and the base stopping transition (B.20).
`AccelControllerBase` holds what the acceleration-level controllers share (also the
baseline of `rhi.control.mobile.baselines`).
"""

from __future__ import annotations

import abc
import dataclasses
import math

import numpy as np

from rhi.control.mobile.bounds import (
    JointBounds,
    acceleration_bounds_unchecked,
    base_stop_acceleration,
    check_dt,
    joint_bounds,
    scale_factor_lists,
)
from rhi.control.mobile.kinematics import (
    WMMKinematics,
    check_base,
    check_vector,
    det_terms,
    gram_inverse,
)
from rhi.control.mobile.protocol import MobileStep
from rhi.devices.model import Device
from rhi.errors import InfeasibleLimits, InvalidInput


def auxiliary_projector(P_N, active) -> np.ndarray:
    """P_A = [I − ((I − S) P_N)⁺] P_N (thesis eq. B.10), the readable reference of `auxiliary_projection`.

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


def auxiliary_projection(J, active, gram_inv, v) -> np.ndarray:
    """P_A v with the auxiliary projector of eq. B.10, from the active columns J_S (what `AMDController` runs).

    P_A is the orthogonal projector onto the motions of the active joints that leave the
    task unchanged: P_A v = (I − J_S⁺J_S) v_S on the active joints and 0 on the others, the
    same matrix as `auxiliary_projector` (tested), in O(r n) without forming I − J⁺J.

    Args:
        J: (r, n) task Jacobian.
        active: (n,) bool diagonal of the selection matrix S; J_S = J[:, active] of full row rank.
        gram_inv: (r, r) (J_S J_Sᵀ)⁻¹ (`SNSResult.gram_inv`).
        v: (n,) vector to project.

    Returns:
        (n,) P_A v.
    """
    out = np.where(active, v, 0.0)
    JS = J[:, active]
    out[active] -= JS.T @ (gram_inv @ (JS @ out[active]))
    return out


def tertiary_acceleration(grad, hess_dq, dq_m, *, gamma1: float, gamma2: float, n_base: int) -> np.ndarray:
    """q̈_A = [0; γ₁ ∇²H q̇_m + γ₂(γ₁ ∇Hᵀ − q̇_m)] (thesis eq. B.13): d/dt of q̇_N = γ₁ [0; ∇Hᵀ] (B.12) plus tracking of it.

    Args:
        grad: (m,) ∇_{q_m} H.
        hess_dq: (m,) ∇²_{q_m} H q̇_m (`manipulability_det_hessian` @ q̇_m, or `det_terms`).
        dq_m: (m,) arm joint velocities [rad/s].
        gamma1: positive gain γ₁ (thesis: 5).
        gamma2: positive gain γ₂ (thesis: 0.5).
        n_base: number of base coordinates (zero entries).

    Returns:
        (n_base + m,) q̈_A [rad/s²].
    """
    out = np.zeros(n_base + len(dq_m))
    out[n_base:] = gamma1 * hess_dq + gamma2 * (gamma1 * grad - dq_m)
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


def sns_acceleration(J, b, ddx, *, lo, hi, enabled, fixed, rank_tol: float = 1e-6) -> SNSResult:
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
        lo: (n,) lower acceleration bounds (B.6–B.8).
        hi: (n,) upper acceleration bounds.
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
        Ginv = gram_inverse(JS, rank_tol)
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
        s, crit = scale_factor_lists(al, cl, lo=lo_l, hi=hi_l, act=active.tolist())
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
        check_dt(self.dt)
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


class AccelControllerBase(abc.ABC):
    """Shared parts of the acceleration-level controllers."""

    def __init__(self, device: Device, config, n_base: int = 3) -> None:
        check_base(device, n_base)
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
        q = check_vector("q", q, n)
        dq = check_vector("dq", dq, n)
        x_des = check_vector("x_des", x_des, 3)
        dx_des = check_vector("dx_des", dx_des, 3)
        ddx_des = check_vector("ddx_des", ddx_des, 3)
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
        _, grad, hvp, sigma = det_terms(J6[:, nb:], dq[nb:])
        return tertiary_acceleration(grad, hvp, dq[nb:], gamma1=c.gamma1, gamma2=c.gamma2, n_base=nb), sigma

    @abc.abstractmethod
    def step(self, t: float, q, dq, x_des, dx_des, ddx_des) -> AccelCommand:
        """One control step: the joint accelerations for the desired end-effector motion."""

    def advance(self, t: float, q, dq, x_des, dx_des, ddx_des, *, stage: str = "track") -> MobileStep:
        """One sample for `rhi.sim.mobile.simulate_mobile`: `step`, integrated as q̇⁺ = q̇ + q̈T (no stages)."""
        cmd = self.step(t, q, dq, x_des, dx_des, ddx_des)
        return MobileStep(dq + cmd.ddq * self.config.dt, cmd.ddq, cmd.x, {
            "base_active": float(cmd.base_active), "alpha": cmd.alpha, "beta": cmd.beta, "sigma": cmd.sigma})


class AMDController(AccelControllerBase):
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
            x_des: (3,) desired end-effector position [m] (world frame).
            dx_des: (3,) desired end-effector velocity [m/s].
            ddx_des: (3,) desired end-effector acceleration [m/s²].

        Returns:
            `AccelCommand`; integrate q̈ over one sample (q̇⁺ = q̇ + q̈T) to keep every bound.
        """
        q, dq, x_des, dx_des, ddx_des = self._inputs(q, dq, x_des, dx_des, ddx_des)
        c, st, nb, n = self.config, self.state, self.n_base, self.device.n
        x, J6, J, b, ddx = self._task(q, dq, x_des, dx_des, ddx_des)
        lo, hi = acceleration_bounds_unchecked(q, dq, self.bounds, c.dt)
        ddq_A, sigma = self._tertiary(J6, dq)
        release = c.sigma_min if c.sigma_release is None else c.sigma_release
        threshold = release if st.base_active else c.sigma_min
        near_singular = c.singularity_avoidance and sigma < threshold
        res: SNSResult | None = None
        if not near_singular:
            fixed = np.zeros(n)
            fixed[:nb] = base_stop_acceleration(dq[:nb], lo[:nb], hi[:nb], c.dt)
            res = sns_acceleration(J, b, ddx, lo=lo, hi=hi, enabled=self._arm_mask, fixed=fixed)
            if not res.feasible:
                res = None
        base_active = res is None
        if res is None:
            res = sns_acceleration(J, b, ddx, lo=lo, hi=hi, enabled=self._all_mask, fixed=self._zeros)
            st.stop_t0, st.stop_v = None, None
        elif st.base_active or (st.stop_t0 is None and np.any(dq[:nb] != 0)):
            st.stop_t0, st.stop_v = t, dq[:nb].copy()  # B.20: t₀ and V_b
        ddq, beta = res.ddq, 0.0
        if c.singularity_avoidance and res.gram_inv is not None:
            # q̈_t = β P_A q̈_A (B.10–B.11, B.13) with the β of Fig. B.4, then B.19
            lam = auxiliary_projection(J, res.active, res.gram_inv, ddq_A)
            beta, _ = scale_factor_lists(lam.tolist(), ddq.tolist(), lo=lo.tolist(), hi=hi.tolist(), act=[True] * n)
            ddq = np.minimum(np.maximum(ddq + beta * lam, lo), hi)
        st.base_active, st.t = base_active, t
        st.steps += 1
        return AccelCommand(ddq, ddx, x, res.alpha, beta, res.active, base_active, sigma, lo, hi)
