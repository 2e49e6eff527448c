"""The acceleration-level mobile controllers' tick, compiled (thesis App. B; equations: `rhi.control.mobile`).

`accel_tick` is one `step` of `rhi.control.mobile.AMDController` (the joint acceleration bounds B.6–B.8, saturation
in the null space B.9, the tertiary objective B.10–B.19 and the base's stop B.20) or of
`rhi.control.mobile.PinvAccelController` (§B.4.3's "traditional" J⁺ with the tertiary objective and the clip),
with the kinematics of `rhi.control._compiled.mobile_terms`. The Python controllers are its oracle (equal to
rounding, `tests/test_mobile_loop.py`). Run by `rhi.sim._compiled.mobile_loop`.
"""

from __future__ import annotations

import math

import numpy as np

from rhi.control._compiled.mobile_terms import det_terms, gram, point_terms, sym3
from rhi.jit import jit

#: `accel_tick`'s controllers.
AMD, PINV = 0, 1
#: Slots of the parameter vector: T [s], K_p, K_d, σ_m,min, the release threshold [m/rad], γ₁, γ₂, singularity
#: avoidance, the tertiary objective (PINV), the clip (PINV), the rank tolerance of J_S.
P_DT, P_KP, P_KD, P_SIGMA, P_RELEASE, P_G1, P_G2, P_AVOID, P_MANIP, P_CLIP, P_RANK = range(11)
N_PARAMS = 11
#: Slots of the state vector: time of the last step [s], base enabled, t₀ of the base's stop (NaN: none), steps,
#: clipped steps (PINV), then V_b (3) of the stop.
S_T, S_BASE, S_STOP_T0, S_STEPS, S_CLIPPED, S_STOP_V = range(6)
N_STATE = 8
#: Slots of a tick's record: α, β, σ_min(J_m) [m/rad], base enabled.
R_ALPHA, R_BETA, R_SIGMA, R_BASE = range(4)
#: `accel_tick`'s outcomes: done; J_m J_mᵀ (or J Jᵀ) singular, which the Python controller raises.
OK, SINGULAR = 0, 1
#: As `rhi.control.mobile.bounds.EPS`.
_EPS = 1e-12


@jit(inline=True)
def acceleration_bounds(q, dq, bnd, T, lo, hi):
    """`rhi.control.mobile.bounds.acceleration_bounds` of one configuration (B.6–B.8), written into lo, hi.

    Args:
        q: (n,) joint positions.
        dq: (n,) joint velocities.
        bnd: (6, n) q_min, q_max, dq_min, dq_max, ddq_min, ddq_max.
        T: sampling time [s].
        lo: (n,) lower bounds Q̈_min, written.
        hi: (n,) upper bounds Q̈_max, written.
    """
    T2 = T * T
    for i in range(q.shape[0]):
        qi, vi = q[i], dq[i]
        qmin, qmax, vmin, vmax, amin, amax = bnd[0, i], bnd[1, i], bnd[2, i], bnd[3, i], bnd[4, i], bnd[5, i]
        a = max(2.0 * (qmin - qi - vi * T) / T2 if qmin > -math.inf else -math.inf, (vmin - vi) / T, amin)
        b = min(2.0 * (qmax - qi - vi * T) / T2 if qmax < math.inf else math.inf, (vmax - vi) / T, amax)
        if qmax < math.inf:
            A = -amin
            r = qmax - qi - 0.5 * vi * T - A * T2 / 8.0
            b = min(b, (-A * T + math.sqrt(A * A * T2 + 2.0 * A * r) - vi) / T if r >= 0 else amin)
            if qi >= qmax + abs(vi) * vi / (2.0 * amin):
                b = amin
        if qmin > -math.inf:
            A = amax
            r = qi - qmin + 0.5 * vi * T - A * T2 / 8.0
            a = max(a, (A * T - math.sqrt(A * A * T2 + 2.0 * A * r) - vi) / T if r >= 0 else amax)
            if qi <= qmin - abs(vi) * vi / (2.0 * amax):
                a = amax
        a = min(max(a, amin), amax)
        b = min(max(b, amin), amax)
        if a > b:
            a = b = a if qi - qmin < qmax - qi else b
        lo[i], hi[i] = a, b


