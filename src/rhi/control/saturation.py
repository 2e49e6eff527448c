"""Actuator saturation: observer (ASO), hysteresis, FME transition, ASCM and the tertiary scaling β.

Pure functions on arrays plus small dataclasses with explicit state (thesis §6.3.2, §7.3–7.4).

Torque allocation is written in one form shared by every method:

    τ(α, y) = α a + b + Z y

with ``a = Jᵀ F_render`` the scalable (rendered-force) torque, ``b`` the torque that is not
scaled (damping, gravity), and ``Z`` (n, n−m) an orthonormal basis of the range of the
torque null-space projector ``N = I − Jᵀ J#ᵀ`` (eq. 7.5), i.e. of the torques with
``J#ᵀ τ = 0``. ``N τ_N = Z y`` for ``τ_N = Z y``, so every allocation below produces the
task-space force ``J#ᵀ τ = J#ᵀ(α a + b)`` exactly.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import linprog

from rhi._validate import as_array
from rhi.errors import InfeasibleLimits, InvalidInput

_TOL = 1e-12


# ------------------------------------------------------------------ limits, bases
def check_torque_limits(torque_min, torque_max, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Validate torque limits for control: finite, ``torque_min < 0 < torque_max``.

    Args:
        torque_min: (n,) lower limits [N m], each < 0.
        torque_max: (n,) upper limits [N m], each > 0.
        n: expected number of joints.

    Raises:
        InvalidInput: NaN/inf or wrong shape.
        InfeasibleLimits: a limit of the wrong sign (zero torque must lie strictly inside).
    """
    lo = as_array("torque_min", torque_min, ndim_min=1, shape_tail=(n,) if n else ())
    hi = as_array("torque_max", torque_max, ndim_min=1, shape_tail=(n,) if n else ())
    if lo.shape != hi.shape or lo.ndim != 1:
        raise InvalidInput(f"torque_min/torque_max: expected two (n,) vectors, got {lo.shape} and {hi.shape}")
    if np.any(lo >= 0):
        raise InfeasibleLimits(f"torque_min: every entry must be < 0, got {lo.tolist()}")
    if np.any(hi <= 0):
        raise InfeasibleLimits(f"torque_max: every entry must be > 0, got {hi.tolist()}")
    return lo, hi


def null_basis(J: np.ndarray, M: np.ndarray | None = None) -> np.ndarray:
    """Orthonormal basis Z (n, n−m) of range(I − Jᵀ J#ᵀ) = null(J M⁻¹) (kinematic: null(J)).

    Args:
        J: (m, n) Jacobian, full row rank.
        M: (n, n) joint-space inertia [kg m²] for the dynamically consistent J#, or None.
    """
    A = J if M is None else np.linalg.solve(M, J.T).T  # J M⁻¹ (M symmetric)
    m = J.shape[0]
    _, _, Vt = np.linalg.svd(A)
    return Vt[m:].T.copy()


