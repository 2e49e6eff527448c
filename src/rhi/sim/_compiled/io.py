"""Compiled per-tick input and output of the simulation loop: the plant's sensors in, the log row out.

`sensors` reads the encoders and the F/T sensor of `rhi.sim.Plant` (the same arithmetic as
`Plant.q`, `Plant.dq` and `Plant.ft`) and `log_row` writes the array block of a log row (q, q̇,
τ, x, ẋ, F_h, F_e, F/T, see `rhi.sim.log.layout`), each in one call instead of a dozen small
NumPy operations. Imported by `rhi.sim.loop.simulate`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

from rhi.jit import jit


@jit
def sensors(ten, tenv, sd, R, c, adr, out):
    """Write q (n,) [rad], q̇ (n,) [rad/s] and the tared F/T reading (6,) [N, N m] into out (2 n + 6,).

    Args:
        ten: MuJoCo's tendon lengths (the first n: the motors' coordinates).
        tenv: the tendon velocities.
        sd: MuJoCo's sensordata.
        R: (9,) the handle site's orientation, row-major.
        c: (n + 3,) the encoders' offsets [rad] (q = length − offset), then the handle's weight (3,) [N].
        adr: (2,) int64: sensordata addresses of the F/T sensor's force and torque.
        out: (2 n + 6,) output.
    """
    n = out.shape[0] // 2 - 3
    for i in range(n):
        out[i] = ten[i] - c[i]
        out[n + i] = tenv[i]
    f, t = adr[0], adr[1]
    fx, fy, fz, tx, ty, tz = sd[f], sd[f + 1], sd[f + 2], sd[t], sd[t + 1], sd[t + 2]
    o = 2 * n
    for r in range(3):  # −R f − weight and −R t: the force and torque the hand applies, in world axes
        out[o + r] = -(R[3 * r] * fx + R[3 * r + 1] * fy + R[3 * r + 2] * fz) - c[n + r]
        out[o + 3 + r] = -(R[3 * r] * tx + R[3 * r + 1] * ty + R[3 * r + 2] * tz)


@jit
def log_row(row, start, read, tau, sd, idx, F_hand, F_env):
    """Write q, q̇, τ, x, ẋ, F_h, F_e and the F/T reading into row[start:] (`rhi.sim.log.layout` order).

    Args:
        row: the log row.
        start: where q starts in it.
        read: (2 n + 6,) q, q̇ and the F/T reading (`sensors`).
        tau: (n,) torques [N m].
        sd: MuJoCo's sensordata.
        idx: (2 m,) int64: the handle position's and velocity's sensordata indices.
        F_hand: (m,) the hand's force [N].
        F_env: (m,) the virtual environment's force [N].
    """
    n, m = tau.shape[0], F_hand.shape[0]
    k = start
    for i in range(2 * n):
        row[k + i] = read[i]
    k += 2 * n
    for i in range(n):
        row[k + i] = tau[i]
    k += n
    for i in range(2 * m):
        row[k + i] = sd[idx[i]]
    k += 2 * m
    for i in range(m):
        row[k + i] = F_hand[i]
        row[k + m + i] = F_env[i]
    k += 2 * m
    for i in range(6):
        row[k + i] = read[2 * n + i]
