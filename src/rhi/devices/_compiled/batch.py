"""Compiled loop behind `rhi.devices.batch`: x, J, ∂J/∂q, M and g of many configurations in blocks.

`evaluate` walks the batch in blocks of `BLOCK` configurations. Inside a block every
quantity is stored with the configuration index last, so each step of the spatial algebra
is one short contiguous loop the compiler turns into SIMD instructions, and each product
with a model constant that is exactly zero is skipped by a test outside that loop (joint
axes and placements of real arms are mostly axis-aligned). The work arrays are allocated
once per call and stay in cache; each block's terms are written straight into the
batch-first outputs.

Constants come from `rhi.devices.batch.BatchChain`: every joint j has an internal frame
F_j = R_j U_j whose z axis is its joint axis, and, with chain coordinates θ = A q + b,

* F_j = F_p(j) G_j Rot_z(θ_j + ψ_j) (revolute) or F_p(j) G_j (prismatic), o_j = o_p(j) + F_p(j) t_j
  (+ θ_j F_j e_z for a prismatic joint); the world joint axis is ω_j = F_j e_z;
* joint spatial axes about the world origin S_j = (ω_j, v_j), v_j = o_j × ω_j (revolute) or
  (0, ω_j) (prismatic);
* end-effector point Jacobian J_j = v_j + ω_j × p for j on the path to the frame's joint;
* ∂J_j/∂θ_k = ω_min(j,k) × J_max(j,k) on the path (the position Hessian, symmetric in j, k);
* composite rigid bodies about the origin (mass m^c_k, first moment h_k, inertia I^c_k):
  M_jk = ω_jᵀ(I^c_k ω_k + h_k × v_k) + v_jᵀ(m^c_k v_k + ω_k × h_k) for j supporting k, plus the
  model's armature; g_j = −ω_jᵀ(h_j × g₀) − m^c_j v_jᵀ g₀;
* motor coordinates: J_q = J_θ A, ∂J_q/∂q contracts ∂J_θ/∂θ with A on both joint axes,
  M_q = Aᵀ M_θ A + diag(armature), g_q = Aᵀ g_θ.

Numba is imported with this module, on the first batched call, not with ``import rhi``.
"""

from __future__ import annotations

import numpy as np

from rhi.jit import jit

#: configurations per block: the block's work arrays (a few 10 kB for 7 joints) stay in the L1/L2 cache
BLOCK = 32


@jit
def _forward(parent, revolute, G, psi, t, th, nb, F, o, v, cs, sn):
    """Internal frames F (nθ, 3 columns, 3, K), origins o (nθ, 3, K) [m], linear axes v (nθ, 3, K)."""
    d3 = t.shape[1]  # 3, a run-time trip count: no full unrolling of the loops around the SIMD loops
    for j in range(parent.shape[0]):
        par = parent[j]
        if par < 0:
            for col in range(d3):
                for r in range(d3):
                    for b in range(nb):
                        F[j, col, r, b] = G[j, r, col]
            for r in range(d3):
                for b in range(nb):
                    o[j, r, b] = t[j, r]
        else:
            for col in range(d3):
                for r in range(d3):
                    for b in range(nb):
                        F[j, col, r, b] = 0.0
                    for k in range(d3):
                        gk = G[j, k, col]
                        if gk != 0.0:
                            for b in range(nb):
                                F[j, col, r, b] += gk * F[par, k, r, b]
            for r in range(d3):
                for b in range(nb):
                    o[j, r, b] = o[par, r, b]
                for k in range(d3):
                    tk = t[j, k]
                    if tk != 0.0:
                        for b in range(nb):
                            o[j, r, b] += tk * F[par, k, r, b]
        if revolute[j]:
            for b in range(nb):
                cs[b] = np.cos(th[j, b] + psi[j])
                sn[b] = np.sin(th[j, b] + psi[j])
            for r in range(d3):
                for b in range(nb):
                    a0, a1 = F[j, 0, r, b], F[j, 1, r, b]
                    F[j, 0, r, b] = cs[b] * a0 + sn[b] * a1
                    F[j, 1, r, b] = cs[b] * a1 - sn[b] * a0
            for r in range(d3):
                y, z = (r + 1) % 3, (r + 2) % 3
                for b in range(nb):
                    v[j, r, b] = o[j, y, b] * F[j, 2, z, b] - o[j, z, b] * F[j, 2, y, b]
        else:
            for r in range(d3):
                for b in range(nb):
                    o[j, r, b] += th[j, b] * F[j, 2, r, b]
                    v[j, r, b] = F[j, 2, r, b]


