"""The torque of one compiled tick by source: `rhi.control.reference.reference_tick`'s ``parts``, compiled.

`split` recomputes steps 2–6 of `rhi.control._compiled.step.tick` at a state the whole tick has just
run (its law forces, the tank's λ and μ of that tick) and writes the torque of each source, as the
reference's `_split` defines them: the task, the gravity compensation's null-space part, the
allocation's null-space torque, the safety torques' shares (damping, barrier), the tank's damper,
each null-space objective's share of Algorithm 2 and the box clip, summing to the clipped torque
before the passivity layer. Projector form, as the tick: equal to the reference to rounding; a held
set the projector form cannot decide returns `FALLBACK` (the caller then replays through the reference).
"""

from __future__ import annotations

import numpy as np

from rhi.control._compiled.allocation import (
    any_true,
    ascm_into,
    basis,
    blocks_all,
    clip,
    held_set,
    held_torque,
    null_projector,
    safety_room,
    square_rank,
    tertiary,
    well_conditioned,
)
from rhi.control._compiled.objectives import N_OBJ, OBJ_BARRIER, OBJ_FME, OBJ_ROWS, objectives
from rhi.control._compiled.step import (
    FALLBACK,
    OK,
    P_ASO_S,
    P_DAMPING,
    P_DYNAMIC,
    P_GRAVITY,
    P_SAFE,
    P_SATURATION,
    allocate,
    aso_volume,
    fme_gradient,
    vme_gradient,
)
from rhi.control._compiled.tank import direction, gated, null_inertia
from rhi.devices._compiled.terms import add, axpy, dot, mtv, mv, sub
from rhi.jit import jit

#: Rows of `split`'s output before the objectives; the box clip is the last row.
TASK, GRAVITY, ALLOCATION, DAMPING, BARRIER, TANK_DAMPER = range(6)
N_FIXED = 6


@jit
def _null(x, J, Jsharp, P, dynamic):
    """N x: x − JᵀJ#ᵀx (dynamic projector) or P x."""
    if dynamic:
        return sub(x, mtv(J, mtv(Jsharp, x)))
    return mv(P, x)


@jit
def _held(x, P, S, k, r):
    """The part of the null-space torque x that keeping the held joints S[:k] unchanged removes (`held_part`)."""
    if k == 0:
        return np.zeros(x.shape[0])
    if k >= r:
        return mv(P, x)
    rr, out = np.empty(k), np.empty(x.shape[0])
    for i in range(k):
        rr[i] = x[S[i]]
    held_torque(P, S, k, rr, out)
    return out


