"""Compiled chain dynamics behind `Device.terms`: Pinocchio's per-state terms for trees of one-DoF joints.

For a kinematic tree of one-DoF revolute and prismatic joints (`rhi.devices.batch.supported`),
`chain_terms` computes at one chain configuration θ and velocity θ̇ what `Device.terms`
otherwise asks Pinocchio for (forward kinematics, the 6-D frame Jacobian, CRBA, generalized
gravity and the Coriolis matrix), then calls `rhi.devices._compiled.terms.task_terms` on them: one
compiled call per state, no per-algorithm Python/boost overhead. Spatial algebra about
the world origin, (linear, angular) ordering as in Pinocchio:

* forward kinematics: R_j = R_p(j) P_j Rot(a_j, θ_j), o_j = o_p(j) + R_p(j) t_j (+ θ_j R_j a_j
  for a prismatic joint); the world joint axis is ω_j = R_j a_j;
* joint spatial axes S_j = (o_j × ω_j, ω_j) (revolute) or (ω_j, 0) (prismatic);
* frame Jacobian at the end-effector point p (LOCAL_WORLD_ALIGNED): (S_v,j + S_ω,j × p, S_ω,j)
  for j supporting the frame's joint;
* CRBA M_jk = S_jᵀ I^c_k S_k for j supporting k (I^c_k: subtree inertia about the origin),
  plus the model's armature; gravity g_j = −S_jᵀ I^c_j (g₀, 0);
* Coriolis matrix of the Christoffel symbols, C_jk = Σ_i ½(∂_i M_jk + ∂_k M_ji − ∂_j M_ik) θ̇_i
  (what Pinocchio's computeCoriolisMatrix returns), with ∂M/∂θ in closed form: the subtree of
  joint i moves with twist S_i, so for j supporting k, ∂_i M_jk = 0 if i supports j,
  −(S_i × S_j)ᵀ I^c_k S_k if i lies on the path from j (excluded) to k, and
  −(S_i × S_j)ᵀ I^c_i S_k − S_jᵀ I^c_i (S_i × S_k) if k supports i (i ≠ k).

The model constants are packed once by `rhi.devices.batch.pack` (a `Device`'s `_fast_maps`). Numba is imported
with this module, on the first `Device.terms` call, not with ``import rhi``.
"""

from __future__ import annotations

import numpy as np

from rhi.devices._compiled.terms import dot, task_terms
from rhi.devices.batch import _ARM, _AX, _COM, _MASS, _P, _ROT, _T
from rhi.jit import jit


@jit
def _cross(a, b, out):
    """Write a × b for 3-vectors a, b into out."""
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@jit
def _motion_cross(s, t, out):
    """Write s × t, the spatial motion cross product of (linear, angular) 6-vectors, into out."""
    out[0] = s[4] * t[2] - s[5] * t[1] + s[1] * t[5] - s[2] * t[4]
    out[1] = s[5] * t[0] - s[3] * t[2] + s[2] * t[3] - s[0] * t[5]
    out[2] = s[3] * t[1] - s[4] * t[0] + s[0] * t[4] - s[1] * t[3]
    out[3] = s[4] * t[5] - s[5] * t[4]
    out[4] = s[5] * t[3] - s[3] * t[5]
    out[5] = s[3] * t[4] - s[4] * t[3]


@jit
def _mv(A, v, out):
    """Write A v into out."""
    for i in range(A.shape[0]):
        s = 0.0
        for j in range(A.shape[1]):
            s += A[i, j] * v[j]
        out[i] = s


@jit
def joint_frame(ints, joints, j, th, oR, o, RP, T):
    """Orientation oR[j] and origin o[j] of chain joint j's frame at its coordinate th [rad or m], in place.

    Its parent's (ints[j], −1: the world) must be written already. RP and T: (3, 3) scratch.
    """
    nt = joints.shape[0]
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
        for r in range(3):
            for c in range(3):
                oR[j, r, c] = RP[r, c]
            o[j, r] += th * (RP[r, 0] * a0 + RP[r, 1] * a1 + RP[r, 2] * a2)


