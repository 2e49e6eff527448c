"""The intent estimators' tick in compiled code, for `rhi.sim`'s compiled loop (planar tasks, m = 2).

`update` is the `update` of `rhi.control.intent`'s `KnownIntent` (nothing), `FilteredIntent` (the
structure tensor, its principal axis and the hysteresis) and `HMMIntent` (the posterior over the motion
primitives and its principal axis), and a known direction along a polyline path (the reference's unit
velocity, kept while it rests; `rhi.experiments.beyond.intent.PathIntent`), with the 2 × 2 principal axis
in closed form instead of LAPACK's `eigh` (equal to rounding; its sign is set from the evidence, as in
Python). `desired` is the desired ellipsoid of u: M_des(u) of eq. 3.23 (`rhi.metrics.desired_vme`) or the
desired FMEs of eqs. 6.12–6.13 (`rhi.metrics.desired_fme`). The estimator's state travels in
one vector (`ST_*` slots after u), its settings in another (`P_*` slots).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.jit import jit

#: Estimator kinds.
KNOWN, FILTERED, HMM, PATH = 0, 1, 2, 3
#: Settings slots: evidence scales and threshold; FilteredIntent's filter step, hysteresis and cos(deadband);
#: HMMIntent's stay and jump probabilities and κ; the path's start [s] and speed [m/s].
P_FS, P_VS, P_MIN, P_A, P_ON, P_OFF, P_COS, P_STAY, P_JUMP, P_KAPPA, P_START, P_SPEED = range(12)
N_P = 12
#: The settings' names (`rhi.control.compiled.CompiledIntent.settings`), in slot order.
SETTINGS = ("force_scale", "speed_scale", "min_evidence", "a", "c_on", "c_off", "cos_deadband", "stay", "jump",
            "kappa", "start", "speed")
#: Kind codes by name.
KINDS = {"known": KNOWN, "filtered": FILTERED, "hmm": HMM, "path": PATH}
#: State slots after u (m): confidence, active (FilteredIntent), then the structure tensor T (m × m).
ST_CONF, ST_ACTIVE = 0, 1


@jit
def _principal(T):
    """(unit principal axis (2,), confidence (λ₁ − λ₂)/tr) of the symmetric 2 × 2 T, as `rhi.control.intent`."""
    a, b, c = T[0, 0], T[0, 1], T[1, 1]
    r = math.hypot(0.5 * (a - c), b)
    e = np.empty(2)
    if a >= c:
        e[0], e[1] = 0.5 * (a - c) + r, b
    else:
        e[0], e[1] = b, 0.5 * (c - a) + r
    s = math.sqrt(e[0] * e[0] + e[1] * e[1])
    if s == 0.0:  # isotropic: LAPACK's last eigenvector of a multiple of I
        e[0], e[1] = 0.0, 1.0
    else:
        e[0], e[1] = e[0] / s, e[1] / s
    tr = (0.5 * (a + c) - r) + (0.5 * (a + c) + r)
    return e, (2.0 * r / tr if tr > 0 else 0.0)


@jit
def update(kind, prm, table, knots, st, p, F, v, t):
    """One tick of the estimator: u = st[:m] and its state advanced in place from F_h (m,) [N], ẋ (m,) [m/s] at t [s].

    Args:
        kind: KNOWN, FILTERED, HMM or PATH.
        prm: (N_P,) settings (P_* slots).
        table: HMM: (k, m) the primitives; PATH: (segments, m) their velocities [m/s].
        knots: PATH: (segments + 1,) arc length at each waypoint [m].
        st: (m + 2 + m m,) u, then the ST_* slots.
        p: HMM: (k,) the posterior, advanced.
        F: (m,) the hand's force on the task axes [N].
        v: (m,) the handle velocity [m/s].
        t: time [s].
    """
    m = F.shape[0]
    if kind == KNOWN or not (math.isfinite(F[0] + F[1]) and math.isfinite(v[0] + v[1])):
        return  # `IntentController.step` updates on finite readings only
    if kind == PATH:
        if knots.shape[0] < 2 or t <= prm[P_START]:
            return
        d = (t - prm[P_START]) * prm[P_SPEED]
        if d >= knots[knots.shape[0] - 1]:
            return
        i = 0
        while knots[i + 1] <= d:  # the segment holding d (bisect_right − 1)
            i += 1
        n = 0.0
        for j in range(m):
            n += table[i, j] * table[i, j]
        n = math.sqrt(n)
        if n > 0:
            for j in range(m):
                st[j] = table[i, j] / n
        return
    d = np.empty(m)
    for j in range(m):
        d[j] = F[j] * (1.0 / prm[P_FS]) + v[j] * (1.0 / prm[P_VS])
    s = math.sqrt(d[0] * d[0] + d[1] * d[1])
    if not (s >= prm[P_MIN] and s > 0):
        return
    for j in range(m):
        d[j] = d[j] / s
    T = st[m + 2:m + 2 + m * m].reshape((m, m))
    if kind == FILTERED:
        a = prm[P_A]
        for i in range(m):
            for j in range(m):
                T[i, j] += a * (d[i] * d[j] - T[i, j])
        e, c = _principal(T)
        st[m + ST_CONF] = c
        if c >= prm[P_ON]:
            st[m + ST_ACTIVE] = 1.0
        elif c < prm[P_OFF]:
            st[m + ST_ACTIVE] = 0.0
        if st[m + ST_ACTIVE] != 0.0 and abs(e[0] * st[0] + e[1] * st[1]) < prm[P_COS]:
            sign = 1.0 if e[0] * d[0] + e[1] * d[1] >= 0 else -1.0
            st[0], st[1] = sign * e[0], sign * e[1]
        return
    total = 0.0  # HMM
    kappa = prm[P_KAPPA]
    for k in range(p.shape[0]):
        c = table[k, 0] * d[0] + table[k, 1] * d[1]
        p[k] = (prm[P_STAY] * p[k] + prm[P_JUMP]) * math.exp(kappa * (c * c - 1.0))
        total += p[k]
    scale = 1.0 / total
    S = np.zeros((2, 2))
    for k in range(p.shape[0]):
        p[k] = p[k] * scale
        for i in range(2):
            for j in range(2):
                S[i, j] += table[k, i] * p[k] * table[k, j]
    e, c = _principal(S)
    st[m + ST_CONF] = c
    sign = 1.0 if e[0] * d[0] + e[1] * d[1] >= 0 else -1.0
    st[0], st[1] = sign * e[0], sign * e[1]


@jit
def desired(u, along, across, D):
    """M(u) = a û ûᵀ + b (I − û ûᵀ) (û = u/‖u‖, a = `along`, b = `across`) into D (m, m).

    VME's M_des (eq. 3.23): a = 1, b = β; FME's M_Stiff^des (eq. 6.13): a = 𝒦, b = ζ; M_Free^des (eq. 6.12):
    a = ζ, b = 𝒦 (`rhi.metrics.desired_fme`).
    """
    m = u.shape[0]
    n = 0.0
    for i in range(m):
        n += u[i] * u[i]
    n = math.sqrt(n)
    for i in range(m):
        for j in range(m):
            uu = (u[i] / n) * (u[j] / n)
            D[i, j] = along * uu + across * ((1.0 if i == j else 0.0) - uu)
