"""The null-space controller's 1 kHz tick, compiled with Numba: one call per tick after the primary law.

`tick` computes steps 2–6 of `rhi.control.controller` (τ_m, the ASO volume V of eq. 6.14,
the FME transition of eqs. 6.15–6.19, the FME- and VME-matching gradients of eqs. 6.10 and
3.22, the allocation — none, simple scaling, ASCM (Algorithm 1) in projector form, or the
active-set method on ASCM's LP started at ASCM (`rhi.control.allocation.lp`) —, the
safety torque and the tertiary torque of Algorithm 2) on small arrays, without a Python
call in between. The readable composition of the same equations is
`rhi.control.reference`, the oracle this kernel is tested against (same torques to
1e-10 N m). Where the projector form cannot decide accurately (a held set with
σ_min(Z_𝒮) < 0.01, whose P[𝒮, 𝒮] = Z_𝒮 Z_𝒮ᵀ squares the condition number) the kernel
returns `FALLBACK` and the controller runs that tick through the reference; a held set of n − m
joints (Z_𝒮 square, no redundancy left) is decided with a basis of P instead.

Numba is imported by `rhi.control`, not by ``import rhi``; the compiled code is cached on
disk (`cache=True`), so only the first use on a machine pays the compilation.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from numba import typeof, types

from rhi.control._compiled.allocation import (
    allocate_scaling,
    any_nonzero,
    any_true,
    ascm_into,
    basis,
    blocks_all,
    clip_to,
    held_into,
    held_set,
    held_torque,
    null_projector,
    safety_room,
    square_rank,
    tertiary,
    tertiary_to,
    well_conditioned,
)
from rhi.control._compiled.lp import active_set, active_set_result, active_set_start
from rhi.control._compiled.tank import TK_GATE, TK_ON, TK_THETA, _null, blend, direction, gate, gated, null_inertia
from rhi.devices._compiled.terms import add, axpy, dot, inv as _inv, inv_to, mm, mtv, mv, shaped, sub
from rhi.jit import KernelRef, jit, stack_empty

#: Status of `tick`.
OK, FALLBACK, SINGULAR = 0, 1, 2
#: Saturation codes of `tick`.
NONE, SCALING, ASCM, ACTIVE_SET = 0, 1, 2, 3
#: Indices of the parameter vector of `tick`.
P_DAMPING, P_ASO_S, P_GRAVITY, P_DYNAMIC, P_SATURATION, P_SAFE, P_CLIPPED = range(7)
N_PARAMS = 7
#: Head slots of the FME-schedule vector of `tick` (empty: no schedule): its gain, ‖M_Free − M_Stiff‖_F,
#: ε₁, ε₂, ρ [s]; then the torque weights 1/T_i² (n), M_Free (m × m), M_Stiff (m × m) (`schedule_vector`).
SCH_GAIN, SCH_DIST, SCH_EPS1, SCH_EPS2, SCH_RHO = range(5)
N_SCH = 5


def schedule_vector(gain: float, w2: np.ndarray, free: np.ndarray, stiff: np.ndarray,
                    schedule: tuple[float, float, float, float]) -> np.ndarray:
    """The FME-schedule vector of `tick` for a compiled "fme_schedule" objective (`rhi.control.compiled`).

    Args:
        gain: its step β [N m] (eq. 6.6).
        w2: (n,) torque weights 1/T_i² [1/(N m)²].
        free: (m, m) M_Free^des.
        stiff: (m, m) M_Stiff^des.
        schedule: (‖M_Free − M_Stiff‖_F, ε₁, ε₂, ρ [s]).
    """
    return np.ascontiguousarray(np.concatenate([np.array([gain, *schedule], dtype=float), w2, free.ravel(),
                                                stiff.ravel()]), dtype=np.float64)


Flags = tuple[int, bool, bool, bool, bool, bool]


def ascm_ref(lo: np.ndarray, hi: np.ndarray, sat: np.ndarray) -> KernelRef:
    """`ascm_into` as `tick` calls it (its ``ascm_at``) for a controller's torque limits (n,) and held joints (n,) bool.

    Compiled (or loaded) at its first call or `KernelRef.resolve`, not here: a tick can be compiled meanwhile
    (`rhi.control._compiled.whole`: aside, in a child) without ASCM's code, and a tick that never allocates by
    ASCM never compiles it.
    """
    vec = types.float64[::1]  # a, b and τ (on the tick's stack), then P
    return _ascm_ref((vec, vec, types.float64[:, ::1], typeof(lo), typeof(hi), types.intp, typeof(sat), vec))


@functools.cache
def _ascm_ref(args: tuple) -> KernelRef:
    return KernelRef(ascm_into, args, types.Tuple((types.float64, types.boolean, types.boolean)))


def flags(prm: np.ndarray, sch: np.ndarray, vme_gain: np.ndarray, tank: np.ndarray) -> Flags:
    """`tick`'s last six arguments from its settings: (code, scheduled, vme, safe, clipped_null, tank_on)."""
    return (int(prm[P_SATURATION]), sch.shape[0] != 0, vme_gain.shape[0] != 0, bool(prm[P_SAFE] != 0.0),
            bool(prm[P_CLIPPED] != 0.0), bool(tank[TK_ON] != 0.0))