@jit
def scale_factor(a, c, lo, hi, act):
    """`rhi.control.mobile.bounds.scale_factor_lists` (Fig. B.4): (s, the most critical joint or −1)."""
    s_hi, i_hi = math.inf, -1
    s_lo, i_lo = -math.inf, -1
    for i in range(a.shape[0]):
        if not act[i]:
            continue
        ai, ci = a[i], c[i]
        if ai > _EPS:
            up, dn = (hi[i] - ci) / ai, (lo[i] - ci) / ai
        elif ai < -_EPS:
            up, dn = (lo[i] - ci) / ai, (hi[i] - ci) / ai
        else:
            if ci > hi[i] + 1e-12 or ci < lo[i] - 1e-12:
                return 0.0, i
            continue
        if up < s_hi:
            s_hi, i_hi = up, i
        if dn > s_lo:
            s_lo, i_lo = dn, i
    s = min(1.0, s_hi)
    if s < 0.0:  # the smallest ratio first (Fig. B.4): no s ≥ 0 brings that joint within its bounds
        return 0.0, i_hi
    if s_lo > s and (s_lo - s) * abs(a[i_lo]) > 1e-12:
        return 0.0, i_lo
    return s, (i_hi if math.isfinite(s_hi) else -1)


@jit
def _clip(v, lo, hi, out):
    """Out = min(max(v, lo), hi) entry by entry."""
    for i in range(v.shape[0]):
        out[i] = min(max(v[i], lo[i]), hi[i])


@jit
def _apply(G, v, out):
    """Out (3,) = G v for a 3×3 G."""
    for r in range(3):
        out[r] = G[r, 0] * v[0] + G[r, 1] * v[1] + G[r, 2] * v[2]


@jit
def sns(J, b, ddx, lo, hi, enabled, fixed, rank_tol, ddq, active, Ginv):
    """`rhi.control.mobile.sns_acceleration` (B.9) for 3 task rows: ddq, the selection `active`, (J_S J_Sᵀ)⁻¹ written.

    Returns:
        (α, feasible, whether Ginv holds the selection's (J_S J_Sᵀ)⁻¹).
    """
    n = J.shape[1]
    qN = np.empty(n)
    for i in range(n):
        active[i] = enabled[i]
        qN[i] = 0.0 if active[i] else fixed[i]
    best_s = -1.0
    found = False
    best_a, best_c, best_act = np.zeros(n), np.zeros(n), active.copy()
    best_G, Gram, G = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    a, c = np.empty(n), np.empty(n)
    rhs, ya, yc, e, d = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for _ in range(n + 1):
        k = 0
        for i in range(n):
            k += active[i]
        if k < 3:
            break
        gram(J, 0, n, active, Gram)
        _, lmin, lmax, inv_ok = sym3(Gram, G)
        if not (inv_ok and lmin > rank_tol * max(lmax, _EPS)):
            break
        for r in range(3):
            rhs[r] = -b[r]
            for i in range(n):
                rhs[r] -= J[r, i] * qN[i]
        for y, v in ((ya, ddx), (yc, rhs)):  # with one step of iterative refinement (as the reference)
            _apply(G, v, y)
            _apply(Gram, y, e)
            for r in range(3):
                e[r] = v[r] - e[r]
            _apply(G, e, d)
            for r in range(3):
                y[r] += d[r]
        for i in range(n):
            a[i], c[i] = 0.0, qN[i]
            if active[i]:
                a[i] = J[0, i] * ya[0] + J[1, i] * ya[1] + J[2, i] * ya[2]
                c[i] += J[0, i] * yc[0] + J[1, i] * yc[1] + J[2, i] * yc[2]
        s, crit = scale_factor(a, c, lo, hi, active)
        if s >= 1.0:
            for i in range(n):
                ddq[i] = min(max(a[i] + c[i], lo[i]), hi[i])
            Ginv[:, :] = G
            return 1.0, True, True
        if s > best_s:
            best_s, found = s, True
            best_a[:], best_c[:], best_act[:], best_G[:, :] = a, c, active, G
        if crit < 0:
            break
        qN[crit] = hi[crit] if a[crit] + c[crit] > hi[crit] else lo[crit]
        active[crit] = False
    if not found:
        _clip(qN, lo, hi, ddq)
        return 0.0, False, False
    for i in range(n):
        ddq[i] = min(max(best_c[i] + best_s * best_a[i], lo[i]), hi[i])
    active[:] = best_act
    Ginv[:, :] = best_G
    return best_s, False, True