@jit
def _composite(parent, mass, lever, inertia, F, o, nb, with_inertia, h, Ic, c, FI):
    """Subtree first moments h (nθ, 3, K) [kg m] and, if asked, inertias about the origin Ic (nθ, 6, K).

    Ic holds the upper triangle xx, xy, xz, yy, yz, zz [kg m²]; c (3, K) and FI (3, 3, K) are work arrays.
    """
    d3 = lever.shape[1]
    nt = parent.shape[0]
    for j in range(nt):
        m = mass[j]
        for r in range(d3):
            for b in range(nb):
                c[r, b] = o[j, r, b]
            for col in range(d3):
                lc = lever[j, col]
                if lc != 0.0:
                    for b in range(nb):
                        c[r, b] += lc * F[j, col, r, b]
            for b in range(nb):
                h[j, r, b] = m * c[r, b]
        if not with_inertia:
            continue
        for col in range(d3):  # columns of F I (I in the internal frame)
            for r in range(d3):
                for b in range(nb):
                    FI[col, r, b] = 0.0
                for k in range(d3):
                    ik = inertia[j, k, col]
                    if ik != 0.0:
                        for b in range(nb):
                            FI[col, r, b] += ik * F[j, k, r, b]
        e = 0
        for x in range(d3):  # F I Fᵀ + m (|c|² E − c cᵀ)
            for y in range(x, d3):
                for b in range(nb):
                    Ic[j, e, b] = (FI[0, x, b] * F[j, 0, y, b] + FI[1, x, b] * F[j, 1, y, b]
                                   + FI[2, x, b] * F[j, 2, y, b] - m * c[x, b] * c[y, b])
                if x == y:
                    for b in range(nb):
                        Ic[j, e, b] += m * (c[0, b] * c[0, b] + c[1, b] * c[1, b] + c[2, b] * c[2, b])
                e += 1
    for j in range(nt - 1, 0, -1):  # children come after their parent
        par = parent[j]
        if par >= 0:
            for r in range(d3):
                for b in range(nb):
                    h[par, r, b] += h[j, r, b]
            if with_inertia:
                for e in range(6):
                    for b in range(nb):
                        Ic[par, e, b] += Ic[j, e, b]


@jit
def _mass(revolute, mass_c, arm_t, sup, F, v, h, Ic, nb, Mt, Hk, Lk):
    """M_θ (nθ, nθ, K) [kg m²] by the composite-rigid-body algorithm; Hk, Lk (3, K) work arrays."""
    d3 = v.shape[1]
    nt = revolute.shape[0]
    for k in range(nt):
        mk = mass_c[k]
        for r in range(d3):  # H = I^c ω + h × v (angular), L = m^c v + ω × h (linear), per unit θ̇_k
            y, z = (r + 1) % 3, (r + 2) % 3
            for b in range(nb):
                Hk[r, b] = h[k, y, b] * v[k, z, b] - h[k, z, b] * v[k, y, b]
                Lk[r, b] = mk * v[k, r, b]
            if revolute[k]:
                e0, e1, e2 = (0, 1, 2) if r == 0 else ((1, 3, 4) if r == 1 else (2, 4, 5))
                for b in range(nb):
                    Hk[r, b] += Ic[k, e0, b] * F[k, 2, 0, b] + Ic[k, e1, b] * F[k, 2, 1, b] + Ic[k, e2, b] * F[k, 2, 2, b]
                    Lk[r, b] += F[k, 2, y, b] * h[k, z, b] - F[k, 2, z, b] * h[k, y, b]
        for j in range(k + 1):
            if not sup[j, k]:
                continue
            for b in range(nb):
                Mt[j, k, b] = v[j, 0, b] * Lk[0, b] + v[j, 1, b] * Lk[1, b] + v[j, 2, b] * Lk[2, b]
            if revolute[j]:
                for b in range(nb):
                    Mt[j, k, b] += F[j, 2, 0, b] * Hk[0, b] + F[j, 2, 1, b] * Hk[1, b] + F[j, 2, 2, b] * Hk[2, b]
            if j == k:
                for b in range(nb):
                    Mt[k, k, b] += arm_t[k]
            else:
                for b in range(nb):
                    Mt[k, j, b] = Mt[j, k, b]


