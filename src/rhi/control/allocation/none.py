"""No compensation (``saturation="none"``): clip the torque to the box, distorting the force direction (Fig. 7.1a)."""

from __future__ import annotations

import numpy as np

from rhi.control import _compiled as kernels
from rhi.control.allocation.base import Allocation, Allocator, register
from rhi.control.saturation import check_allocation


def allocate_none(a, b, *, torque_min, torque_max) -> Allocation:
    """No compensation: clip τ = a + b to the torque box [N m] (distorts the force direction, Fig. 7.1a)."""
    a, b, _, lo, hi = check_allocation(a, b, torque_min=torque_min, torque_max=torque_max)
    tau = a + b
    out = np.clip(tau, lo, hi)
    return Allocation(out, 1.0, (tau > hi) | (tau < lo), np.zeros_like(a), "none")


def _on_basis(a, b, Z, *, torque_min, torque_max) -> Allocation:
    return allocate_none(a, b, torque_min=torque_min, torque_max=torque_max)


NONE = register(Allocator("none", _on_basis, kernel=kernels.NONE))

__all__ = ["NONE", "allocate_none"]