@jit
def _contract(Y, dJ):
    """Σ_ij Y_ij ∂J_ij/∂q_k: (n,) for Y: (m, n), dJ: (m, n, n)."""
    out = np.empty(Y.shape[1])
    _contract_to(Y, dJ, out)
    return out


@jit
def _contract_to(Y, dJ, out):
    """`_contract` written into out (n,)."""
    m, n = Y.shape
    for k in range(n):
        out[k] = 0.0
    for i in range(m):
        for j in range(n):
            y = Y[i, j]
            for k in range(n):
                out[k] += y * dJ[i, j, k]


@jit
def vme_gradient(D, J, dJ):
    """∂/∂q of JBLD(D, JJᵀ) (eq. 3.22): 2 Σ (G J)_ij ∂J_ij/∂q_k, G = ½((D + JJᵀ)/2)⁻¹ − ½(JJᵀ)⁻¹. (n,)."""
    m = J.shape[0]
    M = mm(J, J.T)
    H = np.empty((m, m))
    for i in range(m):  # loops, not array expressions: less code to compile
        for j in range(m):
            H[i, j] = 0.5 * (D[i, j] + M[i, j])
    G = _inv(H)
    Minv = _inv(M)
    for i in range(m):
        for j in range(m):
            G[i, j] = G[i, j] - Minv[i, j]
    return _contract(mm(G, J), dJ)


@jit
def fme_gradient(D, J, dJ, w2, out):
    """∂/∂q of JBLD(M̂, D), M̂ = (J W² Jᵀ)⁻¹ (eqs. 6.9–6.10): −2 Σ (Hᵀ J W²)_ij ∂J_ij/∂q_k, written into out (n,)."""
    m, n = J.shape
    Jw, A, T = stack_empty((m, n), np.float64), stack_empty((m, m), np.float64), stack_empty((m, m), np.float64)
    K = stack_empty((m, n), np.float64)
    for i in range(m):  # scalar loops into a few arrays: no temporary per product
        for j in range(n):
            Jw[i, j] = J[i, j] * w2[j]
    for i in range(m):
        for j in range(m):
            s = 0.0
            for l in range(n):
                s += Jw[i, l] * J[j, l]
            A[i, j] = s
    Mh, G = stack_empty((m, m), np.float64), stack_empty((m, m), np.float64)
    inv_to(A, Mh)
    for i in range(m):
        for j in range(m):
            T[i, j] = 0.5 * (Mh[i, j] + D[i, j])
    inv_to(T, G)
    for i in range(m):
        for j in range(m):
            G[i, j] = 0.5 * (G[i, j] - A[i, j])
    for i in range(m):  # H = M̂ G M̂ (in A)
        for j in range(m):
            s = 0.0
            for l in range(m):
                s += Mh[i, l] * G[l, j]
            T[i, j] = s
    for i in range(m):
        for j in range(m):
            s = 0.0
            for l in range(m):
                s += T[i, l] * Mh[l, j]
            A[i, j] = s
    for i in range(m):
        for j in range(n):
            s = 0.0
            for l in range(m):
                s += A[l, i] * Jw[l, j]
            K[i, j] = s
    _contract_to(K, dJ, out)
    for k in range(n):
        out[k] = -2.0 * out[k]


