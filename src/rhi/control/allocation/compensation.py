"""ASCM, the Actuator Saturation Compensation Method (``saturation="ascm"``, thesis Algorithm 1, eqs. 7.5–7.9).

`ascm` on an orthonormal basis Z of the null-space torques is the reference; `ascm_projector`
computes the same allocation from the projector P = Z Zᵀ with the compiled
`rhi.control._compiled.allocation.ascm`, the branch ``kernels.ASCM`` of the controller's tick.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rhi.control import _compiled as kernels
from rhi.control.allocation.base import Allocation, Allocator, register
from rhi.control.allocation.scaling import allocate_scaling
from rhi.control.saturation import RANK_TOL, basis_from_projector, check_allocation, scaling_alpha
from rhi.errors import InvalidInput


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
    a, b, Z, lo, hi = check_allocation(a, b, Z, torque_min=torque_min, torque_max=torque_max, basis=True)
    if max_iter is not None and (isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1):
        raise InvalidInput(f"max_iter: expected an integer >= 1 or None, got {max_iter!r:.60}")
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
    ``P[:, 𝒮] P[𝒮, 𝒮]⁻¹ r`` (the compiled `rhi.control._compiled.ascm`): for a controller
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


ASCM = register(Allocator("ascm", ascm, kernel=kernels.ASCM))

__all__ = ["ASCM", "ascm", "ascm_projector"]