@jit
def split(q, dq, terms, at, F_r, F_x, lo, hi, prm, obj, vme_D, vme_gain, tank_on, lam, mu, theta, slot, out):
    """The tick's torque by source into out (N_FIXED + k + 1, n) [N m]; OK or FALLBACK.

    Args:
        q: (n,) joint positions [rad].
        dq: (n,) joint velocities [rad/s].
        terms: the device terms of the tick (`rhi.devices.terms.layout`).
        at: their offsets.
        F_r: (m,) the law's rendered force of the tick [N].
        F_x: (m,) its extra force [N].
        lo: (n,) lower torque limits [N m].
        hi: (n,) upper torque limits [N m].
        prm: the tick's parameters (`rhi.control._compiled.step` P_* slots; no scheduled objective, null_space="scaled").
        obj: the static FME-matching objectives and barriers (`rhi.control._compiled.objectives.pack`).
        vme_D: (k_v, m, m) desired VMEs of the VME-matching objectives.
        vme_gain: (k_v,) their gradient steps.
        tank_on: whether the null-space energy tank ran.
        lam: the tank's λ of the tick.
        mu: its allocation damper's rate α of the tick [1/s].
        theta: its gate θ on ASCM's redistribution of the tick (1: none, `rhi.control.tank.redistribution_gate`).
        slot: (k,) int64, objective i's push: static FME terms first (their order in obj), then the VME terms.
        out: rows task, gravity, allocation, damping, barrier, tank damper, objective 0 … k − 1, box clip; written.
    """
    n, m = dq.shape[0], F_r.shape[0]
    r = n - m
    J = terms[at[0]:at[0] + m * n].reshape((m, n))
    dJ = terms[at[1]:at[1] + m * n * n].reshape((m, n, n))
    g = terms[at[3]:at[3] + n]
    JMinv = terms[at[5]:at[5] + m * n].reshape((m, n))
    Jsharp = terms[at[7]:at[7] + n * m].reshape((n, m))
    Gx = terms[at[8]:at[8] + m]
    bar, fme_sum = np.zeros(n), np.zeros(n)  # as `rhi.control._compiled.whole.whole_for`'s tick
    if obj[OBJ_FME] != 0.0 or obj[OBJ_BARRIER] != 0.0:
        objectives(obj, q, dq, J, dJ, bar, fme_sum)
    a = mtv(J, F_r)
    b = mtv(J, F_x)
    g_null = np.zeros(n)
    if prm[P_GRAVITY] != 0.0 and dot(g, g) != 0.0:
        g_null = sub(g, mtv(J, Gx))
        b = add(b, g_null)
    tau_m = add(a, b)
    V = aso_volume(tau_m, lo, hi, prm[P_ASO_S])
    damp = axpy(-prm[P_DAMPING], dq, np.zeros(n))
    tau_s = axpy(-prm[P_DAMPING], dq, bar)
    tau_to = tau_s
    kf = int(obj[OBJ_FME])
    pushes = np.zeros((kf + vme_gain.shape[0], n))
    for i in range(vme_gain.shape[0]):
        grad = vme_gradient(vme_D[i], J, dJ)
        tau_to = axpy(-vme_gain[i], grad, tau_to)
        pushes[kf + i] = axpy(-vme_gain[i], grad, np.zeros(n))
    tau_to = add(tau_to, fme_sum)
    o = N_OBJ + int(obj[OBJ_ROWS]) * (n + 2)
    for i in range(kf):
        grad = np.empty(n)
        fme_gradient(obj[o + 1 + n:o + 1 + n + m * m].reshape((m, m)), J, dJ, obj[o + 1:o + 1 + n], grad)
        for j in range(n):
            pushes[i, j] = -(obj[o] * grad[j])
        o += 1 + n + m * m
    dynamic = prm[P_DYNAMIC] != 0.0
    P = np.empty((n, n))
    ok = null_projector(JMinv if dynamic else J, P)
    if not ok:
        return FALLBACK
    sat = np.zeros(n, np.bool_)
    ok, tau, alpha, clipped = allocate(prm[P_SATURATION], V, a, b, tau_m, P, lo, hi, r, sat, np.empty(n), ascm_into)
    if not ok:
        return FALLBACK
    if theta < 1.0 and any_true(sat) and not clipped:
        tau, alpha = gated(theta, tau, alpha, a, b, lo, hi, sat)
    S, k = held_set(sat)
    if k >= r and k > 0:
        if not blocks_all(P, S, k, r) and (k != r or square_rank(basis(P, r), S, k) != 1):
            return FALLBACK
    elif k > 0 and not well_conditioned(P, S, k):
        return FALLBACK
    al0 = tau
    gamma = 1.0
    if prm[P_SAFE] != 0.0 and k > 0 and not clipped:
        tau, gamma = safety_room(tau, b, _held(_null(tau_s, J, Jsharp, P, dynamic), P, S, k, r), lo, hi, np.empty(n))
    delta, beta, ok = tertiary(tau, sat, P, tau_to, _null(tau_to, J, Jsharp, P, dynamic), lo, hi, r)
    if not ok:
        return FALLBACK
    tau1 = add(tau, delta) if beta != 0.0 else tau
    beta0, d = beta, np.zeros(n)
    final = clip(tau1, lo, hi)
    if tank_on != 0.0:
        delta0, beta0, ok = tertiary(tau, sat, P, tau_s, _null(tau_s, J, Jsharp, P, dynamic), lo, hi, r)
        if not ok:
            return FALLBACK
        d = direction(null_inertia(J, Jsharp, terms[at[2]:at[2] + n * n].reshape((n, n))), dq, S, k, tau)
        tau0 = add(tau, delta0) if beta0 != 0.0 else tau
        diff = sub(tau1, tau0)
        base = axpy(-mu, d, tau0) if mu != 0.0 else tau0
        for i in range(n):
            final[i] = min(max(base[i] + lam * diff[i], lo[i]), hi[i])
    else:
        lam, mu = 1.0, 0.0
    beta_s, beta_o = (1.0 - lam) * beta0 + lam * beta, lam * beta
    inf = np.full(n, np.inf)
    held = sub(sub(tau, b), axpy(gamma, sub(al0, b), np.zeros(n)))  # the safety torque the held joints would block
    hd = _held(_null(damp, J, Jsharp, P, dynamic), P, S, k, r)
    hb = _held(_null(bar, J, Jsharp, P, dynamic), P, S, k, r)
    h = add(hd, hb)
    hh = dot(h, h)
    kk = dot(held, h) / hh if hh > 0.0 else 0.0
    sd, _, ok1 = tertiary(tau, sat, P, damp, _null(damp, J, Jsharp, P, dynamic), -inf, inf, r)
    sb, _, ok2 = tertiary(tau, sat, P, bar, _null(bar, J, Jsharp, P, dynamic), -inf, inf, r)
    if not (ok1 and ok2):
        return FALLBACK
    ga = gamma * alpha
    for i in range(n):
        out[TASK, i] = ga * a[i] + b[i] - g_null[i]
        out[GRAVITY, i] = g_null[i]
        out[ALLOCATION, i] = gamma * (al0[i] - alpha * a[i] - b[i]) + (held[i] - kk * h[i])
        out[DAMPING, i] = kk * hd[i] + beta_s * sd[i]
        out[BARRIER, i] = kk * hb[i] + beta_s * sb[i]
        out[TANK_DAMPER, i] = -mu * d[i]
    for j in range(slot.shape[0]):
        x = pushes[slot[j]]
        sx, _, ok = tertiary(tau, sat, P, x, _null(x, J, Jsharp, P, dynamic), -inf, inf, r)
        if not ok:
            return FALLBACK
        for i in range(n):
            out[N_FIXED + j, i] = beta_o * sx[i]
    last = out.shape[0] - 1
    for i in range(n):
        s = 0.0
        for j in range(last):
            s += out[j, i]
        out[last, i] = final[i] - s
    return OK