@jit(inline=True)
def _amd(prm, st, t, dq, J, b, ddx, lo, hi, ddq_A, sigma, ddq, rec):
    """`AMDController.step` after the task, the bounds and the tertiary acceleration."""
    n = dq.shape[0]
    active = np.empty(n, np.bool_)
    every = np.ones(n, np.bool_)
    G = np.empty((3, 3))
    T, avoid = prm[P_DT], prm[P_AVOID] != 0.0
    was_active = st[S_BASE] != 0.0
    threshold = prm[P_RELEASE] if was_active else prm[P_SIGMA]
    base_active = True
    alpha, has_G = 0.0, False
    fixed = np.zeros(n)
    if not (avoid and sigma < threshold):
        enabled = every.copy()
        for i in range(3):
            fixed[i] = min(max(-dq[i] / T, lo[i]), hi[i])
            enabled[i] = False
        alpha, feasible, has_G = sns(J, b, ddx, lo, hi, enabled, fixed, prm[P_RANK], ddq, active, G)
        base_active = not feasible
    if base_active:
        fixed[:] = 0.0
        alpha, _, has_G = sns(J, b, ddx, lo, hi, every, fixed, prm[P_RANK], ddq, active, G)
        st[S_STOP_T0] = math.nan
        st[S_STOP_V:] = math.nan
    elif was_active or (math.isnan(st[S_STOP_T0]) and (dq[0] != 0.0 or dq[1] != 0.0 or dq[2] != 0.0)):
        st[S_STOP_T0] = t
        st[S_STOP_V:] = dq[:3]
    beta = 0.0
    if avoid and has_G:  # q̈_t = β P_A q̈_A (P_A: `auxiliary_projection`), then B.19
        lam = np.zeros(n)
        w, z = np.zeros(3), np.empty(3)
        for i in range(n):
            if active[i]:
                lam[i] = ddq_A[i]
                for r in range(3):
                    w[r] += J[r, i] * lam[i]
        _apply(G, w, z)
        for i in range(n):
            if active[i]:
                lam[i] -= J[0, i] * z[0] + J[1, i] * z[1] + J[2, i] * z[2]
        beta, _ = scale_factor(lam, ddq, lo, hi, every)
        for i in range(n):
            ddq[i] = min(max(ddq[i] + beta * lam[i], lo[i]), hi[i])
    on = 1.0 if base_active else 0.0
    st[S_BASE], st[S_T] = on, t
    st[S_STEPS] += 1.0
    rec[R_ALPHA], rec[R_BETA], rec[R_SIGMA], rec[R_BASE] = alpha, beta, sigma, on