@jit
def _gravity(revolute, mass_c, g0, F, v, h, nb, gt):
    """g_θ (nθ, K) [N m]."""
    d3 = g0.shape[0]
    for j in range(revolute.shape[0]):
        for b in range(nb):
            gt[j, b] = 0.0
        for r in range(d3):
            if g0[r] != 0.0:
                c = -mass_c[j] * g0[r]
                for b in range(nb):
                    gt[j, b] += c * v[j, r, b]
        if revolute[j]:
            for r in range(d3):  # −ω · (h × g₀) = −Σ_r (g₀ × ω)_r h_r
                y, z = (r + 1) % 3, (r + 2) % 3
                if g0[y] != 0.0:
                    for b in range(nb):
                        gt[j, b] -= g0[y] * F[j, 2, z, b] * h[j, r, b]
                if g0[z] != 0.0:
                    for b in range(nb):
                        gt[j, b] += g0[z] * F[j, 2, y, b] * h[j, r, b]


@jit
def _put_vector(X, A, identity, b0, nb, out, i):
    """out[b0 + b, i, a] = Σ_j X[j, b] A[j, a] for X: (nθ, K)."""
    nt, n = A.shape
    for b in range(nb):
        if identity:
            for a in range(n):
                out[b0 + b, i, a] = X[a, b]
        else:
            for a in range(n):
                s = 0.0
                for j in range(nt):
                    if A[j, a] != 0.0:
                        s += X[j, b] * A[j, a]
                out[b0 + b, i, a] = s


@jit
def _put_congruence(X, A, identity, diag, b0, nb, W, out, i):
    """out[b0 + b, i] = Aᵀ X[:, :, b] A + diag(diag) for X: (nθ, nθ, K); W: (nθ, n, K) work."""
    nt, n = A.shape
    if identity:
        for b in range(nb):
            for a in range(n):
                for c in range(n):
                    out[b0 + b, i, a, c] = X[a, c, b]
                out[b0 + b, i, a, a] += diag[a]
        return
    for j in range(nt):
        for c in range(n):
            for b in range(nb):
                W[j, c, b] = 0.0
            for k in range(nt):
                akc = A[k, c]
                if akc != 0.0:
                    for b in range(nb):
                        W[j, c, b] += akc * X[j, k, b]
    for b in range(nb):
        for a in range(n):
            for c in range(n):
                s = 0.0
                for j in range(nt):
                    if A[j, a] != 0.0:
                        s += A[j, a] * W[j, c, b]
                out[b0 + b, i, a, c] = s
            out[b0 + b, i, a, a] += diag[a]


