"""The teleoperated slave in compiled code: `rhi.sim.Teleoperation.follow` for the compiled simulation loop.

`slave_torque` is the slave's Cartesian PD plus gravity compensation from its encoders and model
(τ_s = J_sᵀ (K_p (s R x_m + p − x_s) − K_d J_s q̇_s) + g_s(q_s)), with the slave's terms from
`rhi.devices._compiled.chain.chain_terms` instead of Pinocchio (equal to rounding), and its velocity
ellipsoid ˢM = J_s J_sᵀ (what `rhi.control.TMIMatching` reads); `slave_period` applies the torque and
runs the slave's physics steps (`rhi.sim.Plant.apply` and `step`). Imported by
`rhi.sim._compiled.fast_loop`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices._compiled.chain import chain_terms
from rhi.jit import jit
from rhi.sim.mjc import step1, step2


@jit
def slave_torque(ten, tenv, const, chain, at, x, buf, gains, R, p, x_master, tau, M):
    """The slave's torque for one control period and its ellipsoid ˢM at its current state; whether τ_s is finite.

    Args:
        ten: (n_s,) the slave's tendon lengths (MuJoCo's view; q_s = ten − const).
        tenv: (n_s,) their velocities q̇_s [rad/s].
        const: (n_s,) the encoder offsets (`rhi.sim.Plant`).
        chain: `chain_terms`' model arguments (ints, joints, consts, A, b, rows, armature, supports, identity).
        at: (≥ 4,) int64 term offsets in buf (`rhi.devices.terms.layout`).
        x: (m,) the slave's end-effector position [m], written.
        buf: the slave's terms, written.
        gains: (3,) K_p [N/m], K_d [N s/m], the motion scale s.
        R: (m, m) master → slave rotation.
        p: (m,) offset [m].
        x_master: (m,) the master's position [m].
        tau: (n_s,) the slave's torque [N m], written.
        M: (m, m) ˢM = J_s J_sᵀ, written.
    """
    ints, joints, consts, A, b, rows, armature, supports, identity = chain
    n, m = ten.shape[0], rows.shape[0]
    q, dq = np.empty(n), np.empty(n)
    for i in range(n):
        q[i], dq[i] = ten[i] - const[i], tenv[i]
    th = np.empty(A.shape[0])
    for j in range(A.shape[0]):
        t = 0.0
        for k in range(n):
            t += q[k] * A[j, k]
        th[j] = t + b[j]
    chain_terms(ints, joints, consts, th, A, rows, armature, supports, identity, dq, x, buf)
    J = buf[at[0]:at[0] + m * n].reshape((m, n))
    g = buf[at[3]:at[3] + n]
    kp, kd, s = gains[0], gains[1], gains[2]
    F = np.empty(m)
    for i in range(m):
        target, v = 0.0, 0.0
        for j in range(m):
            target += s * R[i, j] * x_master[j]
            M[i, j] = 0.0
            for k in range(n):
                M[i, j] += J[i, k] * J[j, k]
        for k in range(n):
            v += J[i, k] * dq[k]
        F[i] = kp * (target + p[i] - x[i]) - kd * v
    total = 0.0
    for k in range(n):
        t = 0.0
        for i in range(m):
            t += J[i, k] * F[i]
        t += g[k]
        tau[k] = t
        total += t * t
    return math.isfinite(total)


@jit
def slave_period(model, data, sub, ctrl, xfrc, tau, wn, bad):
    """Apply τ_s (no force on the handle) and run `sub` physics steps; -1, or the step MuJoCo flagged as diverged."""
    ctrl[:] = tau
    xfrc[:] = 0.0
    for s in range(sub):
        step2(model, data)
        step1(model, data)
        if wn[bad[0]] != 0 or wn[bad[1]] != 0 or wn[bad[2]] != 0:
            return s
    return -1
