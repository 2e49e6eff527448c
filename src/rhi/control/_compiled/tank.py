"""The null-space energy tank of one tick, compiled (equations: `rhi.control.tank`).

`blend` is what `rhi.control.tank.tank_blend` computes, `direction` what `rhi.control.tank.damper_direction`
and `gate` what `rhi.control.tank.redistribution_gate` computes, run inside `rhi.control._compiled.step.tick`;
the reference is their oracle (equal to rounding, `tests/test_tank.py`).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.control._compiled.allocation import above, allocate_scaling, held_torque, scaling_alpha
from rhi.control._compiled.passivity import _largest_scale, _work
from rhi.devices._compiled.terms import dot, mtv, mv
from rhi.jit import jit

#: Slots of the tank vector: settings (on, capacity [J]), then state (T_O [J], a previous tick, its time [s], λ, μ,
#: T_A [J]), then the allocation's gate (setting: on; state: θ of the tick).
TK_ON, TK_CAPACITY, TK_ENERGY, TK_PREV, TK_T, TK_SCALE, TK_DAMPING, TK_ALLOCATION, TK_GATE, TK_THETA = range(10)
N_TANK = 10
#: As `rhi.control.tank.FACE_TOL` and `INWARD_TOL`.
_FACE_TOL = 1e-6
_INWARD_TOL = 1e-12


@jit
def _null(J, Jsharp, tau, g_null):
    """N τ − g_N, N = I − JᵀJ#ᵀ."""
    return tau - mtv(J, mtv(Jsharp, tau)) - g_null


@jit
def null_inertia(J, Jsharp, M):
    """Q = N M (n, n) [kg m²], the null-space inertia of `rhi.control.tank.damper_direction`."""
    n = M.shape[0]
    Q = np.empty((n, n))
    z = np.zeros(n)
    for j in range(n):
        Q[:, j] = _null(J, Jsharp, M[:, j].copy(), z)
    return Q


@jit
def direction(Q, dq, S, k, tau):
    """`rhi.control.tank.damper_direction`: (n,) [N m s].

    Args:
        Q: (n, n) the null-space inertia N M [kg m²].
        dq: (n,) joint velocities [rad/s].
        S: (n,) int, the held joints in S[:k].
        k: how many joints are held.
        tau: (n,) the torque whose held entries are at their limits [N m].
    """
    n = dq.shape[0]
    base = mv(Q, dq)
    tr = 0.0
    for i in range(n):
        tr += Q[i, i]
    best = np.zeros(n)
    p_best = 0.0
    A = np.empty(n, np.int64)
    for mask in range(1 << k):
        ka = 0
        for j in range(k):
            if mask >> j & 1:
                A[ka] = S[j]
                ka += 1
        d = base
        if ka:
            G = np.empty((ka, ka))
            rr = np.empty(ka)
            for i in range(ka):
                rr[i] = base[A[i]]
                for j in range(ka):
                    G[i, j] = Q[A[i], A[j]]
            if not above(G, _FACE_TOL * tr):
                continue
            h = np.empty(n)
            held_torque(Q, A, ka, rr, h)
            d = base - h
        ok = True
        for j in range(k):
            if not (mask >> j & 1) and math.copysign(1.0, tau[S[j]]) * d[S[j]] < -_INWARD_TOL:
                ok = False
        if not ok:
            continue
        p = dot(dq, d)
        if p > p_best:
            best = d
            p_best = p
    return best


@jit
def gate(tank, tank_q, tank_e, t, q, dq, Minv, e):
    """`rhi.control.tank.redistribution_gate`: θ ∈ [0, 1], the share of the redistribution e (n,) [N m] paid for."""
    T_A = tank[TK_ALLOCATION]
    if tank[TK_PREV] != 0.0:
        T_A = min(T_A - dot(tank_e[1], q - tank_q), tank[TK_CAPACITY])
    dt = t - tank[TK_T]
    if not (dt > 0.0 and math.isfinite(dt)):
        return 0.0 if dot(e, e) != 0.0 else 1.0
    return _largest_scale(T_A, np.zeros(q.shape[0]), e, dq, Minv, dt)


