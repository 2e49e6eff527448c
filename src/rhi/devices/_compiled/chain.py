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

from rhi.devices._compiled.terms import shaped, task_terms
from rhi.devices.batch import _ARM, _AX, _COM, _MASS, _P, _ROT, _T
from rhi.jit import jit, stack_empty


@jit(inline=True)
def joint_frame(ints, joints, j, th, oR, o, RP, T):
    """Orientation oR[j] and origin o[j] of chain joint j's frame at its coordinate th [rad or m], in place.

    Its parent's (ints[j], −1: the world) must be written already. RP and T: (3, 3) scratch. Scalar indexing
    throughout: no array views (each would be a reference count, an atomic operation, per use).
    """
    nt = joints.shape[0]
    p = ints[j]
    for r in range(3):  # R_p P_j and o_p + R_p t_j
        for c in range(3):
            if p >= 0:
                RP[r, c] = (oR[p, r, 0] * joints[j, _P + c] + oR[p, r, 1] * joints[j, _P + 3 + c]
                            + oR[p, r, 2] * joints[j, _P + 6 + c])
            else:
                RP[r, c] = joints[j, _P + 3 * r + c]
        if p >= 0:
            o[j, r] = (o[p, r] + oR[p, r, 0] * joints[j, _T] + oR[p, r, 1] * joints[j, _T + 1]
                       + oR[p, r, 2] * joints[j, _T + 2])
        else:
            o[j, r] = joints[j, _T + r]
    a0, a1, a2 = joints[j, _AX], joints[j, _AX + 1], joints[j, _AX + 2]
    if ints[nt + j]:  # revolute: Rodrigues' rotation about the axis
        cq, sq = np.cos(th), np.sin(th)
        for r in range(3):
            for c in range(3):
                T[r, c] = (1.0 - cq) * joints[j, _AX + r] * joints[j, _AX + c] + (cq if r == c else 0.0)
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


@jit(inline=True)
def _forward(ints, joints, th, oR, o, S, Ic, RP, T):
    """Forward kinematics and composite inertias of one configuration, written in place.

    Args:
        ints: the model's integer constants (`rhi.devices.batch.pack`).
        joints: its per-joint constants.
        th: (nθ,) chain coordinates [rad or m].
        oR: (nθ, 3, 3) joint frames' orientations.
        o: (nθ, 3) joint frames' origins [m].
        S: (nθ, 6) joint spatial axes about the world origin.
        Ic: (nθ, 6, 6) composite (subtree) spatial inertias about the world origin.
        RP: (3, 3) scratch.
        T: (3, 3) scratch.
    """
    nt = th.shape[0]
    for j in range(nt):
        joint_frame(ints, joints, j, th[j], oR, o, RP, T)
        a0, a1, a2 = joints[j, _AX], joints[j, _AX + 1], joints[j, _AX + 2]
        w0 = oR[j, 0, 0] * a0 + oR[j, 0, 1] * a1 + oR[j, 0, 2] * a2
        w1 = oR[j, 1, 0] * a0 + oR[j, 1, 1] * a1 + oR[j, 1, 2] * a2
        w2 = oR[j, 2, 0] * a0 + oR[j, 2, 1] * a1 + oR[j, 2, 2] * a2
        if ints[nt + j]:  # (o × ω, ω)
            S[j, 0] = o[j, 1] * w2 - o[j, 2] * w1
            S[j, 1] = o[j, 2] * w0 - o[j, 0] * w2
            S[j, 2] = o[j, 0] * w1 - o[j, 1] * w0
            S[j, 3], S[j, 4], S[j, 5] = w0, w1, w2
        else:  # (ω, 0)
            S[j, 0], S[j, 1], S[j, 2] = w0, w1, w2
            S[j, 3], S[j, 4], S[j, 5] = 0.0, 0.0, 0.0
        # body inertia about the origin: mass m at c, rotational inertia R I Rᵀ about c
        m = joints[j, _MASS]
        c0 = o[j, 0] + oR[j, 0, 0] * joints[j, _COM] + oR[j, 0, 1] * joints[j, _COM + 1] + oR[j, 0, 2] * joints[j, _COM + 2]
        c1 = o[j, 1] + oR[j, 1, 0] * joints[j, _COM] + oR[j, 1, 1] * joints[j, _COM + 1] + oR[j, 1, 2] * joints[j, _COM + 2]
        c2 = o[j, 2] + oR[j, 2, 0] * joints[j, _COM] + oR[j, 2, 1] * joints[j, _COM + 1] + oR[j, 2, 2] * joints[j, _COM + 2]
        for r in range(3):
            for k in range(3):
                T[r, k] = (oR[j, r, 0] * joints[j, _ROT + k] + oR[j, r, 1] * joints[j, _ROT + 3 + k]
                           + oR[j, r, 2] * joints[j, _ROT + 6 + k])
        for r in range(6):
            for k in range(6):
                Ic[j, r, k] = 0.0
        cc = c0 * c0 + c1 * c1 + c2 * c2
        for r in range(3):
            Ic[j, r, r] = m
            cr = c0 if r == 0 else c1 if r == 1 else c2
            for k in range(3):
                ck = c0 if k == 0 else c1 if k == 1 else c2
                Ic[j, 3 + r, 3 + k] = T[r, 0] * oR[j, k, 0] + T[r, 1] * oR[j, k, 1] + T[r, 2] * oR[j, k, 2] - m * cr * ck
            Ic[j, 3 + r, 3 + r] += m * cc
        mc0, mc1, mc2 = m * c0, m * c1, m * c2  # m [c]× below, −m [c]× above the diagonal
        Ic[j, 4, 0], Ic[j, 5, 0], Ic[j, 3, 1], Ic[j, 5, 1], Ic[j, 3, 2], Ic[j, 4, 2] = mc2, -mc1, -mc2, mc0, mc1, -mc0
        Ic[j, 0, 4], Ic[j, 0, 5], Ic[j, 1, 3], Ic[j, 1, 5], Ic[j, 2, 3], Ic[j, 2, 4] = mc2, -mc1, -mc2, mc0, mc1, -mc0
    for j in range(nt - 1, 0, -1):  # composite inertias (parents precede their children)
        p = ints[j]
        if p >= 0:
            for r in range(6):
                for k in range(6):
                    Ic[p, r, k] += Ic[j, r, k]