def scaling_alpha(p: np.ndarray, c: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> float | None:
    """Largest α in [0, 1] with ``lo <= α p + c <= hi``; None when no α in [0, 1] is feasible."""
    a_lo, a_hi = 0.0, 1.0
    tol = 1e-12 * (1.0 + np.abs(p) + np.abs(c))
    for pi, ci, l, h, t in zip(p, c, lo, hi, tol):
        if abs(pi) <= t:
            if ci > h + 1e-12 or ci < l - 1e-12:
                return None
            continue
        r1, r2 = (l - ci) / pi, (h - ci) / pi
        if r1 > r2:
            r1, r2 = r2, r1
        a_lo, a_hi = max(a_lo, r1), min(a_hi, r2)
    if a_lo > a_hi + 1e-12:
        return None
    return max(a_hi, 0.0)


# ---------------------------------------------------------------------- ASO
def aso_volume(tau, torque_min, torque_max, S: float = 50.0) -> float:
    """Actuator saturation observer V ∈ [0, 1]: the tank of unused torque capacity (thesis eq. 6.14).

    V = (1 − exp(−S (−1)ⁿ Πᵢ (τᵢ − T_max,i)(τᵢ − T_min,i)/(T_max,i − T_min,i)²)) / (1 − exp(−S/4ⁿ)).
    V = 1 with every torque at the middle of its range, V = 0 when any torque is at or
    beyond a limit (the formula's sign flips outside the box; we return 0 there).

    Args:
        tau: (n,) joint torques τ_m [N m].
        torque_min, torque_max: (n,) limits [N m], min < max.
        S: shape factor S > 0 (Fig. 6.6 uses 50).
    """
    tau = np.asarray(tau, dtype=float)
    lo = np.asarray(torque_min, dtype=float)
    hi = np.asarray(torque_max, dtype=float)
    if np.any(tau >= hi) or np.any(tau <= lo):
        return 0.0
    n = tau.size
    prod = float(np.prod((hi - tau) * (tau - lo) / (hi - lo) ** 2))  # = (−1)ⁿ Π(...) with each factor > 0
    v = -math.expm1(-S * prod) / -math.expm1(-S / 4.0**n)
    return min(max(v, 0.0), 1.0)


def hysteresis(stiff: bool, V: float, eps1: float, eps2: float) -> bool:
    """Which desired FME is selected, with two thresholds against chattering (thesis eq. 6.15, §6.3.2).

    Switches to stiff when V < ε₁, back to free when V ≥ ε₂ (ε₁ <= ε₂); with ε₁ = ε₂ = ε
    this is the single-threshold switch of eq. 6.15.

    Returns:
        True for M_Stiff^des, False for M_Free^des.
    """
    if eps1 > eps2:
        raise InvalidInput(f"eps1: must be <= eps2, got eps1={eps1}, eps2={eps2}")
    if stiff:
        return not V >= eps2
    return V < eps1


@dataclasses.dataclass(frozen=True)
class TransitionConfig:
    """Parameters of the FME transition (thesis eqs. 6.15–6.19).

    Attributes:
        eps1: ASO threshold below which the transition free → stiff starts (thesis: 0.7).
        eps2: ASO threshold above which the transition stiff → free starts (thesis: 0.95).
        rho: duration per Frobenius distance ρ [s] (eq. 6.19; thesis: 0.003).
        S: ASO shape factor.
    """

    eps1: float = 0.7
    eps2: float = 0.95
    rho: float = 0.003
    S: float = 50.0

    def __post_init__(self) -> None:
        for name in ("eps1", "eps2", "rho", "S"):
            v = getattr(self, name)
            if not np.isfinite(v):
                raise InvalidInput(f"{name}: must be finite, got {v!r}")
        if not 0.0 <= self.eps1 <= self.eps2 <= 1.0:
            raise InvalidInput(f"eps1/eps2: need 0 <= eps1 <= eps2 <= 1, got {self.eps1}, {self.eps2}")
        if self.rho < 0 or self.S <= 0:
            raise InvalidInput(f"rho/S: need rho >= 0 and S > 0, got {self.rho}, {self.S}")


@dataclasses.dataclass(frozen=True)
class TransitionState:
    """State of the activation parameter Ω (1: M_Free^des, 0: M_Stiff^des), eqs. 6.16–6.18.

    Attributes:
        stiff: the target selected by the hysteresis.
        omega_start: Ω when the current transition began.
        t0, tf: start and end of the current transition [s] (tf <= t0: none running).
    """

    stiff: bool = False
    omega_start: float = 1.0
    t0: float = 0.0
    tf: float = 0.0

    def omega(self, t: float) -> float:
        """Ω(t) = Ω_target + (Ω_start − Ω_target) · ½(1 + cos(π (t − t0)/(tf − t0))) (eqs. 6.17, 6.18)."""
        target = 0.0 if self.stiff else 1.0
        if t >= self.tf or self.tf <= self.t0:
            return target
        s = max(0.0, (t - self.t0) / (self.tf - self.t0))
        return target + (self.omega_start - target) * 0.5 * (1.0 + math.cos(math.pi * s))


def transition_step(
    state: TransitionState, t: float, V: float, distance: float, config: TransitionConfig
) -> tuple[TransitionState, float]:
    """Advance the FME transition by one tick: hysteresis on V, then the cosine blend.

    A transition starts when the hysteresis target changes; it runs from the current Ω
    to the new target over ``t_f − t_0 = ρ ‖M_Free − M_Stiff‖_F |Ω_target − Ω|`` (eq. 6.19
    for a full transition). A transition reversed midway starts from the current Ω, so
    Ω is continuous in t and ``|dΩ/dt| <= π/(2 ρ ‖M_Free − M_Stiff‖_F)``.

    Args:
        state: current state.
        t: time [s].
        V: ASO volume in [0, 1].
        distance: ‖M_Free^des − M_Stiff^des‖_F.
        config: thresholds and ρ.

    Returns:
        (new state, Ω(t)); the desired FME is Ω M_Free + (1 − Ω) M_Stiff (eq. 6.16).
    """
    stiff = hysteresis(state.stiff, V, config.eps1, config.eps2)
    if stiff != state.stiff:
        om = state.omega(t)
        target = 0.0 if stiff else 1.0
        duration = config.rho * distance * abs(target - om)
        state = TransitionState(stiff, om, t, t + duration)
    return state, state.omega(t)


# --------------------------------------------------------------------- allocation
@dataclasses.dataclass(frozen=True)
class Allocation:
    """A joint-torque allocation within the torque box.

    Attributes:
        tau: (n,) joint torques [N m], within the limits.
        alpha: force scaling α ∈ [0, 1] of the rendered force (eq. 7.9).
        saturated: (n,) bool, the selection matrix 𝒮 of ASCM (joints held at a limit).
        tau_null: (n,) null-space part N τ_N [N m].
        method: "none" | "scaling" | "ascm" | "lp".
        clipped: whether a last-resort clip to the box was needed (b itself infeasible).
    """

    tau: np.ndarray
    alpha: float
    saturated: np.ndarray
    tau_null: np.ndarray
    method: str
    clipped: bool = False


def allocate_none(a, b, lo, hi) -> Allocation:
    """No compensation: clip τ = a + b to the box (distorts the force direction, Fig. 7.1a)."""
    tau = a + b
    out = np.clip(tau, lo, hi)
    return Allocation(out, 1.0, (tau > hi) | (tau < lo), np.zeros_like(a), "none")


def allocate_scaling(a, b, lo, hi) -> Allocation:
    """Simple scaling: the largest α <= 1 with lo <= α a + b <= hi (Fig. 7.1b, direction preserved)."""
    alpha = scaling_alpha(a, b, lo, hi)
    n = a.size
    if alpha is None:  # b alone is infeasible
        tau = np.clip(b, lo, hi)
        return Allocation(tau, 0.0, np.zeros(n, bool), np.zeros(n), "scaling", clipped=True)
    tau = np.clip(alpha * a + b, lo, hi)
    sat = (np.abs(tau - hi) <= 1e-12 * (1 + np.abs(hi))) | (np.abs(tau - lo) <= 1e-12 * (1 + np.abs(lo)))
    return Allocation(tau, alpha, sat if alpha < 1 else np.zeros(n, bool), np.zeros(n), "scaling")


def _fixed_solution(a, b, Z, S, ts, alpha):
    """τ = α a + b + Z y with y the least-norm solution putting joints S at ts. Returns (τ, Z y)."""
    base = alpha * a + b
    if not S.any():
        return base, np.zeros_like(a)
    y = np.linalg.lstsq(Z[S], ts[S] - base[S], rcond=None)[0]
    d = Z @ y
    return base + d, d


def ascm(a, b, Z, lo, hi, *, max_iter: int | None = None) -> Allocation:
    """Actuator Saturation Compensation Method (thesis Algorithm 1, eqs. 7.5–7.9).

    Starting from τ = a + b, repeatedly selects the most overloaded joint k (largest excess
    relative to its limit), holds it at that limit (𝒮_kk = 1, τ_s,k = T_max/min,k) and moves
    the excess to the unsaturated joints through the least-norm null-space torque
    ``Z y`` with ``(a + b + Z y)_𝒮 = τ_s`` (eq. 7.8). When holding one more joint leaves
    no null-space torque that can do so (``Z_𝒮`` rank-deficient; with the kinematic
    projector this is the thesis's test ``rank(J(I − 𝒮)) < m``), the rendered force is
    scaled by the largest α with all joints in the box, the held joints staying at their
    limits (eq. 7.9, Algorithm 1 lines 16–24; α is taken over every joint, not only joint k,
    so the result never leaves the box). If even that is infeasible it falls back to
    simple scaling.

    Args:
        a: (n,) torque of the rendered force, Jᵀ F_render [N m] (scaled by α).
        b: (n,) unscaled torque [N m].
        Z: (n, n−m) orthonormal basis of the null-space torques (`null_basis`).
        lo, hi: (n,) torque limits [N m].

    Returns:
        The allocation; ``J#ᵀ τ = J#ᵀ(α a + b)``.
    """
    n, r = Z.shape
    S = np.zeros(n, bool)
    ts = np.zeros(n)
    span = hi - lo
    for _ in range(max_iter or n + 1):
        tau, d = _fixed_solution(a, b, Z, S, ts, 1.0)
        over = np.maximum(tau - hi, lo - tau) / span
        over[S] = -np.inf
        k = int(np.argmax(over))
        if over[k] <= 1e-12:
            return Allocation(tau, 1.0, S, d, "ascm")
        S2 = S.copy()
        S2[k] = True
        ts2 = ts.copy()
        ts2[k] = hi[k] if tau[k] > hi[k] else lo[k]
        cnt = int(S2.sum())
        if cnt > r or np.linalg.matrix_rank(Z[S2], tol=1e-9) < cnt:
            break
        S, ts = S2, ts2
    # infeasible: scale the rendered force with the joints of S held at their limits
    if S.any():
        P = np.linalg.pinv(Z[S])
        p = a - Z @ (P @ a[S])
        c = b + Z @ (P @ (ts[S] - b[S]))
        free = ~S
        alpha = scaling_alpha(p[free], c[free], lo[free], hi[free])
        if alpha is not None:
            tau = np.clip(alpha * p + c, lo, hi)
            return Allocation(tau, alpha, S, tau - alpha * a - b, "ascm")
    res = allocate_scaling(a, b, lo, hi)
    return dataclasses.replace(res, method="ascm")


def allocate_lp(a, b, Z, lo, hi) -> Allocation:
    """Optimal allocation: the largest α <= 1 over every null-space torque, by linear programming.

    Solves ``max α`` s.t. ``lo <= α a + b + Z y <= hi``, ``0 <= α <= 1`` (HiGHS). For
    ``b = 0`` and a request at or above the capability, ``α |F|`` equals the optimum of
    `rhi.metrics.max_force`. Falls back to simple scaling if the LP fails.
    """
    n, r = Z.shape
    tau0 = a + b
    if np.all(tau0 <= hi) and np.all(tau0 >= lo):
        return Allocation(tau0, 1.0, np.zeros(n, bool), np.zeros(n), "lp")
    A = np.concatenate([a[:, None], Z], axis=1)
    c = np.zeros(r + 1)
    c[0] = -1.0
    res = linprog(
        c,
        A_ub=np.concatenate([A, -A]),
        b_ub=np.concatenate([hi - b, b - lo]),
        bounds=[(0.0, 1.0)] + [(None, None)] * r,
        method="highs",
    )
    if res.status != 0:
        return dataclasses.replace(allocate_scaling(a, b, lo, hi), method="lp")
    alpha = float(res.x[0])
    d = Z @ res.x[1:]
    tau = np.clip(alpha * a + b + d, lo, hi)
    sat = (np.abs(tau - hi) <= 1e-9) | (np.abs(tau - lo) <= 1e-9)
    return Allocation(tau, alpha, sat, d, "lp")


def tertiary(tau, saturated, Z, tau_to, lo, hi, N: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Tertiary-objective torque in the null space of the primary task and of ASCM (eqs. 7.16, Algorithm 2).

    The objective torque is projected by N (eq. 3.20; orthogonally onto range(Z) if N is
    None), then onto the torques that leave the held joints 𝒮 unchanged, and scaled by
    the largest β <= 1 that keeps every joint in the box (Algorithm 2). β = 0 when no
    redundancy is left after ASCM.

    Args:
        tau: (n,) torque from the allocation [N m], within the box.
        saturated: (n,) bool, ASCM's 𝒮.
        Z: (n, n−m) null-space basis.
        tau_to: (n,) tertiary torque τ_to, e.g. −Λ ∂ν/∂q − k_D q̇ [N m].
        lo, hi: (n,) torque limits [N m].
        N: (n, n) torque null-space projector I − JᵀJ#ᵀ, or None.

    Returns:
        (β δ (n,) [N m] to add to tau, β).
    """
    c = Z.T @ (tau_to if N is None else N @ tau_to)
    if saturated.any():
        ZS = Z[saturated]
        c = c - np.linalg.pinv(ZS) @ (ZS @ c)
    delta = Z @ c
    if not np.any(np.abs(delta) > 1e-15):
        return np.zeros_like(tau), 0.0
    beta = scaling_alpha(delta, np.clip(tau, lo, hi), lo, hi)
    beta = 0.0 if beta is None else beta
    return beta * delta, beta


def force_capability(
    J, u, torque_min, torque_max, *, method: str = "ascm", M=None, samples: int = 41
) -> float:
    """Largest force along u a static allocation method renders, over a ramp of requests [N].

    Requests ``f u`` for f from the simple-scaling capability up to 1.5× the LP optimum
    (`rhi.metrics.max_force`), and returns the peak output ``α f`` — what a quasi-static
    force ramp, as in Fig. 7.1, shows as the peak force. "scaling" and "lp" are exact
    (closed form / LP); "ascm" is Algorithm 1.

    Args:
        J: (m, n) Jacobian [m/rad].
        u: (m,) direction; normalised internally.
        torque_min, torque_max: (n,) limits [N m].
        method: "scaling" | "ascm" | "lp".
        M: (n, n) inertia for the dynamic projector, or None (kinematic).
        samples: requests in the ramp (for "ascm").
    """
    from rhi.metrics import max_force, max_force_scaling

    lo, hi = check_torque_limits(torque_min, torque_max, np.shape(J)[-1])
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    f_s = float(max_force_scaling(J, u, torque_min=lo, torque_max=hi))
    if method == "scaling":
        return f_s
    kw = {"projector": "kinematic"} if M is None else {"projector": "dynamic", "M": M}
    f_lp = float(max_force(J, u, torque_min=lo, torque_max=hi, **kw))
    if method == "lp":
        return f_lp
    if method != "ascm":
        raise InvalidInput(f"method: expected 'scaling', 'ascm' or 'lp', got {method!r}")
    Z = null_basis(np.asarray(J, dtype=float), M)
    t = np.asarray(J, dtype=float).T @ u
    b = np.zeros_like(t)
    best = f_s
    for f in np.concatenate([np.linspace(f_s, 1.5 * f_lp, samples), [f_lp]]):
        al = ascm(f * t, b, Z, lo, hi)
        best = max(best, al.alpha * f)
    return min(best, f_lp) if best <= f_lp * (1 + 1e-9) else best
