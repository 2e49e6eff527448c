"""Actuator saturation: torque allocation within the box (none, scaling, ASCM, LP) and the tertiary scaling β.

Pure functions on arrays plus small dataclasses with explicit state (thesis §7.3–7.4; the ASO
and the FME transition of §6.3.2 are `rhi.control.transition`).

Torque allocation is written in one form shared by every method:

    τ(α, y) = α a + b + Z y

with ``a = Jᵀ F_render`` the scalable (rendered-force) torque, ``b`` the torque that is not
scaled (damping, gravity), and ``Z`` (n, n−m) an orthonormal basis of the range of the
torque null-space projector ``N = I − Jᵀ J#ᵀ`` (eq. 7.5), i.e. of the torques with
``J#ᵀ τ = 0``. ``N τ_N = Z y`` for ``τ_N = Z y``, so every allocation below produces the
task-space force ``J#ᵀ τ = J#ᵀ(α a + b)`` exactly.

The ``*_projector`` variants (`ascm_projector`, `tertiary_projector`) compute the same
allocation from the orthogonal projector ``P = Z Zᵀ`` onto those torques, which a
controller gets from J and M⁻¹ by two small products instead of an SVD: the least-norm
null-space torque that puts the joints 𝒮 at ``r`` is ``P[:, 𝒮] P[𝒮, 𝒮]⁻¹ r``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np
from scipy.optimize import linprog

from rhi._validate import as_array
from rhi.control import kernels
from rhi.device import eye
from rhi.errors import InfeasibleLimits, InvalidInput, Singular

_TOL = 1e-12
# Z_𝒮 counts as rank-deficient (ASCM cannot hold the joints 𝒮) when its smallest singular value is
# below this; Z is orthonormal, so the threshold is relative.
RANK_TOL = 1e-9


# ------------------------------------------------------------------ limits, bases
def check_torque_limits(*, torque_min, torque_max, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
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
    """Orthonormal basis Z (n, n−m) of range(I − Jᵀ J#ᵀ) = null(J M⁻¹) (pseudoinverse: null(J)).

    Args:
        J: (m, n) Jacobian, full row rank.
        M: (n, n) joint-space inertia [kg m²] for the dynamically consistent J#, or None.
    """
    A = J if M is None else np.linalg.solve(M, J.T).T  # J M⁻¹ (M symmetric)
    m = J.shape[0]
    _, _, Vt = np.linalg.svd(A)
    return Vt[m:].T.copy()


def null_projector(J: np.ndarray, M: np.ndarray | None = None, *, JMinv: np.ndarray | None = None) -> np.ndarray:
    """Orthogonal projector P = Z Zᵀ (n, n) onto range(I − Jᵀ J#ᵀ) = null(J M⁻¹) (pseudoinverse: null(J)).

    ``P = I − Q Qᵀ`` with Q an orthonormal basis of the rows of ``A = J M⁻¹`` (or J), by
    Gram–Schmidt with re-orthogonalisation (accurate to rounding whatever cond(A)): the
    subspace of `null_basis` without an SVD.

    Args:
        J: (m, n) Jacobian, full row rank.
        M: (n, n) joint-space inertia [kg m²] for the dynamically consistent J#, or None.
        JMinv: (m, n) J M⁻¹ if already known (then M is not used).

    Raises:
        Singular: J does not have full row rank.
    """
    A = JMinv if JMinv is not None else (J if M is None else np.linalg.solve(M, J.T).T)
    Q: list[np.ndarray] = []
    for i in range(A.shape[0]):
        v = A[i]
        scale = math.sqrt(v.dot(v))
        for _ in range(2):  # CGS2: twice is enough
            for qv in Q:
                v = v - qv.dot(v) * qv
        nv = math.sqrt(v.dot(v))
        if not nv > 1e-12 * scale:
            raise Singular(f"J: rank-deficient Jacobian (row {i} depends on the others)")
        Q.append(v / nv)
    Qm = np.array(Q)
    return eye(A.shape[1]) - Qm.T.dot(Qm)


def basis_from_projector(P: np.ndarray, rank: int | None = None) -> np.ndarray:
    """An orthonormal basis Z (n, r) of the range of an orthogonal projector P (eigenvectors of eigenvalue 1)."""
    w, V = np.linalg.eigh(0.5 * (P + P.T))
    r = int(round(float(np.trace(P)))) if rank is None else rank
    return V[:, w.size - r:]


def scaling_alpha(p, c, *, lo, hi) -> float | None:
    """Largest α in [0, 1] with ``lo <= α p + c <= hi``; None when no α in [0, 1] is feasible.

    Entries with |p| negligible only need c itself in the box.

    Args:
        p: (k,) direction of the scaled part.
        c: (k,) constant part.
        lo: (k,) lower bounds.
        hi: (k,) upper bounds.
    """
    a_lo, a_hi = 0.0, 1.0
    for pi, ci, l, h in zip(*(np.asarray(v, dtype=float).tolist() for v in (p, c, lo, hi))):
        api = abs(pi)
        if api <= 1e-12 * (1.0 + api + abs(ci)):
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


def allocate_none(a, b, *, torque_min, torque_max) -> Allocation:
    """No compensation: clip τ = a + b to the torque box [N m] (distorts the force direction, Fig. 7.1a)."""
    lo, hi = torque_min, torque_max
    tau = a + b
    out = np.clip(tau, lo, hi)
    return Allocation(out, 1.0, (tau > hi) | (tau < lo), np.zeros_like(a), "none")


def allocate_scaling(a, b, *, torque_min, torque_max) -> Allocation:
    """Simple scaling: the largest α <= 1 with torque_min <= α a + b <= torque_max [N m] (Fig. 7.1b, direction preserved)."""
    lo, hi = torque_min, torque_max
    alpha = scaling_alpha(a, b, lo=lo, hi=hi)
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


def ascm(a, b, Z, *, torque_min, torque_max, max_iter: int | None = None) -> Allocation:
    """Actuator Saturation Compensation Method (thesis Algorithm 1, eqs. 7.5–7.9).

    Starting from τ = a + b, repeatedly selects the most overloaded joint k (largest excess
    relative to its limit), holds it at that limit (𝒮_kk = 1, τ_s,k = T_max/min,k) and moves
    the excess to the unsaturated joints through the least-norm null-space torque
    ``Z y`` with ``(a + b + Z y)_𝒮 = τ_s`` (eq. 7.8). When holding one more joint leaves
    no null-space torque that can do so (``Z_𝒮`` rank-deficient: smallest singular value
    below `RANK_TOL`; with the pseudoinverse
    projector this is the thesis's test ``rank(J(I − 𝒮)) < m``), the rendered force is
    scaled by the largest α with all joints in the box, the held joints staying at their
    limits (eq. 7.9, Algorithm 1 lines 16–24; α is taken over every joint, not only joint k,
    so the result never leaves the box). If even that is infeasible it falls back to
    simple scaling.

    Args:
        a: (n,) torque of the rendered force, Jᵀ F_render [N m] (scaled by α).
        b: (n,) unscaled torque [N m].
        Z: (n, n−m) orthonormal basis of the null-space torques (`null_basis`).
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        max_iter: most joints held before giving up (default n + 1: every joint once).

    Returns:
        The allocation; ``J#ᵀ τ = J#ᵀ(α a + b)``.
    """
    lo, hi = torque_min, torque_max
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
        if cnt > r or np.linalg.matrix_rank(Z[S2], tol=RANK_TOL) < cnt:
            break
        S, ts = S2, ts2
    # infeasible: scale the rendered force with the joints of S held at their limits
    if S.any():
        P = np.linalg.pinv(Z[S])
        p = a - Z @ (P @ a[S])
        c = b + Z @ (P @ (ts[S] - b[S]))
        free = ~S
        alpha = scaling_alpha(p[free], c[free], lo=lo[free], hi=hi[free])
        if alpha is not None:
            tau = np.clip(alpha * p + c, lo, hi)
            return Allocation(tau, alpha, S, tau - alpha * a - b, "ascm")
    res = allocate_scaling(a, b, torque_min=lo, torque_max=hi)
    return dataclasses.replace(res, method="ascm")


def ascm_projector(a, b, P, *, torque_min, torque_max, rank: int | None = None) -> Allocation:
    """ASCM (thesis Algorithm 1) from the null-space projector P = Z Zᵀ: the allocation of `ascm`.

    Same iteration as `ascm` (most overloaded joint first, least-norm null-space torque,
    α-scaling when ``Z_𝒮`` would lose rank), with the least-norm torque written
    ``P[:, 𝒮] P[𝒮, 𝒮]⁻¹ r`` (the compiled `rhi.control.kernels.ascm`): for a controller
    tick, where P comes from `null_projector` instead of an SVD. Because P[𝒮, 𝒮] squares
    the condition number of Z_𝒮, a held set with σ_min(Z_𝒮) < 0.01 is handed to `ascm`
    with a basis of P (the same allocation, computed accurately).

    Args:
        a: (n,) torque of the rendered force, Jᵀ F_render [N m] (scaled by α).
        b: (n,) unscaled torque [N m].
        P: (n, n) orthogonal projector onto the null-space torques (`null_projector`).
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        rank: n − m, the rank of P (default: its rounded trace).

    Returns:
        The allocation; equal to ``ascm(a, b, Z, torque_min=..., torque_max=...)`` for any orthonormal Z with Z Zᵀ = P.
    """
    r = int(round(float(np.trace(P)))) if rank is None else rank
    a, b, P, lo, hi = (np.ascontiguousarray(v, dtype=float) for v in (a, b, P, torque_min, torque_max))
    sat = np.zeros(a.shape[0], bool)
    tau, alpha, clipped, ok = kernels.ascm(a, b, P, lo, hi, r, sat)
    if not ok:
        return ascm(a, b, basis_from_projector(P, r), torque_min=lo, torque_max=hi)
    if clipped:
        return dataclasses.replace(allocate_scaling(a, b, torque_min=lo, torque_max=hi), method="ascm")
    return Allocation(tau, alpha, sat, tau - alpha * a - b, "ascm")


def allocate_lp(a, b, Z, *, torque_min, torque_max) -> Allocation:
    """Optimal allocation: the largest α <= 1 over every null-space torque, by linear programming.

    Solves ``max α`` s.t. ``torque_min <= α a + b + Z y <= torque_max``, ``0 <= α <= 1`` (HiGHS). For
    ``b = 0`` and a request at or above the capability, ``α |F|`` equals the optimum of
    `rhi.metrics.max_force`. Falls back to simple scaling if the LP fails.
    """
    lo, hi = torque_min, torque_max
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
        return dataclasses.replace(allocate_scaling(a, b, torque_min=lo, torque_max=hi), method="lp")
    alpha = float(res.x[0])
    d = Z @ res.x[1:]
    tau = np.clip(alpha * a + b + d, lo, hi)
    sat = (np.abs(tau - hi) <= 1e-9) | (np.abs(tau - lo) <= 1e-9)
    return Allocation(tau, alpha, sat, d, "lp")


def tertiary(tau, saturated, Z, tau_to, *, torque_min, torque_max, N: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Tertiary-objective torque in the null space of the primary task and of ASCM (eqs. 7.16, Algorithm 2).

    The objective torque is projected by N (eq. 3.20; orthogonally onto range(Z) if N is
    None), then onto the torques that leave the held joints 𝒮 unchanged, and scaled by
    the largest β <= 1 that keeps every joint in the box (Algorithm 2). β = 0 when no
    redundancy is left after ASCM (fewer than m + 1 joints free), or when the projected
    torque is negligible (every entry below 1e-12 (1 + max|τ_to|) N m).

    Args:
        tau: (n,) torque from the allocation [N m], within the box.
        saturated: (n,) bool, ASCM's 𝒮.
        Z: (n, n−m) null-space basis.
        tau_to: (n,) tertiary torque τ_to, e.g. −Λ ∂ν/∂q − k_D q̇ [N m].
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        N: (n, n) torque null-space projector I − JᵀJ#ᵀ, or None.

    Returns:
        (β δ (n,) [N m] to add to tau, β).
    """
    n, r = Z.shape
    if n - int(np.count_nonzero(saturated)) <= n - r:  # no redundancy left (Algorithm 2, line 2)
        return np.zeros_like(tau), 0.0
    c = Z.T @ (tau_to if N is None else N @ tau_to)
    if saturated.any():
        ZS = Z[saturated]
        c = c - np.linalg.pinv(ZS) @ (ZS @ c)
    delta = Z @ c
    if not np.any(np.abs(delta) > negligible(tau_to)):
        return np.zeros_like(tau), 0.0
    lo, hi = torque_min, torque_max
    beta = scaling_alpha(delta, np.clip(tau, lo, hi), lo=lo, hi=hi)
    beta = 0.0 if beta is None else beta
    return beta * delta, beta


def negligible(tau) -> float:
    """Null-space torques below this [N m] are rounding noise of the projections (tau: (n,) [N m])."""
    return 1e-12 * (1.0 + float(np.max(np.abs(tau))))


def tertiary_projector(
    tau, saturated, P, tau_to, *, torque_min, torque_max, N: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """`tertiary` from the projector P = Z Zᵀ instead of a basis (same result).

    Args:
        tau: (n,) torque from the allocation [N m], within the box.
        saturated: (n,) bool, ASCM's 𝒮.
        P: (n, n) orthogonal projector onto the null-space torques (`null_projector`).
        tau_to: (n,) tertiary torque τ_to [N m].
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        N: (n, n) torque null-space projector I − JᵀJ#ᵀ, or None (then P).

    Returns:
        (β δ (n,) [N m] to add to tau, β).
    """
    r = int(round(float(np.trace(P))))
    tau, P, tau_to, lo, hi = (np.ascontiguousarray(v, dtype=float) for v in (tau, P, tau_to, torque_min, torque_max))
    saturated = np.ascontiguousarray(saturated, dtype=bool)
    Ntau = (P if N is None else np.asarray(N, dtype=float)).dot(tau_to)
    delta, beta, ok = kernels.tertiary(tau, saturated, P, tau_to, Ntau, lo, hi, r)
    if not ok:
        return tertiary(tau, saturated, basis_from_projector(P, r), tau_to, torque_min=lo, torque_max=hi, N=N)
    return delta, beta


def force_capability(
    J, u, *, torque_min, torque_max, method: str = "ascm", projector: Literal["dynamic", "pseudoinverse"] = "dynamic",
    M=None, samples: int = 41,
) -> float:
    """Largest force along u a static allocation method renders, over a ramp of requests [N].

    Requests ``f u`` for f from the simple-scaling capability up to 1.5× the LP optimum
    (`rhi.metrics.max_force`), and returns the peak output ``α f`` — what a quasi-static
    force ramp, as in Fig. 7.1, shows as the peak force. "scaling" and "lp" are exact
    (closed form / LP); "ascm" is Algorithm 1.

    Args:
        J: (m, n) Jacobian [m/rad].
        u: (m,) direction; normalised internally.
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        method: "scaling" | "ascm" | "lp".
        projector: "dynamic" (J#, eq. 7.5; needs M) or "pseudoinverse" (J⁺).
        M: (n, n) inertia [kg m²], required for (and only used by) ``projector="dynamic"``.
        samples: requests in the ramp (for "ascm").

    Raises:
        InvalidInput: an unknown method or projector, or M missing/superfluous.
    """
    from rhi.metrics import max_force, max_force_scaling

    if projector not in ("dynamic", "pseudoinverse"):
        raise InvalidInput(f"projector: expected 'dynamic' or 'pseudoinverse', got {projector!r}")
    lo, hi = check_torque_limits(torque_min=torque_min, torque_max=torque_max, n=np.shape(J)[-1])
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    f_s = float(max_force_scaling(J, u, torque_min=lo, torque_max=hi))
    if method == "scaling":
        return f_s
    f_lp = float(max_force(J, u, torque_min=lo, torque_max=hi, projector=projector, M=M))
    if method == "lp":
        return f_lp
    if method != "ascm":
        raise InvalidInput(f"method: expected 'scaling', 'ascm' or 'lp', got {method!r}")
    Z = null_basis(np.asarray(J, dtype=float), M)
    t = np.asarray(J, dtype=float).T @ u
    b = np.zeros_like(t)
    best = f_s
    for f in np.concatenate([np.linspace(f_s, 1.5 * f_lp, samples), [f_lp]]):
        al = ascm(f * t, b, Z, torque_min=lo, torque_max=hi)
        best = max(best, al.alpha * f)
    return min(best, f_lp) if best <= f_lp * (1 + 1e-9) else best