@jit
def evaluate(parent, revolute, G, psi, t, mass, lever, inertia, mass_c, arm_t, fj, ft, g0, sup, path,
             A, identity, rows, arm_q, th, want, x, J, dJ, M, g):
    """Write the requested terms of every configuration of th into the outputs.

    Args:
        parent: (nθ,) int64 parent chain index of each joint (−1: the world); parents precede children.
        revolute: (nθ,) bool, revolute (else prismatic) joints.
        G: (nθ, 3, 3) joint placement rotations between internal frames.
        psi: (nθ,) joint angle offsets [rad].
        t: (nθ, 3) joint placement translations in the parent's internal frame [m].
        mass: (nθ,) body masses [kg].
        lever: (nθ, 3) centres of mass in the internal frames [m].
        inertia: (nθ, 3, 3) rotational inertias about the centres of mass, internal frames [kg m²].
        mass_c: (nθ,) subtree masses [kg].
        arm_t: (nθ,) the model's armature [kg m²].
        fj: chain index of the end-effector frame's joint (−1: the world).
        ft: (3,) end-effector frame origin in that joint's internal frame [m].
        g0: (3,) gravity [m/s²].
        sup: (nθ, nθ) bool, [j, k]: joint j supports joint k (or is k).
        path: (nθ,) bool, joints supporting the frame's joint.
        A: (nθ, n) actuation map.
        identity: A is the identity.
        rows: (m,) int64 task rows (world axes).
        arm_q: (n,) motor armature [kg m²].
        th: (B, nθ) chain coordinates θ = A q + b [rad or m].
        want: flags for (x, J, dJ, M, g); an output not wanted may be any array of its rank.
        x: (B, m) output, end-effector position [m].
        J: (B, m, n) output, task Jacobian [m/rad].
        dJ: (B, m, n, n) output, [b, i, j, k] = ∂J_ij/∂q_k [m/rad²].
        M: (B, 1, n, n) output, joint-space inertia [kg m²].
        g: (B, 1, n) output, gravity torque [N m].
    """
    d3 = ft.shape[0]
    B, nt = th.shape
    n, m, K = A.shape[1], rows.shape[0], BLOCK
    want_x, want_J, want_dJ, want_M, want_g = want
    kin, dyn = want_x or want_J or want_dJ, want_M or want_g
    tb = np.empty((nt, K))
    F = np.empty((nt, 3, 3, K))
    o = np.empty((nt, 3, K))
    v = np.empty((nt, 3, K))
    cs = np.empty(K)
    sn = np.empty(K)
    p = np.empty((3, K))
    Jp = np.zeros((nt, 3, K))  # point Jacobian columns; zero off the path
    Hs = np.zeros((nt, nt, K))  # one task row of ∂J_θ/∂θ; zero off the path and for prismatic joints
    h = np.empty((nt, 3, K))
    Ic = np.empty((nt, 6, K))
    Mt = np.zeros((nt, nt, K))  # zero between joints on different branches
    gt = np.empty((nt, K))
    W = np.empty((nt, n, K))
    X = np.empty((nt, K))
    c3 = np.empty((3, K))
    L3 = np.empty((3, K))
    FI = np.empty((3, 3, K))
    no_diag = np.zeros(n)
    first = rows.shape[0] - m  # 0 as a run-time integer: one compiled version of the _put functions
    for b0 in range(0, B, K):
        nb = min(K, B - b0)
        for b in range(nb):
            for j in range(nt):
                tb[j, b] = th[b0 + b, j]
        _forward(parent, revolute, G, psi, t, tb, nb, F, o, v, cs, sn)
        if kin:
            for r in range(d3):
                for b in range(nb):
                    p[r, b] = ft[r] if fj < 0 else o[fj, r, b]
                if fj >= 0:
                    for col in range(d3):
                        if ft[col] != 0.0:
                            for b in range(nb):
                                p[r, b] += ft[col] * F[fj, col, r, b]
            for j in range(nt):
                if not path[j]:
                    continue
                for r in range(d3):
                    for b in range(nb):
                        Jp[j, r, b] = v[j, r, b]
                    if revolute[j]:
                        y, z = (r + 1) % 3, (r + 2) % 3
                        for b in range(nb):
                            Jp[j, r, b] += F[j, 2, y, b] * p[z, b] - F[j, 2, z, b] * p[y, b]
            for i in range(m):
                row = rows[i]
                if want_x:
                    for b in range(nb):
                        x[b0 + b, i] = p[row, b]
                if want_J:
                    for j in range(nt):
                        for b in range(nb):
                            X[j, b] = Jp[j, row, b]
                    _put_vector(X, A, identity, b0, nb, J, i)
                if want_dJ:
                    y, z = (row + 1) % 3, (row + 2) % 3
                    for j in range(nt):
                        if not (path[j] and revolute[j]):
                            continue
                        for k in range(j, nt):
                            if path[k]:
                                for b in range(nb):
                                    Hs[j, k, b] = F[j, 2, y, b] * Jp[k, z, b] - F[j, 2, z, b] * Jp[k, y, b]
                                    Hs[k, j, b] = Hs[j, k, b]
                    _put_congruence(Hs, A, identity, no_diag, b0, nb, W, dJ, i)
        if dyn:
            _composite(parent, mass, lever, inertia, F, o, nb, want_M, h, Ic, c3, FI)
            if want_g:
                _gravity(revolute, mass_c, g0, F, v, h, nb, gt)
                _put_vector(gt, A, identity, b0, nb, g, first)
            if want_M:
                _mass(revolute, mass_c, arm_t, sup, F, v, h, Ic, nb, Mt, c3, L3)
                _put_congruence(Mt, A, identity, arm_q, b0, nb, W, M, first)
