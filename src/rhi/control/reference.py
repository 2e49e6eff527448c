"""The controller tick as the readable composition of the thesis's equations: the oracle of the kernel.

`reference_tick` computes what `rhi.control._compiled.tick` computes (steps 2–6 of
`rhi.control.controller`), one equation per line, with an orthonormal null-space basis Z
from an SVD (`null_basis`), the configured strategy's `allocate` on that basis (`rhi.control.allocation`),
`tertiary`, `safety_room` and `held_part`, the objectives' own `gradient(device, q)` and the
`rhi.metrics` projectors. ``ControllerConfig(implementation="reference")`` runs every tick
here; the fast controller runs a tick here only where the kernel cannot decide accurately
(a held set whose projector block is ill-conditioned, the LP's start outside the box) and for a strategy without a
compiled branch.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from rhi.control.allocation.scaling import allocate_scaling
from rhi.control.objectives import gradient_function
from rhi.control.safety import held_part, safety_room
from rhi.control.saturation import null_basis, tertiary
from rhi.control.settings import ControllerParts
from rhi.control.tank import damper_direction, redistribution_gate, tank_blend
from rhi.control.transition import aso_volume
from rhi.devices.model import DeviceTerms
from rhi.errors import Singular
from rhi.metrics import nullspace_projector


def reference_terms(ctrl: ControllerParts, q: np.ndarray, dq: np.ndarray) -> DeviceTerms:
    """The device terms from per-call Device methods (fk, jacobian, jacobian_derivative, mass_matrix, gravity)."""
    dev = ctrl.device
    return DeviceTerms(
        dev, q, dq, x=dev.fk(q), J=dev.jacobian(q), dJ=dev.jacobian_derivative(q), M=dev.mass_matrix(q), g=dev.gravity(q)
    )


def reference_tick(
    ctrl: ControllerParts, t: float, kin: DeviceTerms, sensors: Mapping[str, np.ndarray],
    forces: tuple[np.ndarray, np.ndarray] | None = None, parts: dict[str, np.ndarray] | None = None,
) -> tuple[np.ndarray, float, float, np.ndarray, bool]:
    """Steps 2–6 of one tick; advances ``ctrl.state``'s V, transition and Ω.

    `forces` (F_render, F_extra) [N] when the primary law has already run this tick. `parts`, if given, is
    filled with the torque by source (``null_space="scaled"`` only), each (n,) [N m], summing to the
    clipped τ: "task" (γ α Jᵀ F_render + Jᵀ F_extra: the rendered wall, its damping and compensation), "gravity"
    (the null-space part of the gravity compensation), "allocation" (the allocation's null-space torque γ Z y,
    eq. 7.8, with what the safety room's clip leaves), "damping" and "barrier" (the safety torque's shares: the
    held part and Algorithm 2's), "tank damper" (`rhi.control.tank`), one "objective i: Name" per objective
    (Algorithm 2's share, times the tank's λ) and "box clip".

    Returns:
        (τ (n,) [N m] before the final clip to the box, α, β, saturated (n,) bool, clipped).
    """
    s, cfg, dev = ctrl.state, ctrl.config, ctrl.device
    lo, hi = ctrl.lo, ctrl.hi
    J, q, dq = kin.J, kin.q, kin.dq
    F_r, F_x = cfg.primary.forces(t, kin, sensors) if forces is None else forces
    a = J.T @ F_r
    b = J.T @ F_x
    g_null = np.zeros(dev.n)
    if cfg.gravity_compensation and kin.g @ kin.g != 0.0:
        g_null = kin.g - J.T @ kin.Gx  # (I − JᵀJ#ᵀ) g: the part G_x leaves out
        b = b + g_null
    tau_m = a + b
    if not np.isfinite(tau_m).all():  # e.g. at a singular configuration or a joint limit: a safe stop (`step`)
        raise Singular(f"the primary law's joint torque Jᵀ F is not finite: F_render={np.asarray(F_r).tolist()}, "
                       f"F_extra={np.asarray(F_x).tolist()}")
    s.V = aso_volume(tau_m, torque_min=lo, torque_max=hi, S=ctrl.aso_shape)
    objectives = ctrl.objectives
    if ctrl.schedule is not None:  # the scheduled objective for this tick's Ω joins the others
        gain, sched = ctrl.schedule
        s.transition, s.omega = sched.advance(s.transition, t, s.V)
        if gain > 0:
            objectives = [(gain, sched.objective(s.omega, hi)), *objectives]

    # a controller's tick always has q̇ (dq is not None)
    tau_s = -cfg.damping * np.asarray(dq) - sum((gain * gradient_function(obj, dev)(kin) for gain, obj in ctrl.barriers),
                                                np.zeros(dev.n))
    tau_to = tau_s
    pushes = [-gain * np.asarray(obj.gradient(dev, q), dtype=float) for gain, obj in objectives]  # −gain ∂ν/∂q each
    for push in pushes:
        tau_to = tau_to + push

    M = kin.M if cfg.projector == "dynamic" else None
    Z = null_basis(J, M)
    if not np.isfinite(Z).all():
        raise Singular("the null-space basis is not finite")
    al = ctrl.allocation.allocate(a, b, Z, torque_min=lo, torque_max=hi)
    N = nullspace_projector(J, M)
    gated = cfg.tank is not None and s.tank is not None and cfg.tank.allocation == "gate"
    if gated and cfg.tank is not None and s.tank is not None:  # the redistribution spends only what T_A holds
        s.tank.gate = 1.0
        if al.saturated.any() and not al.clipped:
            s.tank.gate = theta = redistribution_gate(cfg.tank, s.tank, t, q, np.asarray(dq), kin.Minv,
                                                      N @ al.tau - g_null)
            if theta < 1.0:
                al = blend_allocations(al, allocate_scaling(a, b, torque_min=lo, torque_max=hi), theta)
    al0 = al
    gamma = 1.0
    if al.saturated.any() and ctrl.allocation.safe:  # safety the held joints would block
        tau1, gamma = safety_room(al.tau, b, held_part(Z, al.saturated, N @ tau_s), torque_min=lo, torque_max=hi,
                                 skip=al.clipped)
        al = dataclasses.replace(al, tau=tau1)
    if cfg.null_space == "clipped":  # eqs. 6.2–6.6 as written: the caller clips τ to the box
        return al.tau + N @ tau_to, gamma * al.alpha, 1.0, al.saturated, al.clipped
    delta, beta = tertiary(al.tau, al.saturated, Z, tau_to, torque_min=lo, torque_max=hi, N=N)
    tau = al.tau + delta if beta else al.tau
    beta0, d = beta, np.zeros(dev.n)
    if cfg.tank is not None and s.tank is not None:  # the objectives spend only what the tank holds (rhi.control.tank)
        delta0, beta0 = tertiary(al.tau, al.saturated, Z, tau_s, torque_min=lo, torque_max=hi, N=N)
        d = damper_direction(N @ kin.M, np.asarray(dq), al.saturated, al.tau)
        tau_a = b + gamma * (al0.tau - b) if gated else al.tau  # the gate meters the redistribution alone
        tau = tank_blend(cfg.tank, s.tank, t, q, np.asarray(dq), J, kin.Jsharp, kin.Minv, g_null, tau_a,
                         al.tau + delta0 if beta0 else al.tau, tau, d, lo, hi)
    if parts is not None:
        lam, mu = (1.0, 0.0) if s.tank is None else (s.tank.scale, s.tank.damping)
        _split(parts, ctrl, kin, Z, N, a, b, g_null, al0, al.tau, gamma, tau_s, objectives, pushes,
               (1.0 - lam) * beta0 + lam * beta, lam * beta, -mu * d, np.minimum(np.maximum(tau, lo), hi))
    return tau, gamma * al.alpha, beta, al.saturated, al.clipped


def blend_allocations(ascm, scaling, theta: float):
    """θ ASCM + (1 − θ) simple scaling (`rhi.control.tank.redistribution_gate`): an `Allocation` in the box.

    α and τ blend linearly; a joint stays held where both hold it at the same limit.
    """
    tau = theta * ascm.tau + (1.0 - theta) * scaling.tau
    held = ascm.saturated & scaling.saturated & (np.sign(ascm.tau) == np.sign(scaling.tau))
    return dataclasses.replace(ascm, tau=tau, alpha=theta * ascm.alpha + (1.0 - theta) * scaling.alpha,
                               saturated=held, tau_null=theta * ascm.tau_null, method=f"{ascm.method} gated")


def _split(parts, ctrl, kin, Z, N, a, b, g_null, al0, tau_al, gamma, tau_s, objectives, pushes, beta_s, beta_o, damper,
           tau):
    """Fill `parts` with the tick's torque τ (n,) [N m] by source (see `reference_tick`; pushes: each objective's −gain ∂ν/∂q)."""
    dq = kin.dq
    sat = al0.saturated
    inf = np.full(dq.shape[0], np.inf)

    def share(x: np.ndarray) -> np.ndarray:  # Algorithm 2's projection Π x (β = 1)
        return tertiary(tau_al, sat, Z, x, torque_min=-inf, torque_max=inf, N=N)[0]

    damp = -ctrl.config.damping * dq
    bar = tau_s - damp
    held = tau_al - b - gamma * (al0.tau - b)  # the safety torque the held joints would block (`safety_room`)
    hd, hb = held_part(Z, sat, N @ damp), held_part(Z, sat, N @ bar)
    h = hd + hb
    k = float(held @ h) / float(h @ h) if h @ h > 0.0 else 0.0
    parts.clear()
    parts["task"] = gamma * al0.alpha * a + b - g_null
    parts["gravity"] = g_null
    parts["allocation"] = gamma * (al0.tau - al0.alpha * a - b) + (held - k * h)
    parts["damping"] = k * hd + beta_s * share(damp)
    parts["barrier"] = k * hb + beta_s * share(bar)
    parts["tank damper"] = damper
    for i, ((_, obj), push) in enumerate(zip(objectives, pushes)):
        parts[f"objective {i}: {type(obj).__name__}"] = beta_o * share(push)
    parts["box clip"] = tau - sum(parts.values())


__all__ = ["reference_terms", "reference_tick"]