@jit
def _forward(ints, joints, th, oR, o, S, Ic):
    """Forward kinematics and composite inertias of one configuration, written in place.

    Args:
        ints: the model's integer constants (`rhi.devices.batch.pack`).
        joints: its per-joint constants.
        th: (nθ,) chain coordinates [rad or m].
        oR: (nθ, 3, 3) joint frames' orientations.
        o: (nθ, 3) joint frames' origins [m].
        S: (nθ, 6) joint spatial axes about the world origin.
        Ic: (nθ, 6, 6) composite (subtree) spatial inertias about the world origin.
    """
    nt = th.shape[0]
    RP = np.empty((3, 3))
    T = np.empty((3, 3))
    com = np.empty(3)
    for j in range(nt):
        joint_frame(ints, joints, j, th[j], oR, o, RP, T)
        row = joints[j]
        a0, a1, a2 = row[_AX], row[_AX + 1], row[_AX + 2]
        R = oR[j]
        w = S[j, 3:]
        for r in range(3):
            w[r] = R[r, 0] * a0 + R[r, 1] * a1 + R[r, 2] * a2
        if ints[nt + j]:
            _cross(o[j], w, S[j, :3])
        else:
            for r in range(3):
                S[j, r], S[j, 3 + r] = w[r], 0.0
        # body inertia about the origin: mass m at c, rotational inertia R I Rᵀ about c
        m = row[_MASS]
        for r in range(3):
            com[r] = o[j, r] + R[r, 0] * row[_COM] + R[r, 1] * row[_COM + 1] + R[r, 2] * row[_COM + 2]
        for r in range(3):
            for k in range(3):
                T[r, k] = R[r, 0] * row[_ROT + k] + R[r, 1] * row[_ROT + 3 + k] + R[r, 2] * row[_ROT + 6 + k]
        I = Ic[j]
        I[:, :] = 0.0
        for r in range(3):
            I[r, r] = m
            for k in range(3):
                I[3 + r, 3 + k] = T[r, 0] * R[k, 0] + T[r, 1] * R[k, 1] + T[r, 2] * R[k, 2] - m * com[r] * com[k]
            I[3 + r, 3 + r] += m * (com[0] * com[0] + com[1] * com[1] + com[2] * com[2])
        mc0, mc1, mc2 = m * com[0], m * com[1], m * com[2]  # m [c]× below, −m [c]× above the diagonal
        I[4, 0], I[5, 0], I[3, 1], I[5, 1], I[3, 2], I[4, 2] = mc2, -mc1, -mc2, mc0, mc1, -mc0
        I[0, 4], I[0, 5], I[1, 3], I[1, 5], I[2, 3], I[2, 4] = mc2, -mc1, -mc2, mc0, mc1, -mc0
    for j in range(nt - 1, 0, -1):  # composite inertias (parents precede their children)
        p = ints[j]
        if p >= 0:
            for r in range(6):
                for k in range(6):
                    Ic[p, r, k] += Ic[j, r, k]


