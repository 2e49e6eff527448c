"""The LP optimum (``saturation="lp"``): the largest α over every null-space torque, by HiGHS.

`allocate_lp` (HiGHS) is this strategy's reference: ``implementation="reference"``, the static capability
(`force_capability`) and the ticks the compiled tick hands back. The compiled tick reaches the same optimum α*
by the active-set method warm-started at ASCM (its ACTIVE_SET branch, `rhi.control.allocation.active_set`).
Where the optimal face is more than a point (α* = 1 reached with room to spare, or a degenerate vertex), the two
return different null-space torques of it; both keep α*, the handle force (J#ᵀ τ = J#ᵀ(α* a + b)) and the box,
and the tests compare those, not the vertex (HiGHS's choice of vertex is its own).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import linprog

from rhi.control import _compiled as kernels
from rhi.control.allocation.base import Allocation, Allocator, register
from rhi.control.allocation.scaling import allocate_scaling
from rhi.control.saturation import check_allocation


def allocate_lp(a, b, Z, *, torque_min, torque_max) -> Allocation:
    """Optimal allocation: the largest α <= 1 over every null-space torque, by linear programming.

    Solves ``max α`` s.t. ``torque_min <= α a + b + Z y <= torque_max``, ``0 <= α <= 1`` (HiGHS). For
    ``b = 0`` and a request at or above the capability, ``α |F|`` equals the optimum of
    `rhi.metrics.max_force`. Falls back to simple scaling if the LP fails.
    """
    a, b, Z, lo, hi = check_allocation(a, b, Z, torque_min=torque_min, torque_max=torque_max, basis=True)
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


LP = register(Allocator("lp", allocate_lp, kernel=kernels.ACTIVE_SET))

__all__ = ["LP", "allocate_lp"]