@jit(inline=True)
def _take(w, pos, size):
    """(w[pos:pos + size], pos + size): the next part of a work vector."""
    return w[pos:pos + size], pos + size


@jit(inline=True)
def work_size(nt):
    """Floats of `chain_dynamics`' work vector for a chain of nt joints."""
    return 67 * nt + 21 + 20 * nt * nt + nt * nt * nt


@jit
def chain_dynamics(ints, joints, consts, th, dth):
    """x, J6, M_θ, g_θ, C_θ of one state (views of one new work vector; `chain_dynamics_in` on a given one)."""
    return chain_dynamics_in(ints, joints, consts, th, dth, np.empty(work_size(th.shape[0])))


@jit(inline=True)
def chain_dynamics_in(ints, joints, consts, th, dth, w):
    """x, J6, M_θ, g_θ, C_θ of one state, as views of the work vector w (`work_size` floats).

    Args:
        ints: the model's integer constants (`rhi.devices.batch.pack`).
        joints: its per-joint constants.
        consts: its frame and gravity constants.
        th: (nθ,) chain coordinates [rad or m].
        dth: (nθ,) chain velocities [rad/s or m/s].
        w: the work vector every result and scratch array is a view of.

    Returns:
        p (3,) end-effector position [m], J6 (6, nθ) frame Jacobian (LOCAL_WORLD_ALIGNED, linear rows
        first), M (nθ, nθ) inertia incl. the model's armature [kg m²], g (nθ,) gravity torque [N m],
        C (nθ, nθ) Coriolis matrix (C θ̇ [N m]).
    """
    nt = th.shape[0]
    # every float array below is a view of the one work vector (one allocation, or none: `chain_terms`)
    oR, p = _take(w, 0, 9 * nt)
    o, p = _take(w, p, 3 * nt)
    S, p = _take(w, p, 6 * nt)
    Ic, p = _take(w, p, 36 * nt)
    RP, p = _take(w, p, 9)
    T, p = _take(w, p, 9)
    pt, p = _take(w, p, 3)
    J6, p = _take(w, p, 6 * nt)
    F, p = _take(w, p, 6 * nt)  # F_k = I^c_k S_k
    M, p = _take(w, p, nt * nt)
    g, p = _take(w, p, nt)
    X, p = _take(w, p, 6 * nt * nt)  # X[i, j] = S_i × S_j
    Y, p = _take(w, p, 6 * nt * nt)  # Y[i, k] = I^c_i S_k
    Z, p = _take(w, p, 6 * nt * nt)  # Z[i, k] = I^c_i (S_i × S_k)
    D, p = _take(w, p, nt * nt * nt)  # ∂M_jk/∂θ_i (D[i, j, k])
    C, p = _take(w, p, nt * nt)
    oR, o, S, Ic = shaped(oR, (nt, 3, 3)), shaped(o, (nt, 3)), shaped(S, (nt, 6)), shaped(Ic, (nt, 6, 6))
    RP, T, J6, F, M = shaped(RP, (3, 3)), shaped(T, (3, 3)), shaped(J6, (6, nt)), shaped(F, (nt, 6)), shaped(M, (nt, nt))
    X, Y, Z = shaped(X, (nt, nt, 6)), shaped(Y, (nt, nt, 6)), shaped(Z, (nt, nt, 6))
    D, C = shaped(D, (nt, nt, nt)), shaped(C, (nt, nt))
    _forward(ints, joints, th, oR, o, S, Ic, RP, T)
    sup = stack_empty((nt, nt), np.bool_)  # sup[a, b]: joint a supports joint b (or is b)
    sup[:, :] = False
    for j in range(nt):
        k = j
        while k >= 0:
            sup[k, j] = True
            k = ints[k]
    # end-effector point and frame Jacobian
    f = ints[2 * nt]
    for r in range(3):
        pt[r] = consts[9 + r]
        if f >= 0:
            pt[r] = o[f, r] + oR[f, r, 0] * consts[9] + oR[f, r, 1] * consts[10] + oR[f, r, 2] * consts[11]
    J6[:, :] = 0.0
    for j in range(nt):
        if f >= 0 and sup[j, f]:
            J6[0, j] = S[j, 0] + (S[j, 4] * pt[2] - S[j, 5] * pt[1])
            J6[1, j] = S[j, 1] + (S[j, 5] * pt[0] - S[j, 3] * pt[2])
            J6[2, j] = S[j, 2] + (S[j, 3] * pt[1] - S[j, 4] * pt[0])
            for r in range(3):
                J6[3 + r, j] = S[j, 3 + r]
    # CRBA and gravity
    M[:, :] = 0.0
    for k in range(nt):
        for r in range(6):
            s = 0.0
            for c in range(6):
                s += Ic[k, r, c] * S[k, c]
            F[k, r] = s
        s = 0.0
        for r in range(6):
            s += S[k, r] * (Ic[k, r, 0] * consts[12] + Ic[k, r, 1] * consts[13] + Ic[k, r, 2] * consts[14])
        g[k] = -s
        for j in range(k + 1):
            if sup[j, k]:
                s = 0.0
                for r in range(6):
                    s += S[j, r] * F[k, r]
                M[j, k] = M[k, j] = s
        M[k, k] += joints[k, _ARM]
    # ∂M_jk/∂θ_i for j supporting k, mirrored
    for i in range(nt):
        for j in range(nt):
            s0, s1, s2, s3, s4, s5 = S[i, 0], S[i, 1], S[i, 2], S[i, 3], S[i, 4], S[i, 5]
            t0, t1, t2, t3, t4, t5 = S[j, 0], S[j, 1], S[j, 2], S[j, 3], S[j, 4], S[j, 5]
            X[i, j, 0] = s4 * t2 - s5 * t1 + s1 * t5 - s2 * t4
            X[i, j, 1] = s5 * t0 - s3 * t2 + s2 * t3 - s0 * t5
            X[i, j, 2] = s3 * t1 - s4 * t0 + s0 * t4 - s1 * t3
            X[i, j, 3] = s4 * t5 - s5 * t4
            X[i, j, 4] = s5 * t3 - s3 * t5
            X[i, j, 5] = s3 * t4 - s4 * t3
            if sup[j, i] and j != i:  # only k strictly supporting i is used below
                for r in range(6):
                    s = 0.0
                    for c in range(6):
                        s += Ic[i, r, c] * S[j, c]
                    Y[i, j, r] = s
                for r in range(6):
                    s = 0.0
                    for c in range(6):
                        s += Ic[i, r, c] * X[i, j, c]
                    Z[i, j, r] = s
    D[:, :, :] = 0.0
    for k in range(nt):
        for j in range(k + 1):
            if not sup[j, k]:
                continue
            for i in range(nt):
                if sup[i, j]:
                    continue
                if sup[i, k]:
                    s = 0.0
                    for r in range(6):
                        s += X[i, j, r] * F[k, r]
                    d = -s
                elif sup[k, i]:
                    s = 0.0
                    for r in range(6):
                        s += X[i, j, r] * Y[i, k, r]
                    s2 = 0.0
                    for r in range(6):
                        s2 += S[j, r] * Z[i, k, r]
                    d = -s - s2
                else:
                    continue
                D[i, j, k] = D[i, k, j] = d
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
    nt, n = A.shape
    dth = stack_empty(nt, np.float64)
    for i in range(nt):
        s = 0.0
        for j in range(n):
            s += A[i, j] * dq[j]
        dth[i] = s
    w = stack_empty(work_size(nt), np.float64)  # the terms are read here: on this call's stack
    pt, J6, Mt, gt, Ct = chain_dynamics_in(ints, joints, consts, th, dth, w)
    for i in range(rows.shape[0]):
        x[i] = pt[rows[i]]
    task_terms(J6, Mt, gt, Ct, A, rows, armature, supports, identity, False, dq, out)
