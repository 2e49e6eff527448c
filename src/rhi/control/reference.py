"""The controller tick as the readable composition of the thesis's equations: the oracle of the kernel.

`reference_tick` computes what `rhi.control.kernels.tick` computes (steps 2–6 of
`rhi.control.controller`), one equation per line, with an orthonormal null-space basis Z
from an SVD (`null_basis`), `ascm` / `allocate_lp` / `allocate_active_set` on that basis,
`tertiary`, `safety_room` and `held_part`, the objectives' own `gradient(device, q)` and the
`rhi.metrics` projectors. ``ControllerConfig(implementation="reference")`` runs every tick
here; the fast controller runs a tick here only where the kernel cannot decide accurately
(a held set whose projector block is ill-conditioned) and for the LP allocation.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from rhi.control.active_set import allocate_active_set
from rhi.control.safety import held_part, safety_room
from rhi.control.saturation import (
    allocate_lp,
    allocate_none,
    allocate_scaling,
    ascm,
    null_basis,
    tertiary,
)
from rhi.control.transition import aso_volume, transition_step
from rhi.device import DeviceTerms
from rhi.metrics import nullspace_projector

if TYPE_CHECKING:
    from rhi.control.controller import NullSpaceController

#: Allocations after which the safety torque acts whatever the held (or clipped) joints: all but simple
#: scaling, which keeps chapter 6's Algorithm 2 (its FME term and limit barrier balance each other there).
SAFE = ("ascm", "lp", "active_set", "none")


def reference_terms(ctrl: NullSpaceController, q: np.ndarray, dq: np.ndarray) -> DeviceTerms:
    """The device terms from per-call Device methods (fk, jacobian, jacobian_derivative, mass_matrix, gravity)."""
    dev = ctrl.device
    return DeviceTerms(
        dev, q, dq, x=dev.fk(q), J=dev.jacobian(q), dJ=dev.jacobian_derivative(q), M=dev.mass_matrix(q), g=dev.gravity(q)
    )


def reference_tick(
    ctrl: NullSpaceController, t: float, kin: DeviceTerms, sensors: Mapping[str, np.ndarray],
    forces: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, float, float, np.ndarray, bool]:
    """Steps 2–6 of one tick; advances ``ctrl.state``'s V, transition and Ω.

    `forces` (F_render, F_extra) [N] when the primary law has already run this tick.

    Returns:
        (τ (n,) [N m] before the final clip to the box, α, β, saturated (n,) bool, clipped).
    """
    s, cfg, dev = ctrl.state, ctrl.config, ctrl.device
    lo, hi = ctrl.lo, ctrl.hi
    J, q, dq = kin.J, kin.q, kin.dq
    F_r, F_x = cfg.primary.forces(t, kin, sensors) if forces is None else forces
    a = J.T @ F_r
    b = J.T @ F_x
    if cfg.gravity_compensation and kin.g @ kin.g != 0.0:
        b = b + (kin.g - J.T @ kin.Gx)  # (I − JᵀJ#ᵀ) g: the part G_x leaves out
    tau_m = a + b
    s.V = aso_volume(tau_m, lo, hi, ctrl.aso_shape)
    fme = cfg.fme
    if fme is not None:
        s.transition, s.omega = transition_step(s.transition, t, s.V, fme.distance, fme.transition)

    # a controller's tick always has q̇ (dq is not None)
    tau_s = -cfg.damping * dq - sum((gain * np.asarray(obj.gradient(dev, q)) for gain, obj in ctrl.barriers),  # type: ignore[operator]
                                    np.zeros(dev.n))
    tau_to = tau_s
    if fme is not None and fme.gain > 0:
        # ctrl.fme_objective is built whenever config.fme is set
        tau_to = tau_to - fme.gain * ctrl.fme_objective.with_desired(  # type: ignore[union-attr]
            fme.desired(s.omega)).gradient(dev, q)
    for gain, obj in ctrl.objectives:
        tau_to = tau_to - gain * np.asarray(obj.gradient(dev, q), dtype=float)

    M = kin.M if cfg.projector == "dynamic" else None
    Z = null_basis(J, M)
    sat = cfg.saturation
    if sat == "ascm":
        al = ascm(a, b, Z, lo, hi)
    elif sat == "lp":
        al = allocate_lp(a, b, Z, lo, hi)
    elif sat == "active_set":
        al = allocate_active_set(a, b, Z, lo, hi)
    elif sat == "scaling":
        al = allocate_scaling(a, b, lo, hi)
    else:
        al = allocate_none(a, b, lo, hi)
    N = nullspace_projector(J, M)
    gamma = 1.0
    if al.saturated.any() and al.method in SAFE:  # safety the held joints would block
        tau1, gamma = safety_room(al.tau, b, held_part(Z, al.saturated, N @ tau_s), lo, hi, skip=al.clipped)
        al = dataclasses.replace(al, tau=tau1)
    delta, beta = tertiary(al.tau, al.saturated, Z, tau_to, lo, hi, N)
    return (al.tau + delta if beta else al.tau), gamma * al.alpha, beta, al.saturated, al.clipped


__all__ = ["reference_terms", "reference_tick"]
