"""Compiled kinematics of the mobile controllers' tick: the end-effector point, its Jacobian, drift and det-manipulability.

`point_terms` is what `rhi.control.mobile.WMMKinematics` asks Pinocchio for (the position, the 6-D
world-aligned Jacobian and the drift J̇q̇ of a serial chain), on `rhi.devices.batch.pack`'s constants; `sym3`
and `det_terms` are `rhi.control.mobile.kinematics`' closed forms. Their oracles are those Python functions
(equal to rounding, `tests/test_mobile_loop.py`). Imported by `rhi.control._compiled.mobile`.
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices._compiled.chain import joint_frame
from rhi.devices.batch import AXIS_COLUMN as _AX
from rhi.jit import jit


@jit(inline=True)
def point_terms(ints, joints, fc, q, dq, x, J6, drift):
    """End-effector position x (3,) [m], Jacobian J6 (6, n) [linear; angular] and drift J̇q̇ (3,) [m/s²], written.

    For a serial chain of one-DoF joints (joint j's parent is j − 1) whose coordinates are q: the linear
    column of joint j is ω_j × (x − o_j) (revolute) or ω_j (prismatic), with ω_j its world axis; the drift
    is Σ_t ((2 Σ_{s<t} a_s q̇_s + a_t q̇_t) × v_t) q̇_t (a, v: the angular and linear columns), the
    classical acceleration of the point at q̈ = 0.

    Args:
        ints: `pack`'s integer constants.
        joints: `pack`'s per-joint constants.
        fc: (≥ 12,) the frame placement in its joint (rotation (9), translation (3)).
        q: (n,) joint positions [rad or m].
        dq: (n,) joint velocities.
        x: (3,) output: the position.
        J6: (6, n) output: the Jacobian.
        drift: (3,) output: the drift.
    """
    nt = joints.shape[0]
    oR = np.empty((nt, 3, 3))
    o = np.empty((nt, 3))
    RP = np.empty((3, 3))
    T = np.empty((3, 3))
    for j in range(nt):
        joint_frame(ints, joints, j, q[j], oR, o, RP, T)
    f = ints[2 * nt]
    for r in range(3):
        x[r] = fc[9 + r]
        if f >= 0:
            x[r] = o[f, r] + oR[f, r, 0] * fc[9] + oR[f, r, 1] * fc[10] + oR[f, r, 2] * fc[11]
    J6[:, :] = 0.0
    w0 = w1 = w2 = 0.0  # Σ_{s<t} a_s q̇_s
    drift[:] = 0.0
    for j in range(f + 1):
        a0, a1, a2 = joints[j, _AX], joints[j, _AX + 1], joints[j, _AX + 2]
        u0 = oR[j, 0, 0] * a0 + oR[j, 0, 1] * a1 + oR[j, 0, 2] * a2
        u1 = oR[j, 1, 0] * a0 + oR[j, 1, 1] * a1 + oR[j, 1, 2] * a2
        u2 = oR[j, 2, 0] * a0 + oR[j, 2, 1] * a1 + oR[j, 2, 2] * a2
        if ints[nt + j]:
            d0, d1, d2 = x[0] - o[j, 0], x[1] - o[j, 1], x[2] - o[j, 2]
            v0, v1, v2 = u1 * d2 - u2 * d1, u2 * d0 - u0 * d2, u0 * d1 - u1 * d0
            J6[3, j], J6[4, j], J6[5, j] = u0, u1, u2
        else:
            v0, v1, v2 = u0, u1, u2
            u0 = u1 = u2 = 0.0
        J6[0, j], J6[1, j], J6[2, j] = v0, v1, v2
        qd = dq[j]
        c0, c1, c2 = 2.0 * w0 + u0 * qd, 2.0 * w1 + u1 * qd, 2.0 * w2 + u2 * qd
        drift[0] += (c1 * v2 - c2 * v1) * qd
        drift[1] += (c2 * v0 - c0 * v2) * qd
        drift[2] += (c0 * v1 - c1 * v0) * qd
        w0, w1, w2 = w0 + u0 * qd, w1 + u1 * qd, w2 + u2 * qd


@jit
def sym3(P, inv):
    """`rhi.control.mobile.kinematics.sym3`: (det, lmin, lmax, invertible) of a symmetric 3×3 P; inv (3, 3) written."""
    a, b, c, d, e, f = P[0, 0], P[0, 1], P[0, 2], P[1, 1], P[1, 2], P[2, 2]
    A0, A1, A2 = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * A0 + b * A1 + c * A2
    p1 = b * b + c * c + e * e
    qm = (a + d + f) / 3.0
    a_, d_, f_ = a - qm, d - qm, f - qm
    p2 = a_ * a_ + d_ * d_ + f_ * f_ + 2.0 * p1
    if p2 <= 1e-300:
        lmin = lmax = qm
    else:
        p = math.sqrt(p2 / 6.0)
        detB = (a_ * (d_ * f_ - e * e) - b * (b * f_ - e * c) + c * (b * e - d_ * c)) / p**3
        phi = math.acos(min(1.0, max(-1.0, 0.5 * detB))) / 3.0
        lmax = qm + 2.0 * p * math.cos(phi)
        lmin = qm + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    if not det > 0:
        return det, lmin, lmax, False
    B4, B5 = a * f - c * c, b * c - a * e
    inv[0, 0], inv[0, 1], inv[0, 2] = A0 / det, A1 / det, A2 / det
    inv[1, 0], inv[1, 1], inv[1, 2] = A1 / det, B4 / det, B5 / det
    inv[2, 0], inv[2, 1], inv[2, 2] = A2 / det, B5 / det, (a * d - b * b) / det
    return det, lmin, lmax, True


@jit
def gram(J, c0, c1, use, out):
    """Out (3, 3) = Σ J[:, i] J[:, i]ᵀ over the columns c0 ≤ i < c1 with use[i] (the rows of J: 3)."""
    for a in range(3):
        for b in range(3):
            s = 0.0
            for i in range(c0, c1):
                if use[i]:
                    s += J[a, i] * J[b, i]
            out[a, b] = s


@jit
def _cross(a0, a1, a2, b0, b1, b2):
    """A × b of two 3-vectors given by their components."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@jit(inline=True)
def det_terms(J6, dqm, grad, hvp):
    """`rhi.control.mobile.kinematics.det_terms` of the arm columns: ∇H, ∇²H q̇ written; (σ_min(J_m), invertible).

    Args:
        J6: (6, n) the Jacobian (`point_terms`); the arm's columns are the last m.
        dqm: (m,) arm joint velocities [rad/s].
        grad: (m,) ∇H, written.
        hvp: (m,) ∇²H q̇, written.

    Returns:
        (σ_min(J_m) [m/rad], False where J_m J_mᵀ is singular (grad and hvp then unwritten)).
    """
    m = dqm.shape[0]
    nb = J6.shape[1] - m
    V = J6[:3, nb:]
    A = J6[3:, nb:]
    C = np.empty((m, m, 3))  # C[s, t] = a_s × v_t (s ≤ t): ∂v_j/∂q_k = C[min, max]
    for s in range(m):
        for t in range(s, m):
            C[s, t, 0], C[s, t, 1], C[s, t, 2] = _cross(A[0, s], A[1, s], A[2, s], V[0, t], V[1, t], V[2, t])
    Jd = np.zeros((3, m))
    for j in range(m):
        for k in range(m):
            s, t = min(j, k), max(j, k)
            for r in range(3):
                Jd[r, j] += dqm[k] * C[s, t, r]
    om = np.zeros(3)
    ad = np.empty((m, 3))  # a_s × ω_s, ω_s = Σ_{l<s} a_l q̇_l
    for s in range(m):
        ad[s, 0], ad[s, 1], ad[s, 2] = _cross(A[0, s], A[1, s], A[2, s], om[0], om[1], om[2])
        for r in range(3):
            om[r] += A[r, s] * dqm[s]
    Cd = np.empty((m, m, 3))  # d/dt C[s, t] = a_s × J̇_t − (a_s × ω_s) × v_t
    for s in range(m):
        for t in range(s, m):
            c0, c1, c2 = _cross(A[0, s], A[1, s], A[2, s], Jd[0, t], Jd[1, t], Jd[2, t])
            u0, u1, u2 = _cross(ad[s, 0], ad[s, 1], ad[s, 2], V[0, t], V[1, t], V[2, t])
            Cd[s, t, 0], Cd[s, t, 1], Cd[s, t, 2] = c0 - u0, c1 - u1, c2 - u2
    Psi = np.empty((3, 3))
    G = np.empty((3, 3))
    gram(V, 0, m, np.ones(m, np.bool_), Psi)
    det, lam, _, ok = sym3(Psi, G)
    if not ok:
        return 0.0, False
    W = np.zeros((3, m))  # Ψ⁻¹J
    Pd = np.zeros((3, 3))  # Ψ̇ = J̇Jᵀ + JJ̇ᵀ
    for r in range(3):
        for j in range(m):
            for a in range(3):
                W[r, j] += G[r, a] * V[a, j]
                Pd[r, a] += Jd[r, j] * V[a, j] + V[r, j] * Jd[a, j]
    Wd = np.zeros((3, m))  # Ψ⁻¹(J̇ − Ψ̇ Ψ⁻¹J)
    E = Jd.copy()
    for r in range(3):
        for j in range(m):
            for a in range(3):
                E[r, j] -= Pd[r, a] * W[a, j]
    trd = 0.0
    for r in range(3):
        for a in range(3):
            trd += G[r, a] * Pd[r, a]
            for j in range(m):
                Wd[r, j] += G[r, a] * E[a, j]
    for k in range(m):
        gt, gd = 0.0, 0.0
        for j in range(m):
            s, t = min(j, k), max(j, k)
            for r in range(3):
                gt += C[s, t, r] * W[r, j]
                gd += C[s, t, r] * Wd[r, j] + Cd[s, t, r] * W[r, j]
        grad[k] = 2.0 * det * gt
        hvp[k] = 2.0 * det * (trd * gt + gd)
    return math.sqrt(max(lam, 0.0)), True
