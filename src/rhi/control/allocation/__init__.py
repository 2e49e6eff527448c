"""Torque allocation within the box: one module per strategy, selected by name (``ControllerConfig.saturation``).

Every strategy places ``τ(α, y) = α a + b + Z y`` in the torque box (thesis §7.3; the protocol,
the result type and the registry are `rhi.control.allocation.base`). The bundled strategies:
``"none"`` (clip), ``"scaling"`` (simple scaling), ``"ascm"`` (Algorithm 1) and ``"lp"`` (the LP
optimum; its solvers and the alias ``"active_set"``: `rhi.control.allocation.lp`). Importing a strategy
module registers it: `MODULES` is the registration.
"""

from typing import Literal

from rhi.control.allocation import compensation, lp, none, scaling
from rhi.control.allocation.base import (
    Allocation,
    AllocationMethod,
    Allocator,
    allocation_method,
    method_names,
    register,
)
from rhi.control.allocation.capability import force_capability, ramp_peak
from rhi.control.allocation.compensation import ascm, ascm_projector
from rhi.control.allocation.lp import LPOptimum, allocate_active_set, allocate_lp
from rhi.control.allocation.none import allocate_none
from rhi.control.allocation.scaling import allocate_scaling

#: The strategy modules, one per strategy (ASCM's is `compensation`); importing one registers its strategy.
MODULES = (none, scaling, compensation, lp)

#: The bundled strategies' names and the alias "active_set" (of "lp"), for type checkers and the run-configuration
#: schema (`method_names` also lists strategies registered elsewhere; tests/test_control.py checks the bundled ones agree).
Saturation = Literal["none", "scaling", "ascm", "lp", "active_set"]

__all__ = [
    "Allocation",
    "AllocationMethod",
    "Allocator",
    "LPOptimum",
    "MODULES",
    "Saturation",
    "allocate_active_set",
    "allocate_lp",
    "allocate_none",
    "allocate_scaling",
    "allocation_method",
    "ascm",
    "ascm_projector",
    "force_capability",
    "ramp_peak",
    "method_names",
    "register",
]
