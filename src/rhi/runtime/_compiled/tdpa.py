"""The TDPA's port controllers in compiled code: `rhi.runtime.tdpa`'s `book`, `damp` and `correct` on a port's slots.

A port's `rhi.runtime.tdpa.PortEnergy` is five slots of a float vector (`P_*`), the settings one vector
(`settings`); the same arithmetic as the Python functions (their reference). Imported by
`rhi.runtime._compiled.bilateral_loop`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices._compiled.terms import dot
from rhi.jit import jit

#: A port's slots (`rhi.runtime.tdpa.PortEnergy`): E_in, E_out, dissipated [J], gain, deficit [J].
P_IN, P_OUT, P_DISS, P_GAIN, P_DEF = range(5)
_EPS_V, _EPS_F = 1e-6, 1e-6  # as rhi.runtime.tdpa


@jit
def book(p, e):
    """`PortEnergy.book` on the port slots p: add the energy e the port put out over a sample [J]."""
    if e > 0:
        p[P_OUT] += e
    else:
        p[P_IN] -= e


@jit
def damp(p, F, v, mass, E_other, dt, cfg):
    """`rhi.runtime.tdpa.damp` on the port slots p: F (m,) [N] damped in place; cfg: `settings`."""
    p[P_GAIN], p[P_DEF] = 0.0, 0.0
    W = E_other - p[P_OUT] - max(dot(F, v), 0.0) * dt
    vv = dot(v, v)
    if W >= 0:
        return
    if vv <= _EPS_V**2:
        p[P_DEF] = -W
        return
    beta = min(-W / (dt * vv), cfg[2], 0.5 * mass / dt, cfg[1] / math.sqrt(vv))
    p[P_GAIN] = beta
    p[P_DISS] += beta * vv * dt
    p[P_DEF] = -W - beta * vv * dt
    for i in range(F.shape[0]):
        F[i] = F[i] - beta * v[i]


@jit
def correct(p, v, F_e, E_other, drift, dt, cfg):
    """`rhi.runtime.tdpa.correct` on the port slots p: the set-point velocity v (m,) [m/s] corrected in place."""
    p[P_GAIN], p[P_DEF] = 0.0, 0.0
    P = -dot(F_e, v)
    A = E_other - p[P_OUT]
    W = A - max(P, 0.0) * dt
    ff = dot(F_e, F_e)
    m = v.shape[0]
    if W < 0 and ff > _EPS_F**2:
        alpha = min(-W / (dt * ff), cfg[5] / math.sqrt(ff))
        p[P_GAIN] = alpha
        p[P_DISS] += alpha * ff * dt
        p[P_DEF] = -W - alpha * ff * dt
        for i in range(m):
            v[i] = v[i] + alpha * F_e[i]
        return
    if W < 0:
        p[P_DEF] = -W
        return
    dn = math.sqrt(dot(drift, drift))
    if cfg[3] == 0.0 or dn == 0.0:
        return
    g = min(cfg[3], cfg[4] / dn)
    cost = 0.0
    for i in range(m):
        cost -= F_e[i] * (-g * drift[i])
    s = 1.0 if cost <= 0 else min(1.0, max(0.0, (A / dt - P) / cost))
    for i in range(m):
        v[i] = v[i] + s * (-g * drift[i])


def settings(passivity) -> np.ndarray:
    """The kernels' cfg: the TDPA's settings (a `rhi.runtime.tdpa.TDPA`, or None: off) as one vector (6,).

    On (1/0), max force [N], max damping [N s/m], drift rate [1/s], max drift speed [m/s], max correction speed [m/s].
    """
    if passivity is None:
        return np.zeros(6)
    p = passivity
    return np.array([1.0, p.max_force, p.max_damping, p.drift_rate, p.max_drift_speed, p.max_correction_speed])
