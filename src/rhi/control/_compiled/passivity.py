"""The passivity observer and controller of one tick, compiled (equations: `rhi.control.passivity`).

`apply` is what `PassivityController.apply` runs at 1 kHz; `rhi.control.passivity.reference_passivity`
is its readable oracle (equal to rounding, `tests/test_passivity.py`).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices._compiled.terms import dot
from rhi.jit import jit, stack_empty


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
def _effort(motors, Jsharp, tau, out):
    """Write τ (motor port) or J#ᵀτ (handle port) into out (k,); returns out."""
    if motors:
        for i in range(tau.shape[0]):
            out[i] = tau[i]
        return out
    _mtv_to(Jsharp, tau, out)
    return out


@jit
def _mtv_to(A, v, out):
    """Write Aᵀ v into out (n,) for A (k, n), v (k,): `rhi.devices._compiled.terms.mtv`'s arithmetic, no allocation."""
    k, n = A.shape
    for j in range(n):
        out[j] = 0.0
    for i in range(k):
        vi = v[i]
        for j in range(n):
            out[j] += A[i, j] * vi


#: Codes of `apply`'s mode: observe only, series damper and energy bounding, the series damper only,
#: energy bounding only (`rhi.control.passivity.Passivity.method`).
OBSERVE, DAMPER_BOUNDING, DAMPER, BOUNDING = 0, 1, 2, 3


@jit(inline=True)
def apply(E, has_prev, pos_prev, eff_prev, dt, pos, v, M_port, Minv_port, J, Jsharp, tau0, lo, hi, motors, mode,
          alpha_max, tau, eff):
    """PO then PC of one tick (steps 1–4 of `PassivityController.apply`).

    Its temporaries live on the stack (`rhi.jit.stack_empty`): no allocation; the arithmetic is that of the array
    expressions it replaced, element by element.

    Args:
        E: E_obs before this tick [J].
        has_prev: a torque was sent at an earlier tick (pos_prev, eff_prev hold it).
        pos_prev: (k,) port position of that tick.
        eff_prev: (k,) port effort of that tick (read before eff is written: may be the same array).
        dt: time since that tick [s] (≤ 0 or non-finite: observe only).
        pos: (k,) port position now (q [rad] or x [m]).
        v: (k,) port velocity now (q̇ or ẋ).
        M_port: (k, k) the port's inertia (M_q or M_x).
        Minv_port: (k, k) its inverse.
        J: (m, n) task Jacobian.
        Jsharp: (n, m) its dynamically consistent inverse J#.
        tau0: (n,) the law's torque [N m] (another array than tau).
        lo: (n,) lower bound of the torque box [N m].
        hi: (n,) upper bound of the torque box [N m].
        motors: the motor port (else the handle port).
        mode: OBSERVE, DAMPER_BOUNDING (steps 1–4), DAMPER (steps 1–3: the law untouched) or BOUNDING
            (steps 1, 2 and 4: no damper).
        alpha_max: bound on α [1/s] (≤ 0: 0.5 / dt).
        tau: (n,) output, the torque to send [N m].
        eff: (k,) output, the effort sent (τ at the motor port, J#ᵀτ at the handle port).

    Returns:
        (E_obs(n) [J], α [1/s], λ, energy the damping is predicted to take out [J]).
    """
    if has_prev:
        s = 0.0
        for i in range(pos.shape[0]):
            s += eff_prev[i] * (pos[i] - pos_prev[i])
        E -= s
    alpha, scale, dissipated = 0.0, 1.0, 0.0
    n, k = tau0.shape[0], pos.shape[0]
    for i in range(n):
        tau[i] = tau0[i]
    if mode != OBSERVE and dt > 0.0 and math.isfinite(dt):
        e0, e1 = stack_empty(k, np.float64), stack_empty(k, np.float64)
        _effort(motors, Jsharp, tau0, e0)
        w0 = _work(e0, v, Minv_port, dt)
        if w0 > E:
            Mv = stack_empty(k, np.float64)
            for i in range(k):  # M v
                s = 0.0
                for j in range(k):
                    s += M_port[i, j] * v[j]
                Mv[i] = s
            ke2 = dot(v, Mv)  # 2 × the kinetic energy of the port's motion [J]
            tau_d, out = stack_empty(n, np.float64), stack_empty(n, np.float64)
            for i in range(n):
                tau_d[i] = 0.0
            if ke2 > 0.0 and mode != BOUNDING:
                a_max = 0.5 / dt if alpha_max <= 0.0 else alpha_max
                alpha = min((w0 - E) / (dt * ke2), a_max)
                na = -alpha
                for i in range(k):  # −α M v
                    Mv[i] = na * Mv[i]
                if motors:
                    for i in range(n):
                        tau_d[i] = Mv[i]
                else:
                    _mtv_to(J, Mv, tau_d)
                for i in range(n):  # np.minimum(np.maximum(τ_d, lo), hi): NaN propagates
                    tau_d[i] = np.minimum(np.maximum(tau_d[i], lo[i]), hi[i])
                dissipated = -_work(_effort(motors, Jsharp, tau_d, e1), v, Minv_port, dt)
            if mode == DAMPER:
                for i in range(n):
                    out[i] = tau0[i] + tau_d[i]
            elif motors:  # the null-space part yields first, then the task part
                tau_t, tau_n, base = stack_empty(n, np.float64), stack_empty(n, np.float64), stack_empty(n, np.float64)
                _mtv_to(Jsharp, tau0, e1[:J.shape[0]])
                _mtv_to(J, e1[:J.shape[0]], tau_t)
                for i in range(n):
                    tau_n[i] = tau0[i] - tau_t[i]
                    base[i] = tau_t[i] + tau_d[i]
                lam_n = _largest_scale(E, base, tau_n, v, Minv_port, dt)
                lam_t = 1.0 if lam_n > 0.0 else _largest_scale(E, tau_d, tau_t, v, Minv_port, dt)
                for i in range(n):
                    out[i] = lam_t * tau_t[i] + lam_n * tau_n[i] + tau_d[i]
                scale = lam_t
            else:
                scale = _largest_scale(E, _effort(motors, Jsharp, tau_d, e1), e0, v, Minv_port, dt)
                for i in range(n):
                    out[i] = scale * tau0[i] + tau_d[i]
            for i in range(n):
                tau[i] = min(max(out[i], lo[i]), hi[i])
    _effort(motors, Jsharp, tau, eff)
    return E, alpha, scale, dissipated
