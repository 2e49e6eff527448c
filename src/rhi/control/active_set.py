"""An active-set allocation on ASCM's linear program: ASCM that can release or flip the joints it holds.

ASCM (thesis Algorithm 1, `rhi.control.saturation.ascm`) holds the most overloaded joint at
its limit, then the next, and never lets a held joint go: a greedy path to a vertex of

    max α   s.t.   lo <= α a + b + Z y <= hi,   0 <= α <= 1,                     (LP)

that need not be the optimum (the optimum may put a joint at its *opposite* limit, or leave
it inside the box). `allocate_active_set` starts from ASCM's allocation (feasible, usually
optimal) and runs a primal active-set method on the (1 + r) variables x = (α, y): with the
working set W of active constraints, it moves along the projection of the objective onto
the null space of W until a constraint blocks (ratio test), and at a vertex it drops the
constraint of W with the most negative Lagrange multiplier (a held joint released; a joint
at one limit that the ratio test then stops at the other is flipped). It ends at a point
where every multiplier is >= 0: the optimum of (LP), the value `allocate_lp` (HiGHS) finds,
at a per-tick cost of a few small solves instead of an LP solver call.
"""

from __future__ import annotations

import numpy as np

from rhi.control.saturation import Allocation, allocate_lp, ascm


def allocate_active_set(a, b, Z, lo, hi, *, start: Allocation | None = None, max_iter: int = 50) -> Allocation:
    """The LP-optimal allocation of ASCM's problem by a primal active-set method warm-started at ASCM.

    Same problem and result as `rhi.control.saturation.allocate_lp`: the largest α <= 1 with
    ``lo <= α a + b + Z y <= hi`` (eq. 7.9 with every null-space torque allowed). Falls back to
    `allocate_lp` if ASCM's start is not feasible (b itself outside the box) or the
    iteration does not settle within `max_iter` steps (degenerate cycling).

    Args:
        a: (n,) torque of the rendered force, Jᵀ F_render [N m] (scaled by α).
        b: (n,) unscaled torque [N m].
        Z: (n, r) orthonormal basis of the null-space torques (`null_basis`, either projector).
        lo, hi: (n,) torque limits [N m].
        start: a feasible allocation to start from (default: `ascm(a, b, Z, lo, hi)`).
        max_iter: iteration limit.

    Returns:
        Allocation with method "active_set"; ``saturated`` marks the joints at a limit, and
        ``J#ᵀ τ = J#ᵀ(α a + b)`` (or J⁺ᵀ with the pseudoinverse basis).
    """
    n, r = Z.shape
    tau0 = a + b
    if np.all(tau0 <= hi) and np.all(tau0 >= lo):
        return Allocation(tau0, 1.0, np.zeros(n, bool), np.zeros(n), "active_set")
    al = ascm(a, b, Z, lo, hi) if start is None else start
    if al.clipped or not a.any():
        return _lp(a, b, Z, lo, hi)
    k = r + 1
    sa = float(np.sqrt(a.dot(a)))  # variables x = (α |a|, y): columns of one scale (Z is orthonormal)
    A = np.empty((n, k))
    A[:, 0] = a / sa
    A[:, 1:] = Z
    e0 = np.zeros(k)
    e0[0] = 1.0
    G = np.vstack([A, -A, e0, -e0])  # G x <= h
    h = np.concatenate([hi - b, b - lo, [sa, 0.0]])
    x = np.empty(k)
    x[0] = al.alpha * sa
    x[1:] = Z.T @ (al.tau - al.alpha * a - b)
    # working set: the joints ASCM holds (independent by its rank test), and α = 1 or 0 when at a bound
    held = np.flatnonzero(al.saturated).tolist()
    tau = al.tau
    W = [j if tau[j] >= 0.5 * (hi[j] + lo[j]) else n + j for j in held]
    if al.alpha >= 1.0 - 1e-12 and len(W) < k:
        W.append(2 * n)
    elif al.alpha <= 1e-12 and len(W) < k:
        W.append(2 * n + 1)
    gnorm = 1e-12 * np.sqrt(np.einsum("ij,ij->i", G, G))
    for _ in range(max_iter):
        GW = G[W]
        if len(W) < k:
            d = e0 - GW.T @ np.linalg.solve(GW @ GW.T, GW[:, 0]) if W else e0.copy()
            if float(d @ d) > 1e-20:
                Gd = G @ d
                mask = Gd > gnorm
                mask[W] = False
                if not mask.any():
                    return _lp(a, b, Z, lo, hi)  # unbounded cannot happen with α <= 1
                ratios = np.maximum(h - G @ x, 0.0)[mask] / Gd[mask]
                i = int(np.argmin(ratios))
                x = x + ratios[i] * d
                W = W + [int(np.flatnonzero(mask)[i])]
                continue
        lam = np.linalg.solve(GW @ GW.T, GW[:, 0])  # GWᵀ λ = e0 (GW has independent rows)
        i = int(np.argmin(lam))
        if lam[i] >= -1e-12:
            return _result(x[0] / sa, x[1:], a, b, Z, lo, hi)
        W = W[:i] + W[i + 1:]
    return _lp(a, b, Z, lo, hi)


def _result(alpha: float, y: np.ndarray, a, b, Z, lo, hi) -> Allocation:
    alpha = min(max(float(alpha), 0.0), 1.0)
    d = Z @ y
    tau = np.clip(alpha * a + b + d, lo, hi)
    tol = 1e-9 * (1.0 + np.abs(hi - lo))
    sat = (np.abs(tau - hi) <= tol) | (np.abs(tau - lo) <= tol)
    return Allocation(tau, alpha, sat, d, "active_set")


def _lp(a, b, Z, lo, hi) -> Allocation:
    al = allocate_lp(a, b, Z, lo, hi)
    return Allocation(al.tau, al.alpha, al.saturated, al.tau_null, "active_set", al.clipped)


__all__ = ["allocate_active_set"]