@jit
def _mv_to(A, v, out):
    """Write A v into out (k,) for A (k, n), v (n,): `rhi.devices._compiled.terms.mv`'s arithmetic, no allocation."""
    k, n = A.shape
    for i in range(k):
        s = 0.0
        for j in range(n):
            s += A[i, j] * v[j]
        out[i] = s


@jit
def dynamic_null(J, Jsharp, t, out):
    """Write t − Jᵀ (J#ᵀ t) into out (n,): the part of the torque t (n,) that puts no force at the handle [N m]."""
    m, n = J.shape
    for j in range(n):
        w = 0.0
        for i in range(m):
            u = 0.0
            for c in range(n):
                u += Jsharp[c, i] * t[c]
            w += J[i, j] * u
        out[j] = t[j] - w


@jit
def _clip1(v, lo, hi):
    """The scalar v clipped to [lo, hi] (NaN stays NaN), as `rhi.control._compiled.allocation.clip`."""
    if v < lo:
        v = lo
    if v > hi:
        v = hi
    return v


@jit
def aso_volume(tau, lo, hi, S):
    """The actuator saturation observer V ∈ [0, 1] of eq. 6.14 (0 on or outside the box)."""
    prod = 1.0
    n = tau.shape[0]
    for i in range(n):
        t = tau[i]
        if t >= hi[i] or t <= lo[i]:
            return 0.0
        prod *= (hi[i] - t) * (t - lo[i]) / (hi[i] - lo[i]) ** 2
    v = -math.expm1(-S * prod) / -math.expm1(-S / 4.0**n)
    return min(max(v, 0.0), 1.0)


@jit
def _omega(tr, t):
    """Ω(t) of the transition state tr = (stiff, Ω_start, t0, tf) (eqs. 6.17, 6.18)."""
    target = 0.0 if tr[0] != 0.0 else 1.0
    if t >= tr[3] or tr[3] <= tr[2]:
        return target
    s = max(0.0, (t - tr[2]) / (tr[3] - tr[2]))
    return target + (tr[1] - target) * 0.5 * (1.0 + math.cos(math.pi * s))


@jit(inline=True)
def allocate(code, V, a, b, tau_m, P, lo, hi, r, sat, out, ascm_at):
    """The allocation strategy `code` of τ_m = a + b (n,) [N m] in the box [lo, hi]: (ok, τ, α, clipped).

    `ascm_at` is `rhi.control._compiled.allocation.ascm_into`, or it by address (`ascm_ref`: a caller compiled
    without its code, e.g. while another process compiles it).

    ASCM and the active set keep τ_m while the ASO volume V > 0 (P, the null-space projector, is read only where
    they act); ok is False where the reference must decide (the LP). sat (n,) is written with the held joints, out
    (n,) with τ by ASCM and without a strategy (τ is out there).
    Inlined: where `code` is a compile-time constant (`rhi.control._compiled.whole.whole_for`) only its strategy
    is compiled.
    """
    n = a.shape[0]
    if V > 0.0 and (code == ASCM or code == ACTIVE_SET):
        sat[:] = False
        return True, tau_m, 1.0, False
    if code == ASCM:
        alpha, clipped, ok = ascm_at(a, b, P, lo, hi, r, sat, out)
        return ok, out, alpha, clipped
    if code == ACTIVE_SET:
        tau, alpha, clipped = active_set_start(a, b, P, lo, hi, r, sat)
        if clipped or not any_nonzero(a):
            return False, tau, alpha, clipped  # the LP decides
        Z = basis(P, r)
        ok, alpha, y = active_set(a, b, Z, lo, hi, alpha, tau, sat, np.int64(50))  # int64, as from Python: one compile
        if not ok:
            return False, tau, alpha, clipped
        tau, alpha = active_set_result(alpha, y, a, b, Z, lo, hi, sat)
        return True, tau, alpha, clipped
    if code == SCALING:
        tau, alpha, clipped = allocate_scaling(a, b, lo, hi, sat)
        return True, tau, alpha, clipped
    for i in range(n):
        sat[i] = tau_m[i] > hi[i] or tau_m[i] < lo[i]
    clip_to(tau_m, lo, hi, out)
    return True, out, 1.0, False


