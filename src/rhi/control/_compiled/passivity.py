"""The passivity observer and controller of one tick, compiled (equations: `rhi.control.passivity`).

`apply` is what `PassivityController.apply` runs at 1 kHz; `rhi.control.passivity.reference_passivity`
is its readable oracle (equal to rounding, `tests/test_passivity.py`).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices._compiled.terms import dot, mtv, mv
from rhi.jit import jit


@jit
def _quad(a, Minv, b):
    """aᵀ M⁻¹ b for vectors a, b (k,) and Minv (k, k) (loops: no temporary vector)."""
    k = a.shape[0]
    s = 0.0
    for i in range(k):
        t = 0.0
        for j in range(k):
            t += Minv[i, j] * b[j]
        s += a[i] * t
    return s


@jit
def _work(e, v, Minv, dt):
    """w(e) = ΔT eᵀv + ½ ΔT² eᵀ M⁻¹ e [J]."""
    return dt * dot(e, v) + 0.5 * dt * dt * _quad(e, Minv, e)


@jit
def _largest_scale(E, base, part, v, Minv, dt):
    """The largest λ ∈ [0, 1] with w(base + λ part) ≤ E (the larger root of a convex quadratic in λ)."""
    A = 0.5 * dt * dt * _quad(part, Minv, part)
    B = dt * dot(part, v) + dt * dt * _quad(part, Minv, base)
    C = _work(base, v, Minv, dt) - E
    if A + B + C <= 0.0:
        return 1.0
    if C >= 0.0:
        return 0.0
    lam = (-B + math.sqrt(max(B * B - 4.0 * A * C, 0.0))) / (2.0 * A) if A > 0.0 else -C / B
    return min(max(lam, 0.0), 1.0)


@jit
def _effort(motors, Jsharp, tau):
    """τ (motor port) or J#ᵀτ (handle port)."""
    return tau.copy() if motors else mtv(Jsharp, tau)


#: Codes of `apply`'s mode: observe only, series damper and energy bounding, the series damper only,
#: energy bounding only (`rhi.control.passivity.Passivity.method`).
OBSERVE, DAMPER_BOUNDING, DAMPER, BOUNDING = 0, 1, 2, 3


@jit(inline=True)
def apply(E, has_prev, pos_prev, eff_prev, dt, pos, v, M_port, Minv_port, J, Jsharp, tau0, lo, hi, motors, mode,
          alpha_max, tau):
    """PO then PC of one tick (steps 1–4 of `PassivityController.apply`).

    Args:
        E: E_obs before this tick [J].
        has_prev: a torque was sent at an earlier tick (pos_prev, eff_prev hold it).
        pos_prev: (k,) port position of that tick.
        eff_prev: (k,) port effort of that tick.
        dt: time since that tick [s] (≤ 0 or non-finite: observe only).
        pos: (k,) port position now (q [rad] or x [m]).
        v: (k,) port velocity now (q̇ or ẋ).
        M_port: (k, k) the port's inertia (M_q or M_x).
        Minv_port: (k, k) its inverse.
        J: (m, n) task Jacobian.
        Jsharp: (n, m) its dynamically consistent inverse J#.
        tau0: (n,) the law's torque [N m].
        lo: (n,) lower bound of the torque box [N m].
        hi: (n,) upper bound of the torque box [N m].
        motors: the motor port (else the handle port).
        mode: OBSERVE, DAMPER_BOUNDING (steps 1–4), DAMPER (steps 1–3: the law untouched) or BOUNDING
            (steps 1, 2 and 4: no damper).
        alpha_max: bound on α [1/s] (≤ 0: 0.5 / dt).
        tau: (n,) output, the torque to send [N m].

    Returns:
        (E_obs(n) [J], α [1/s], λ, energy the damping is predicted to take out [J], (k,) effort sent).
    """
    if has_prev:
        s = 0.0
        for i in range(pos.shape[0]):
            s += eff_prev[i] * (pos[i] - pos_prev[i])
        E -= s
    alpha, scale, dissipated = 0.0, 1.0, 0.0
    n = tau0.shape[0]
    for i in range(n):
        tau[i] = tau0[i]
    if mode != OBSERVE and dt > 0.0 and math.isfinite(dt):
        e0 = _effort(motors, Jsharp, tau0)
        w0 = _work(e0, v, Minv_port, dt)
        if w0 > E:
            Mv = mv(M_port, v)
            ke2 = dot(v, Mv)  # 2 × the kinetic energy of the port's motion [J]
            tau_d = np.zeros(n)
            if ke2 > 0.0 and mode != BOUNDING:
                a_max = 0.5 / dt if alpha_max <= 0.0 else alpha_max
                alpha = min((w0 - E) / (dt * ke2), a_max)
                tau_d = -alpha * Mv if motors else mtv(J, -alpha * Mv)
                tau_d = np.minimum(np.maximum(tau_d, lo), hi)
                dissipated = -_work(_effort(motors, Jsharp, tau_d), v, Minv_port, dt)
            if mode == DAMPER:
                out = tau0 + tau_d
            elif motors:  # the null-space part yields first, then the task part
                tau_t = mtv(J, mtv(Jsharp, tau0))
                tau_n = tau0 - tau_t
                lam_n = _largest_scale(E, tau_t + tau_d, tau_n, v, Minv_port, dt)
                lam_t = 1.0 if lam_n > 0.0 else _largest_scale(E, tau_d, tau_t, v, Minv_port, dt)
                out = lam_t * tau_t + lam_n * tau_n + tau_d
                scale = lam_t
            else:
                scale = _largest_scale(E, _effort(motors, Jsharp, tau_d), e0, v, Minv_port, dt)
                out = scale * tau0 + tau_d
            for i in range(n):
                tau[i] = min(max(out[i], lo[i]), hi[i])
    return E, alpha, scale, dissipated, _effort(motors, Jsharp, tau)