@jit(inline=True)
def _pinv(prm, st, J, b, ddx, lo, hi, ddq_A, ddq, rec):
    """`PinvAccelController.step` after the task, the bounds and the tertiary acceleration; False: J Jᵀ singular."""
    n = ddq.shape[0]
    G, Gram = np.empty((3, 3)), np.empty((3, 3))
    every = np.ones(n, np.bool_)
    gram(J, 0, n, every, Gram)
    if not sym3(Gram, G)[3]:
        return False
    y, z, e = np.empty(3), np.empty(3), np.zeros(3)
    for r in range(3):
        e[r] = ddx[r] - b[r]
    _apply(G, e, y)  # J⁺ = Jᵀ (J Jᵀ)⁻¹
    if prm[P_MANIP] != 0.0:  # + (I − J⁺J) q̈_A
        e[:] = 0.0
        for i in range(n):
            for r in range(3):
                e[r] += J[r, i] * ddq_A[i]
        _apply(G, e, z)
    for i in range(n):
        ddq[i] = J[0, i] * y[0] + J[1, i] * y[1] + J[2, i] * y[2]
        if prm[P_MANIP] != 0.0:
            ddq[i] += ddq_A[i] - (J[0, i] * z[0] + J[1, i] * z[1] + J[2, i] * z[2])
    if prm[P_CLIP] != 0.0:
        clipped = False
        for i in range(n):
            v = min(max(ddq[i], lo[i]), hi[i])
            clipped = clipped or v != ddq[i]
            ddq[i] = v
        if clipped:
            st[S_CLIPPED] += 1.0
    gram(J, 3, n, every, Gram)
    lmin = sym3(Gram, G)[1]
    rec[R_ALPHA], rec[R_BETA], rec[R_SIGMA], rec[R_BASE] = 1.0, 1.0, math.sqrt(max(lmin, 0.0)), 1.0
    return True


@jit(inline=True)
def accel_tick(kind, prm, bnd, ints, joints, fc, st, t, q, dq, xd, dxd, ddxd, x, ddq, rec):
    """One step of the AMD (kind AMD) or the traditional controller (PINV) at time t [s].

    Args:
        kind: AMD or PINV.
        prm: (N_PARAMS,) settings (P_* slots).
        bnd: (6, n) the joint bounds (`acceleration_bounds`).
        ints: the device's `pack` integer constants (`point_terms`).
        joints: its per-joint constants.
        fc: its frame constants.
        st: (N_STATE,) the controller's state (S_* slots), advanced.
        t: time [s].
        q: (n,) configuration [x_b, y_b, θ_b, q_m].
        dq: (n,) commanded velocities.
        xd: (3,) desired position [m].
        dxd: (3,) desired velocity [m/s].
        ddxd: (3,) desired acceleration [m/s²].
        x: (3,) the kinematics' end-effector position [m], written.
        ddq: (n,) joint accelerations, written.
        rec: (4,) the tick's record (R_* slots), written.

    Returns:
        OK, or SINGULAR (nothing of the state advanced).
    """
    n = q.shape[0]
    J6 = np.empty((6, n))
    drift, ddx = np.empty(3), np.empty(3)
    point_terms(ints, joints, fc, q, dq, x, J6, drift)
    for r in range(3):
        v = 0.0
        for i in range(n):
            v += J6[r, i] * dq[i]
        ddx[r] = ddxd[r] + prm[P_KD] * (dxd[r] - v) + prm[P_KP] * (xd[r] - x[r])
    lo, hi = np.empty(n), np.empty(n)
    acceleration_bounds(q, dq, bnd, prm[P_DT], lo, hi)
    grad, hvp = np.empty(n - 3), np.empty(n - 3)
    sigma, ok = det_terms(J6, dq[3:], grad, hvp)
    if not ok:
        return SINGULAR
    ddq_A = np.zeros(n)
    g1, g2 = prm[P_G1], prm[P_G2]
    for i in range(n - 3):
        ddq_A[3 + i] = g1 * hvp[i] + g2 * (g1 * grad[i] - dq[3 + i])
    if kind == AMD:
        _amd(prm, st, t, dq, J6, drift, ddx, lo, hi, ddq_A, sigma, ddq, rec)
    elif not _pinv(prm, st, J6, drift, ddx, lo, hi, ddq_A, ddq, rec):
        return SINGULAR
    return OK
