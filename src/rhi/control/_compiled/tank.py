"""The null-space energy tank of one tick, compiled (equations: `rhi.control.tank`).

`blend` is what `rhi.control.tank.tank_blend` computes, run inside `rhi.control._compiled.step.tick`;
the reference is its oracle (equal to rounding, `tests/test_tank.py`).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.control._compiled.allocation import scaling_alpha
from rhi.control._compiled.passivity import _largest_scale, _work
from rhi.devices._compiled.terms import dot, mtv
from rhi.jit import jit

#: Slots of the tank vector: settings (on, capacity [J]), then state (T [J], a previous tick, its time [s], λ, μ).
TK_ON, TK_CAPACITY, TK_ENERGY, TK_PREV, TK_T, TK_SCALE, TK_DAMPING = range(7)
N_TANK = 7


@jit
def _null(J, Jsharp, tau, g_null):
    """N τ − g_N, N = I − JᵀJ#ᵀ."""
    return tau - mtv(J, mtv(Jsharp, tau)) - g_null


@jit
def blend(tank, tank_q, tank_e, t, q, dq, J, Jsharp, Minv, g_null, tau0, tau1, d, lo, hi, tau_out):
    """Steps 1–4 of `rhi.control.tank.tank_blend`; writes the torque to send into tau_out and advances the tank.

    Args:
        tank: (N_TANK,) settings and state (TK_* slots), advanced in place.
        tank_q: (n,) q of the previous tick [rad], written.
        tank_e: (n,) the metered null-space torque of the previous tick [N m], written.
        t: time [s].
        q: (n,) joint positions [rad].
        dq: (n,) joint velocities [rad/s].
        J: (m, n) task Jacobian.
        Jsharp: (n, m) J#.
        Minv: (n, n) M⁻¹.
        g_null: (n,) null-space part of the gravity compensation [N m].
        tau0: (n,) the tick without the objectives [N m].
        tau1: (n,) the tick with them [N m].
        d: (n,) the damper's direction Π q̇ [rad/s].
        lo: (n,) lower torque limits [N m].
        hi: (n,) upper torque limits [N m].
        tau_out: (n,) the torque to send, written [N m].
    """
    n = q.shape[0]
    if tank[TK_PREV] != 0.0:
        tank[TK_ENERGY] = min(tank[TK_ENERGY] - dot(tank_e, q - tank_q), tank[TK_CAPACITY])
    E = tank[TK_ENERGY]
    dt = t - tank[TK_T]
    lam, mu = 0.0, 0.0
    tau = tau0.copy()
    diff = tau1 - tau0
    if dt > 0.0 and math.isfinite(dt):
        deficit = _work(_null(J, Jsharp, tau0, g_null), dq, Minv, dt) - E
        p = dot(dq, d)
        if deficit > 0.0 and p > 0.0:
            tr = 0.0
            for i in range(n):
                tr += Minv[i, i]
            mu = min(deficit / (dt * p), 0.5 / (dt * tr))
            sigma = scaling_alpha(-mu * d, tau0, lo, hi, np.ones(n, np.bool_))
            mu = mu * sigma if sigma > 0.0 else 0.0
            tau = tau0 - mu * d
        lam = _largest_scale(E, _null(J, Jsharp, tau, g_null), _null(J, Jsharp, diff, np.zeros(n)), dq, Minv, dt)
        if lam > 0.0:
            room = scaling_alpha(diff, tau, lo, hi, np.ones(n, np.bool_))
            lam = min(lam, room if room > 0.0 else 0.0)
    for i in range(n):
        tau_out[i] = min(max(tau[i] + lam * diff[i], lo[i]), hi[i])
    tank[TK_SCALE], tank[TK_DAMPING], tank[TK_PREV], tank[TK_T] = lam, mu, 1.0, t
    tank_q[:] = q
    tank_e[:] = _null(J, Jsharp, tau_out, g_null)