@jit
def gated(theta, tau, alpha, a, b, lo, hi, sat):
    """θ τ_ASCM + (1 − θ) τ_scaling and its α (`rhi.control.reference.blend_allocations`); sat narrowed in place.

    A joint stays held where simple scaling holds it too, at the same limit.
    """
    n = a.shape[0]
    sc = np.zeros(n, np.bool_)
    tau_sc, alpha_sc, _ = allocate_scaling(a, b, lo, hi, sc)
    for i in range(n):
        sat[i] = sat[i] and sc[i] and (tau[i] > 0.0) == (tau_sc[i] > 0.0)
    out = np.empty(n)
    for i in range(n):
        out[i] = theta * (tau[i] - tau_sc[i]) + tau_sc[i]
    return out, theta * alpha + (1.0 - theta) * alpha_sc


@jit(inline=True)
def blend(tank, tank_q, tank_e, t, q, dq, J, Jsharp, Minv, g_null, tau_a, tau0, tau1, d, lo, hi, tau_out):
    """Steps 1–4 of `rhi.control.tank.tank_blend`; writes the torque to send into tau_out and advances the tank.

    Args:
        tank: (N_TANK,) settings and state (TK_* slots), advanced in place.
        tank_q: (n,) q of the previous tick [rad], written.
        tank_e: (2, n) the metered null-space torques e_O, e_A of the previous tick [N m], written.
        t: time [s].
        q: (n,) joint positions [rad].
        dq: (n,) joint velocities [rad/s].
        J: (m, n) task Jacobian.
        Jsharp: (n, m) J#.
        Minv: (n, n) M⁻¹.
        g_null: (n,) null-space part of the gravity compensation [N m].
        tau_a: (n,) the allocation's torque [N m].
        tau0: (n,) the tick without the objectives [N m].
        tau1: (n,) the tick with them [N m].
        d: (n,) the damper's direction (`direction`) [N m s].
        lo: (n,) lower torque limits [N m].
        hi: (n,) upper torque limits [N m].
        tau_out: (n,) the torque to send, written [N m].
    """
    n = q.shape[0]
    if tank[TK_PREV] != 0.0:
        dqk = q - tank_q
        tank[TK_ENERGY] = min(tank[TK_ENERGY] - dot(tank_e[0], dqk), tank[TK_CAPACITY])
        tank[TK_ALLOCATION] = min(tank[TK_ALLOCATION] - dot(tank_e[1], dqk), tank[TK_CAPACITY])
    dt = t - tank[TK_T]
    lam, mu = 0.0, 0.0
    tau = tau0.copy()
    diff = tau1 - tau0
    e_a = _null(J, Jsharp, tau_a, g_null)
    if dt > 0.0 and math.isfinite(dt):
        deficit = _work(e_a, dq, Minv, dt) - tank[TK_ALLOCATION]
        p = dot(dq, d)
        if deficit > 0.0 and p > 0.0 and tank[TK_GATE] == 0.0:
            mu = min(deficit / (dt * p), 0.5 / dt)
            sigma = scaling_alpha(-mu * d, tau0, lo, hi, np.ones(n, np.bool_))
            mu = mu * sigma if sigma > 0.0 else 0.0
            tau = tau0 - mu * d
        lam = _largest_scale(tank[TK_ENERGY], _null(J, Jsharp, tau0, g_null) - e_a,
                             _null(J, Jsharp, diff, np.zeros(n)), dq, Minv, dt)
        if lam > 0.0:
            room = scaling_alpha(diff, tau, lo, hi, np.ones(n, np.bool_))
            lam = min(lam, room if room > 0.0 else 0.0)
    for i in range(n):
        tau_out[i] = min(max(tau[i] + lam * diff[i], lo[i]), hi[i])
    tank[TK_SCALE], tank[TK_DAMPING], tank[TK_PREV], tank[TK_T] = lam, mu, 1.0, t
    e_a = e_a - mu * _null(J, Jsharp, d, np.zeros(n))
    tank_q[:] = q
    tank_e[1, :] = e_a
    tank_e[0, :] = _null(J, Jsharp, tau_out, g_null) - e_a
