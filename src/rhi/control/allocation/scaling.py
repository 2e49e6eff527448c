"""Simple scaling (``saturation="scaling"``): the largest α <= 1 that fits the box, direction preserved (Fig. 7.1b).

Chapter 6's allocation: with it the controller keeps Algorithm 2 as it is (``safe=False``: the
safety torque is scaled with the objectives, whose FME term and limit barrier balance there).
"""

from __future__ import annotations

import numpy as np

from rhi.control import _compiled as kernels
from rhi.control.allocation.base import Allocation, Allocator, register
from rhi.control.saturation import check_allocation, scaling_alpha


def allocate_scaling(a, b, *, torque_min, torque_max) -> Allocation:
    """Simple scaling: the largest α <= 1 with torque_min <= α a + b <= torque_max [N m] (Fig. 7.1b, direction preserved)."""
    a, b, _, lo, hi = check_allocation(a, b, torque_min=torque_min, torque_max=torque_max)
    alpha = scaling_alpha(a, b, lo=lo, hi=hi)
    n = a.size
    if alpha is None:  # b alone is infeasible
        tau = np.clip(b, lo, hi)
        return Allocation(tau, 0.0, np.zeros(n, bool), np.zeros(n), "scaling", clipped=True)
    tau = np.clip(alpha * a + b, lo, hi)
    sat = (np.abs(tau - hi) <= 1e-12 * (1 + np.abs(hi))) | (np.abs(tau - lo) <= 1e-12 * (1 + np.abs(lo)))
    return Allocation(tau, alpha, sat if alpha < 1 else np.zeros(n, bool), np.zeros(n), "scaling")


def _on_basis(a, b, Z, *, torque_min, torque_max) -> Allocation:
    return allocate_scaling(a, b, torque_min=torque_min, torque_max=torque_max)


SCALING = register(Allocator("scaling", _on_basis, safe=False, kernel=kernels.SCALING))

__all__ = ["SCALING", "allocate_scaling"]