@jit(inline=True)
def chain_dynamics(ints, joints, consts, th, dth):
    """x, J6, M_θ, g_θ, C_θ of one state.

    Args:
        ints: the model's integer constants (`rhi.devices.batch.pack`).
        joints: its per-joint constants.
        consts: its frame and gravity constants.
        th: (nθ,) chain coordinates [rad or m].
        dth: (nθ,) chain velocities [rad/s or m/s].

    Returns:
        p (3,) end-effector position [m], J6 (6, nθ) frame Jacobian (LOCAL_WORLD_ALIGNED, linear rows
        first), M (nθ, nθ) inertia incl. the model's armature [kg m²], g (nθ,) gravity torque [N m],
        C (nθ, nθ) Coriolis matrix (C θ̇ [N m]).
    """
    nt = th.shape[0]
    oR = np.empty((nt, 3, 3))
    o = np.empty((nt, 3))
    S = np.empty((nt, 6))
    Ic = np.empty((nt, 6, 6))
    _forward(ints, joints, th, oR, o, S, Ic)
    sup = np.zeros((nt, nt), dtype=np.bool_)  # sup[a, b]: joint a supports joint b (or is b)
    for j in range(nt):
        k = j
        while k >= 0:
            sup[k, j] = True
            k = ints[k]
    # end-effector point and frame Jacobian
    f = ints[2 * nt]
    pt = consts[9:12].copy()
    if f >= 0:
        for r in range(3):
            pt[r] = o[f, r] + oR[f, r, 0] * consts[9] + oR[f, r, 1] * consts[10] + oR[f, r, 2] * consts[11]
    J6 = np.zeros((6, nt))
    v = np.empty(3)
    for j in range(nt):
        if f >= 0 and sup[j, f]:
            _cross(S[j, 3:], pt, v)
            for r in range(3):
                J6[r, j] = S[j, r] + v[r]
                J6[3 + r, j] = S[j, 3 + r]
    # CRBA and gravity
    F = np.empty((nt, 6))  # F_k = I^c_k S_k
    M = np.zeros((nt, nt))
    g = np.empty(nt)
    for k in range(nt):
        _mv(Ic[k], S[k], F[k])
        I = Ic[k]
        s = 0.0
        for r in range(6):
            s += S[k, r] * (I[r, 0] * consts[12] + I[r, 1] * consts[13] + I[r, 2] * consts[14])
        g[k] = -s
        for j in range(k + 1):
            if sup[j, k]:
                M[j, k] = M[k, j] = dot(S[j], F[k])
        M[k, k] += joints[k, _ARM]
    # ∂M_jk/∂θ_i (D[i, j, k]) for j supporting k, mirrored
    X = np.empty((nt, nt, 6))  # X[i, j] = S_i × S_j
    Y = np.empty((nt, nt, 6))  # Y[i, k] = I^c_i S_k
    Z = np.empty((nt, nt, 6))  # Z[i, k] = I^c_i (S_i × S_k)
    for i in range(nt):
        for j in range(nt):
            _motion_cross(S[i], S[j], X[i, j])
            if sup[j, i] and j != i:  # only k strictly supporting i is used below
                _mv(Ic[i], S[j], Y[i, j])
                _mv(Ic[i], X[i, j], Z[i, j])
    D = np.zeros((nt, nt, nt))
    for k in range(nt):
        for j in range(k + 1):
            if not sup[j, k]:
                continue
            for i in range(nt):
                if sup[i, j]:
                    continue
                if sup[i, k]:
                    d = -dot(X[i, j], F[k])
                elif sup[k, i]:
                    d = -dot(X[i, j], Y[i, k]) - dot(S[j], Z[i, k])
                else:
                    continue
                D[i, j, k] = D[i, k, j] = d
    C = np.empty((nt, nt))
    for j in range(nt):
        for k in range(nt):
            s = 0.0
            for i in range(nt):
                s += (D[i, j, k] + D[k, j, i] - D[j, i, k]) * dth[i]
            C[j, k] = 0.5 * s
    return pt, J6, M, g, C


@jit
def chain_terms(ints, joints, consts, th, A, rows, armature, supports, identity, dq, x, out):
    """`chain_dynamics` then `rhi.devices._compiled.terms.task_terms`: every term of one state in one call.

    Args:
        ints: the model's integer constants (`rhi.devices.batch.pack`).
        joints: its per-joint constants.
        consts: its frame and gravity constants.
        th: (nθ,) chain coordinates θ = A q + b.
        A: (nθ, n) actuation map.
        rows: (m,) task rows (world axes).
        armature: (n,) rotor inertia [kg m²].
        supports: (nθ, nθ) bool, [j, k]: chain joint k supports joint j (or is j).
        identity: A is the identity.
        dq: (n,) joint velocities [rad/s].
        x: (m,) output, the end-effector position on the task rows [m].
        out: flat float64 output of `task_terms`.
    """
    dth = np.empty(A.shape[0])
    _mv(A, dq, dth)
    pt, J6, Mt, gt, Ct = chain_dynamics(ints, joints, consts, th, dth)
    for i in range(rows.shape[0]):
        x[i] = pt[rows[i]]
    task_terms(J6, Mt, gt, Ct, A, rows, armature, supports, identity, False, dq, out)