@jit(inline=True)
def transition(tr, t, V, distance, eps1, eps2, rho):
    """Advance tr in place by one tick (hysteresis of eq. 6.15, then the cosine blend); returns Ω(t)."""
    stiff_now = tr[0] != 0.0
    stiff = (not V >= eps2) if stiff_now else V < eps1
    if stiff != stiff_now:
        om = _omega(tr, t)
        target = 0.0 if stiff else 1.0
        tr[0], tr[1], tr[2], tr[3] = (1.0 if stiff else 0.0), om, t, t + rho * distance * abs(target - om)
    return _omega(tr, t)


@jit(inline=True)
def tick(t, terms, at, F_r, F_x, q, dq, lo, hi, prm, tr, sch, vme_D, vme_gain, tau_s_extra, tau_to_extra, tank, tank_q,
         tank_e, tau_out, sat, ascm_at, code, scheduled, vme, safe, clipped_null, tank_on):
    """Steps 2–6 of one controller tick (see `rhi.control.controller`).

    The last six arguments say which parts the tick has (from the settings: `flags`). Where the caller passes
    compile-time constants (`rhi.control._compiled.whole.whole_for`), Numba prunes the other branches before
    typing them: a tick compiles only the strategy and objectives its controller uses.

    Args:
        t: time [s].
        terms: the device terms, flat (`rhi.devices._compiled.terms.task_terms`; at least the first nine).
        at: (≥ 9,) int64 start of each term in `terms` (`rhi.devices.terms.layout`).
        F_r: (m,) rendered (α-scaled) task force [N].
        F_x: (m,) extra task force (never scaled) [N].
        q: (n,) joint positions [rad] (read by the null-space energy tank).
        dq: (n,) joint velocities [rad/s].
        lo: (n,) lower torque limits [N m].
        hi: (n,) upper torque limits [N m].
        prm: (N_PARAMS,) parameters (P_* indices).
        tr: (4,) FME transition state (stiff, Ω_start, t0, tf), advanced in place.
        sch: the FME schedule (SCH_* slots, `schedule_vector`), or empty without one.
        vme_D: (k, m, m) desired VMEs of the VME-matching objectives.
        vme_gain: (k,) their gradient steps.
        tau_s_extra: (n,) −Σ gain ∂ν_lim/∂q of the joint-limit barriers [N m].
        tau_to_extra: (n,) −Σ gain ∂ν/∂q of the objectives computed outside the kernel [N m].
        tank: (N_TANK,) the null-space energy tank's settings and state (`rhi.control._compiled.tank`), advanced.
        tank_q: (n,) its q of the previous tick, written.
        tank_e: (2, n) its metered torques (objectives, allocation) of the previous tick, written.
        tau_out: (n,) the torque, written [N m].
        sat: (n,) bool, the held joints, written.
        ascm_at: ASCM's kernel, by address (`ascm_ref`; called where code is ASCM).
        code: the allocation (NONE, SCALING, ASCM, ACTIVE_SET; = prm[P_SATURATION]).
        scheduled: there is an FME schedule (sch not empty).
        vme: there are VME-matching objectives (vme_gain not empty).
        safe: the safety torque of the held joints is kept (= prm[P_SAFE] != 0).
        clipped_null: null_space="clipped" (= prm[P_CLIPPED] != 0).
        tank_on: the null-space energy tank runs (= tank[TK_ON] != 0).

    Returns:
        (status, α, β, V, Ω, clipped).
    """
    n, m = dq.shape[0], F_r.shape[0]
    J = shaped(terms[at[0]:at[0] + m * n], (m, n))
    dJ = shaped(terms[at[1]:at[1] + m * n * n], (m, n, n))
    g = terms[at[3]:at[3] + n]
    JMinv = shaped(terms[at[5]:at[5] + m * n], (m, n))
    Jsharp = shaped(terms[at[7]:at[7] + n * m], (n, m))
    Gx = terms[at[8]:at[8] + m]
    gravity = prm[P_GRAVITY] != 0.0 and dot(g, g) != 0.0
    a, b, tau_m = stack_empty(n, np.float64), stack_empty(n, np.float64), stack_empty(n, np.float64)
    tau_s, tau_to = stack_empty(n, np.float64), stack_empty(n, np.float64)
    for j in range(n):  # a = Jᵀ F_r, b = Jᵀ F_x (+ g − Jᵀ G_x), τ_m = a + b; scalar loops, no temporaries
        sa, sb, sg = 0.0, 0.0, 0.0
        for i in range(m):
            sa += J[i, j] * F_r[i]
            sb += J[i, j] * F_x[i]
            sg += J[i, j] * Gx[i]
        a[j] = sa
        b[j] = sb + (g[j] - sg) if gravity else sb
        tau_m[j] = sa + b[j]
        tau_s[j] = -prm[P_DAMPING] * dq[j] + tau_s_extra[j]
        tau_to[j] = tau_s[j]
    V = aso_volume(tau_m, lo, hi, prm[P_ASO_S])
    omega = 1.0
    if scheduled:
        omega = transition(tr, t, V, sch[SCH_DIST], sch[SCH_EPS1], sch[SCH_EPS2], sch[SCH_RHO])
        if sch[SCH_GAIN] > 0.0:
            w2 = sch[N_SCH:N_SCH + n]
            free = shaped(sch[N_SCH + n:N_SCH + n + m * m], (m, m))
            stiff = shaped(sch[N_SCH + n + m * m:N_SCH + n + 2 * m * m], (m, m))
            D = free
            if omega == 0.0:
                D = stiff
            elif omega != 1.0:
                D = stack_empty((m, m), np.float64)
                for i in range(m):
                    for j in range(m):
                        D[i, j] = omega * free[i, j] + (1.0 - omega) * stiff[i, j]
            grad = stack_empty(n, np.float64)
            fme_gradient(D, J, dJ, w2, grad)
            for i in range(n):
                tau_to[i] = -sch[SCH_GAIN] * grad[i] + tau_to[i]
    if vme:
        for k in range(vme_gain.shape[0]):
            grad = vme_gradient(vme_D[k], J, dJ)
            for i in range(n):
                tau_to[i] = -vme_gain[k] * grad[i] + tau_to[i]
    for i in range(n):
        tau_to[i] = tau_to[i] + tau_to_extra[i]
    r = n - m
    dynamic = prm[P_DYNAMIC] != 0.0
    have_P = False
    P, Ntau = stack_empty((n, n), np.float64), stack_empty(n, np.float64)  # local: on the stack
    for i in range(n):
        for j in range(n):
            P[i, j] = 1.0 if i == j else 0.0
    if dynamic:
        dynamic_null(J, Jsharp, tau_to, Ntau)
    else:
        ok = null_projector(J, P)
        if not ok:
            return SINGULAR, 1.0, 0.0, V, omega, False
        have_P = True
        _mv_to(P, tau_to, Ntau)
    if (code == ASCM or code == ACTIVE_SET) and not V > 0.0 and not have_P:
        ok = null_projector(JMinv, P)
        if not ok:
            return SINGULAR, 1.0, 0.0, V, omega, False
        have_P = True
    ok, tau, alpha, clipped = allocate(code, V, a, b, tau_m, P, lo, hi, r, sat, stack_empty(n, np.float64), ascm_at)
    if not ok:
        return FALLBACK, 1.0, 0.0, V, omega, False
    g_null = stack_empty(n, np.float64)
    g_null[:] = 0.0
    if prm[P_GRAVITY] != 0.0 and dot(g, g) != 0.0:
        g_null = sub(g, mtv(J, Gx))
    gate_on = tank_on and tank[TK_GATE] != 0.0
    if gate_on:  # the redistribution spends only what the allocation's account holds (rhi.control.tank)
        tank[TK_THETA] = 1.0
        if any_true(sat) and not clipped:
            Minv = shaped(terms[at[4]:at[4] + n * n], (n, n))
            theta = gate(tank, tank_q, tank_e, t, q, dq, Minv, sub(_null(J, Jsharp, tau, np.zeros(n)), g_null))
            tank[TK_THETA] = theta
            if theta < 1.0:
                tau, alpha = gated(theta, tau, alpha, a, b, lo, hi, sat)
    tau_alloc = tau
    gamma = 1.0
    if safe and any_true(sat):  # the safety torque the held joints would block
        if not have_P:
            ok = null_projector(JMinv, P)
            if not ok:
                return SINGULAR, 1.0, 0.0, V, omega, False
            have_P = True
        Nsafe, held, S = stack_empty(n, np.float64), stack_empty(n, np.float64), stack_empty(n, np.int64)
        if dynamic:
            dynamic_null(J, Jsharp, tau_s, Nsafe)
        else:
            _mv_to(P, tau_s, Nsafe)
        k = held_into(sat, S)
        if k >= r:  # no redundancy left (e.g. an LP vertex with more than r joints at a limit): all of it is held
            if not blocks_all(P, S, k, r) and (k != r or square_rank(basis(P, r), S, k) != 1):
                return FALLBACK, 1.0, 0.0, V, omega, False
            _mv_to(P, Nsafe, held)
        else:
            if not well_conditioned(P, S, k):
                return FALLBACK, 1.0, 0.0, V, omega, False
            rr = stack_empty(k, np.float64)
            for i in range(k):
                rr[i] = Nsafe[S[i]]
            held_torque(P, S, k, rr, held)
        if not clipped:
            tau, gamma = safety_room(tau, b, held, lo, hi, stack_empty(n, np.float64))
    if clipped_null:  # null_space="clipped": τ + N τ_to, each joint clipped at its limit (eqs. 6.2–6.6)
        for i in range(n):
            tau_out[i] = _clip1(tau[i] + Ntau[i], lo[i], hi[i])
        return OK, gamma * alpha, 1.0, V, omega, clipped
    if not have_P and any_true(sat):
        ok = null_projector(JMinv, P)
        if not ok:
            return SINGULAR, 1.0, 0.0, V, omega, False
    delta = stack_empty(n, np.float64)
    beta, ok = tertiary_to(tau, sat, P, tau_to, Ntau, lo, hi, r, delta)
    if not ok:
        return FALLBACK, 1.0, 0.0, V, omega, False
    if not tank_on:
        for i in range(n):
            tau_out[i] = _clip1(tau[i] + delta[i] if beta != 0.0 else tau[i], lo[i], hi[i])
        return OK, gamma * alpha, beta, V, omega, clipped
    tau1 = add(tau, delta) if beta != 0.0 else tau
    # the null-space energy tank (rhi.control.tank): the tick without the objectives, the damper's direction
    Nsafe = np.empty(n)
    if dynamic:
        dynamic_null(J, Jsharp, tau_s, Nsafe)
    else:
        Nsafe = mv(P, tau_s)
    delta0, beta0, ok = tertiary(tau, sat, P, tau_s, Nsafe, lo, hi, r)
    if not ok:
        return FALLBACK, 1.0, 0.0, V, omega, False
    S, k = held_set(sat)
    M = shaped(terms[at[2]:at[2] + n * n], (n, n))
    d = direction(null_inertia(J, Jsharp, M), dq, S, k, tau)
    Minv = shaped(terms[at[4]:at[4] + n * n], (n, n))
    tau_a = add(b, axpy(gamma, sub(tau_alloc, b), np.zeros(n))) if gate_on else tau  # the gate meters the redistribution
    blend(tank, tank_q, tank_e, t, q, dq, J, Jsharp, Minv, g_null, tau_a, add(tau, delta0) if beta0 != 0.0 else tau,
          tau1, d, lo, hi, tau_out)
    return OK, gamma * alpha, beta, V, omega, clipped
