"""Compiled handle kinematics for the simulation loop: x and ẋ of the end-effector from the encoders.

What a haptic rendering loop computes before its controller runs (the virtual environment's
input): forward kinematics of a tree of one-DoF revolute/prismatic joints packed by
`rhi.chain_kernel.pack`, the end-effector point p and its velocity ṗ = Σ_j J_j θ̇_j over the
joints j supporting the frame, with the linear Jacobian column J_j = ω_j × (p − o_j) for a
revolute joint and ω_j for a prismatic one (ω_j = R_j a_j the joint's world axis, o_j its
origin). The same recursion as `rhi.chain_kernel` (Pinocchio's conventions), without the
inertias, the Jacobian's angular rows or the dynamics. Imported by `rhi.sim.loop.Kinematics`,
not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import numpy as np

from rhi.terms_kernel import _jit

#: columns of `pack`'s per-joint constants used here: placement rotation (9), translation (3), axis (3)
_P, _T, _AX = 0, 9, 12


@_jit
def handle_state(ints, joints, fc, q, dq, out):
    """Write the end-effector position and velocity on the task rows at motor state (q, q̇) into `out`.

    Args:
        ints: (2 nθ + 1 + m,) int64: `pack`'s integer constants, then the task rows (world axes).
        joints: (nθ, 29) `pack`'s per-joint constants.
        fc: (12 + nθ + nθ n,) the frame placement (`pack`'s consts[:12]), the actuation offset b
            (nθ,) [rad or m] and the actuation map A (nθ, n) row-major: θ = A q + b.
        q: (n,) motor positions [rad].
        dq: (n,) motor velocities [rad/s].
        out: (2, m) output: the end-effector position [m], then its velocity [m/s].
    """
    nt, n, m = joints.shape[0], q.shape[0], out.shape[1]
    oR = np.empty((nt, 3, 3))
    o = np.empty((nt, 3))
    RP = np.empty((3, 3))
    T = np.empty((3, 3))
    for j in range(nt):
        th = fc[12 + j]
        for k in range(n):
            th += fc[12 + nt + j * n + k] * q[k]
        p = ints[j]
        row = joints[j]
        for r in range(3):  # R_p P_j and o_p + R_p t_j
            for c in range(3):
                if p >= 0:
                    RP[r, c] = oR[p, r, 0] * row[_P + c] + oR[p, r, 1] * row[_P + 3 + c] + oR[p, r, 2] * row[_P + 6 + c]
                else:
                    RP[r, c] = row[_P + 3 * r + c]
            if p >= 0:
                o[j, r] = o[p, r] + oR[p, r, 0] * row[_T] + oR[p, r, 1] * row[_T + 1] + oR[p, r, 2] * row[_T + 2]
            else:
                o[j, r] = row[_T + r]
        a0, a1, a2 = row[_AX], row[_AX + 1], row[_AX + 2]
        if ints[nt + j]:  # revolute: Rodrigues' rotation about the axis
            cq, sq = np.cos(th), np.sin(th)
            for r in range(3):
                for c in range(3):
                    T[r, c] = (1.0 - cq) * row[_AX + r] * row[_AX + c] + (cq if r == c else 0.0)
            T[0, 1] -= sq * a2
            T[1, 0] += sq * a2
            T[0, 2] += sq * a1
            T[2, 0] -= sq * a1
            T[1, 2] -= sq * a0
            T[2, 1] += sq * a0
            for r in range(3):
                for c in range(3):
                    oR[j, r, c] = RP[r, 0] * T[0, c] + RP[r, 1] * T[1, c] + RP[r, 2] * T[2, c]
        else:
            oR[j] = RP
            for r in range(3):
                o[j, r] += th * (RP[r, 0] * a0 + RP[r, 1] * a1 + RP[r, 2] * a2)
    f = ints[2 * nt]
    pt = np.empty(3)
    for r in range(3):
        pt[r] = fc[9 + r]
        if f >= 0:
            pt[r] = o[f, r] + oR[f, r, 0] * fc[9] + oR[f, r, 1] * fc[10] + oR[f, r, 2] * fc[11]
    v = np.zeros(3)
    j = f
    while j >= 0:  # the joints supporting the frame, from its own joint to the root
        dth = 0.0
        for k in range(n):
            dth += fc[12 + nt + j * n + k] * dq[k]
        R = oR[j]
        a0, a1, a2 = joints[j, _AX], joints[j, _AX + 1], joints[j, _AX + 2]
        w0 = R[0, 0] * a0 + R[0, 1] * a1 + R[0, 2] * a2
        w1 = R[1, 0] * a0 + R[1, 1] * a1 + R[1, 2] * a2
        w2 = R[2, 0] * a0 + R[2, 1] * a1 + R[2, 2] * a2
        if ints[nt + j]:  # ω × (p − o_j)
            d0, d1, d2 = pt[0] - o[j, 0], pt[1] - o[j, 1], pt[2] - o[j, 2]
            v[0] += (w1 * d2 - w2 * d1) * dth
            v[1] += (w2 * d0 - w0 * d2) * dth
            v[2] += (w0 * d1 - w1 * d0) * dth
        else:
            v[0] += w0 * dth
            v[1] += w1 * dth
            v[2] += w2 * dth
        j = ints[j]
    for i in range(m):
        r = ints[2 * nt + 1 + i]
        out[0, i] = pt[r]
        out[1, i] = v[r]
