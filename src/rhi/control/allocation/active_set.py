"""The active-set allocation (``saturation="active_set"``) on ASCM's LP: ASCM that can release or flip the joints it holds.

ASCM (thesis Algorithm 1, `rhi.control.allocation.ascm.ascm`) holds the most overloaded joint at
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

from rhi.control import _compiled as kernels
from rhi.control.allocation.base import Allocation, Allocator, register
from rhi.control.allocation.lp import allocate_lp
from rhi.control.saturation import check_allocation


def allocate_active_set(a, b, Z, *, torque_min, torque_max, start: Allocation | None = None, max_iter: int = 50) -> Allocation:
    """The LP-optimal allocation of ASCM's problem by a primal active-set method warm-started at ASCM.

    Same problem and result as `rhi.control.allocation.lp.allocate_lp`: the largest α <= 1 with
    ``torque_min <= α a + b + Z y <= torque_max`` (eq. 7.9 with every null-space torque allowed). Falls back to
    `allocate_lp` if ASCM's start is not feasible (b itself outside the box) or the
    iteration does not settle within `max_iter` steps (degenerate cycling). The iteration is
    the compiled `rhi.control._compiled.active_set`.

    Args:
        a: (n,) torque of the rendered force, Jᵀ F_render [N m] (scaled by α).
        b: (n,) unscaled torque [N m].
        Z: (n, r) orthonormal basis of the null-space torques (`null_basis`, either projector).
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        start: a feasible allocation to start from (default: ASCM in projector form on P = Z Zᵀ, or
            simple scaling where that form cannot decide; `rhi.control._compiled.allocation.active_set_start`).
        max_iter: iteration limit.

    Returns:
        Allocation with method "active_set"; ``saturated`` marks the joints at a limit, and
        ``J#ᵀ τ = J#ᵀ(α a + b)`` (or J⁺ᵀ with the pseudoinverse basis).
    """
    a, b, Z, lo, hi = (np.ascontiguousarray(v) for v in check_allocation(a, b, Z, torque_min=torque_min,
                                                                          torque_max=torque_max, basis=True))
    n, r = Z.shape
    tau0 = a + b
    if np.all(tau0 <= hi) and np.all(tau0 >= lo):
        return Allocation(tau0, 1.0, np.zeros(n, bool), np.zeros(n), "active_set")
    if start is None:
        sat = np.zeros(n, bool)
        tau, alpha, clipped = kernels.active_set_start(a, b, Z @ Z.T, lo, hi, r, sat)
        start = Allocation(tau, alpha, sat, tau - alpha * a - b, "ascm", clipped)
    if start.clipped or not a.any():
        return _lp(a, b, Z, lo, hi)
    ok, alpha, y = kernels.active_set(a, b, Z, lo, hi, float(start.alpha), np.ascontiguousarray(start.tau, dtype=float),
                                      np.ascontiguousarray(start.saturated, dtype=bool), max_iter)
    if not ok:
        return _lp(a, b, Z, lo, hi)
    sat = np.zeros(n, bool)
    tau, alpha = kernels.active_set_result(alpha, y, a, b, Z, lo, hi, sat)
    return Allocation(tau, alpha, sat, Z @ y, "active_set")


def _lp(a, b, Z, lo, hi) -> Allocation:
    al = allocate_lp(a, b, Z, torque_min=lo, torque_max=hi)
    return Allocation(al.tau, al.alpha, al.saturated, al.tau_null, "active_set", al.clipped)


ACTIVE_SET = register(Allocator("active_set", allocate_active_set, kernel=kernels.ACTIVE_SET))

__all__ = ["ACTIVE_SET", "allocate_active_set"]
