"""The controller tick as the readable composition of the thesis's equations: the oracle of the kernel.

`reference_tick` computes what `rhi.control._compiled.tick` computes (steps 2–6 of
`rhi.control.controller`), one equation per line, with an orthonormal null-space basis Z
from an SVD (`null_basis`), the configured strategy's `allocate` on that basis (`rhi.control.allocation`),
`tertiary`, `safety_room` and `held_part`, the objectives' own `gradient(device, q)` and the
`rhi.metrics` projectors. ``ControllerConfig(implementation="reference")`` runs every tick
here; the fast controller runs a tick here only where the kernel cannot decide accurately
(a held set whose projector block is ill-conditioned) and for a strategy without a compiled branch (the LP).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from rhi.control.safety import held_part, safety_room
from rhi.control.saturation import null_basis, tertiary
from rhi.control.tank import hold_work, largest_scale, tank_blend
from rhi.control.transition import aso_volume
from rhi.devices.model import DeviceTerms
from rhi.errors import InvalidInput, Singular
from rhi.metrics import nullspace_projector

if TYPE_CHECKING:
    from rhi.control.controller import NullSpaceController
    from rhi.control.passivity import PassivityController

def reference_terms(ctrl: NullSpaceController, q: np.ndarray, dq: np.ndarray) -> DeviceTerms:
    """The device terms from per-call Device methods (fk, jacobian, jacobian_derivative, mass_matrix, gravity)."""
    dev = ctrl.device
    return DeviceTerms(
        dev, q, dq, x=dev.fk(q), J=dev.jacobian(q), dJ=dev.jacobian_derivative(q), M=dev.mass_matrix(q), g=dev.gravity(q)
    )


def reference_tick(
    ctrl: NullSpaceController, t: float, kin: DeviceTerms, sensors: Mapping[str, np.ndarray],
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
    tau_s = -cfg.damping * dq - sum((gain * np.asarray(obj.gradient(dev, q)) for gain, obj in ctrl.barriers),  # type: ignore[operator]
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
    al0 = al
    N = nullspace_projector(J, M)
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
        c = np.zeros(Z.shape[1])
        if dev.n - int(np.count_nonzero(al.saturated)) > dev.m:  # the damper's direction: q̇ on the allowed torques
            c = Z.T @ dq
            if al.saturated.any():
                ZS = Z[al.saturated]
                c = c - np.linalg.pinv(ZS) @ (ZS @ c)
        d = Z @ c
        tau = tank_blend(cfg.tank, s.tank, t, q, np.asarray(dq), J, kin.Jsharp, kin.Minv, g_null,
                         al.tau + delta0 if beta0 else al.tau, tau, d, lo, hi)
    if parts is not None:
        lam, mu = (1.0, 0.0) if s.tank is None else (s.tank.scale, s.tank.damping)
        _split(parts, ctrl, kin, Z, N, a, b, g_null, al0, al.tau, gamma, tau_s, objectives, pushes,
               (1.0 - lam) * beta0 + lam * beta, lam * beta, -mu * d, np.minimum(np.maximum(tau, lo), hi))
    return tau, gamma * al.alpha, beta, al.saturated, al.clipped


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


def reference_passivity(pc: PassivityController, t: float, kin: DeviceTerms, tau0: np.ndarray, lo: np.ndarray,
                        hi: np.ndarray) -> np.ndarray:
    """`PassivityController.apply` (steps 1–4 of its docstring), one equation per line.

    The oracle of `rhi.control._compiled.passivity.apply`. Returns the torque to send (n,) [N m];
    advances ``pc.state``.
    """
    s, cfg = pc.state, pc.config
    motors = cfg.port == "motors"
    pos, v = (kin.q, kin.dq) if motors else (kin.x, kin.xdot)
    if v is None:
        raise InvalidInput("dq: the passivity controller needs the joint velocity; call Device.terms(q, dq)")
    if s.position is not None and s.effort is not None:  # 1. PO: the held effort's exact work over the interval
        s.energy -= float(s.effort.dot(pos - s.position))
    E, dt = s.energy, t - s.t
    s.alpha, s.scale = 0.0, 1.0
    tau = tau0

    def effort(tau: np.ndarray) -> np.ndarray:  # τ at the motor port, J#ᵀτ (eq. 7.5) at the handle
        return tau if motors else kin.Jsharp.T.dot(tau)

    if cfg.control and dt > 0.0 and math.isfinite(dt):
        Minv = kin.Minv if motors else kin.JMinv.dot(kin.J.T)
        e0 = effort(tau0)
        w0 = hold_work(e0, v, Minv, dt)
        if w0 > E:  # 2. the coming interval would leave E_obs < 0
            Mv = kin.M.dot(v) if motors else kin.Lambda.dot(v)
            ke2 = float(v.dot(Mv))  # 2 × the kinetic energy of the port's motion [J]
            tau_d = np.zeros_like(tau0)
            if ke2 > 0.0 and cfg.method != "bounding":  # 3. the series damper
                a_max = 0.5 / dt if cfg.alpha_max is None else cfg.alpha_max
                s.alpha = min((w0 - E) / (dt * ke2), a_max)
                tau_d = -s.alpha * Mv if motors else kin.J.T.dot(-s.alpha * Mv)
                tau_d = np.minimum(np.maximum(tau_d, lo), hi)
                s.dissipated -= hold_work(effort(tau_d), v, Minv, dt)
            if cfg.method == "damper":  # the law untouched
                tau = tau0 + tau_d
            elif motors:  # 4. the null-space part of the law's torque yields first, then the task part
                tau_t = kin.J.T.dot(kin.Jsharp.T.dot(tau0))
                lam_n = largest_scale(E, tau_t + tau_d, tau0 - tau_t, v, Minv, dt)
                lam_t = 1.0 if lam_n > 0.0 else largest_scale(E, tau_d, tau_t, v, Minv, dt)
                tau = lam_t * tau_t + lam_n * (tau0 - tau_t) + tau_d
                s.scale = lam_t
            else:
                s.scale = largest_scale(E, effort(tau_d), e0, v, Minv, dt)
                tau = s.scale * tau0 + tau_d
            tau = np.minimum(np.maximum(tau, lo), hi)
    s.t, s.position, s.effort = t, np.array(pos, dtype=float), effort(tau)
    return tau
