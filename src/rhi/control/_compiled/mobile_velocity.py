"""App. A's velocity-level controller tick, compiled: weighted motion distribution with DM enhancement.

`velocity_tick` is one `rhi.control.mobile.WeightedDistributionController.step` (eqs. A.5, A.8–A.20: the
weighted pseudoinverse with the adaptive γ, the directional manipulability's Cartesian and null-space stages,
the bounds of A.13 and Table B.1), line by line, with the kinematics of
`rhi.control._compiled.mobile_terms.point_terms` (∂J/∂q from its columns: a_min(j,k) × v_max(j,k)). The Python
controller is its oracle (equal to rounding, `tests/test_mobile_velocity.py`). Run by
`rhi.sim._compiled.mobile_loop`.
"""

from __future__ import annotations

import math

import numpy as np

from rhi.control._compiled.mobile import scale_factor
from rhi.control._compiled.mobile_terms import point_terms, sym3
from rhi.jit import jit

#: Slots of the parameter vector: T [s], K_x [1/s], ε, the distribution, the null-space projector, the
#: weighting, DM on, k_C, k_N, the printed A.9 factor, wheel radius R, l1 + l2 [m], then the DM vector: u (3),
#: τ_lim (m) [N m], and per axis x, y, z: optimised (1/0), x_min, x_max [m].
P_DT, P_KX, P_EPS, P_DIST, P_NULL, P_WEIGHT, P_DM, P_KC, P_KN, P_PRINTED, P_R, P_L = range(12)
N_PARAMS = 12
#: Codes of the distribution, the null-space projector, the weighting and the stage.
WEIGHTED, PINV, PINV_GENERALIZED = 0, 1, 2
NULL_GENERALIZED, NULL_WEIGHTED = 0, 1
WHEEL, GENERALIZED = 0, 1
TRACK, DM_CARTESIAN, DM_NULL = 0, 1, 2
#: Slots of a tick's record: γ, η, H₂ [N].
R_GAMMA, R_ETA, R_DM = range(3)
#: Outcomes: done; the Python controller raises (Jᵀu = 0: the DM is unbounded).
OK, RAISES = 0, 1
#: As `rhi.control.mobile.weighted.HELD`, `rhi.control.mobile.bounds.EPS`, `rhi.metrics`' SINGULAR_RTOL.
_HELD, _EPS, _SINGULAR = 1e-6, 1e-12, 1e-12


@jit
def _nmax(a, b):
    """np.maximum of two floats (NaN if either is)."""
    return a if a != a or a > b else b


@jit
def _nmin(a, b):
    """np.minimum of two floats (NaN if either is)."""
    return a if a != a or a < b else b


@jit
def mecanum(theta, R, L):
    """`rhi.devices.mobile_base.mecanum_map` (3, 4) at heading theta for wheel radius R and l1 + l2 = L [m]."""
    k = R / 4.0
    JV = np.array([[k, k, k, k], [-k, k, k, -k], [k * (-1.0 / L), k * (1.0 / L), k * (-1.0 / L), k * (1.0 / L)]])
    c, s = math.cos(theta), math.sin(theta)
    JI = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return JI @ JV


@jit
def weighted_pinv(J, gamma, nb):
    """`rhi.control.mobile.weighted.weighted_pinv_psd` with W = diag(γ I_nb, (1 − γ) I): (k, 3) for J (3, k)."""
    k = J.shape[1]
    s = np.empty(k)
    for i in range(k):
        s[i] = math.sqrt(gamma if i < nb else 1.0 - gamma)
    A = np.empty((3, k))
    for r in range(3):
        for i in range(k):
            A[r, i] = J[r, i] * s[i]
    out = np.ascontiguousarray(np.linalg.pinv(A, 1e-10))
    for i in range(k):
        for r in range(3):
            out[i, r] = s[i] * out[i, r]
    return out


@jit
def distribution_pinv(gamma, J, Jq, P, weighting):
    """`WeightedDistributionController._weighted_pinv`: J† at γ as a map to [wheel speeds; arm rates] (4 + m, 3)."""
    if weighting == WHEEL:
        return weighted_pinv(J, gamma, 4)
    Jg = weighted_pinv(Jq, gamma, 3)
    m = Jq.shape[1] - 3
    out = np.empty((4 + m, 3))
    out[:4] = np.ascontiguousarray(np.linalg.pinv(P)) @ np.ascontiguousarray(Jg[:3])
    out[4:] = Jg[3:]
    return out


@jit
def null_motion(J, Jq, P, Jp, grad, held, null_space):
    """`WeightedDistributionController._null_motion`: (I − J†J) v_n as [wheel speeds; arm rates] (4 + m,)."""
    m = grad.shape[0]
    if null_space == NULL_WEIGHTED:
        v = np.zeros(4 + m)
        v[4:] = grad
        return v - Jp @ (J @ v)
    vq = np.zeros(3 + m)
    Jh = Jq.copy()
    for i in range(m):
        vq[3 + i] = 0.0 if held[i] else grad[i]
        if held[i]:
            Jh[:, 3 + i] = 0.0
    G = Jh @ Jh.T
    Gi = np.empty((3, 3))
    _, lmin, _, ok = sym3(G, Gi)
    if ok and lmin > 0.0:
        vq = vq - Jh.T @ (Gi @ (Jh @ vq))
    else:
        vq = vq - np.ascontiguousarray(np.linalg.pinv(Jh)) @ (Jh @ vq)
    out = np.empty(4 + m)
    out[:4] = np.ascontiguousarray(np.linalg.pinv(P)) @ vq[:3]
    out[4:] = vq[3:]
    return out


@jit
def dm_terms(J6, prm, grad_out):
    """H₂ (A.8) of the arm columns of J6 and, into grad_out (m,), ∂H₂/∂q_m (A.9); NaN where Jᵀu = 0 (the raise)."""
    n = J6.shape[1]
    m = n - 3
    u = prm[N_PARAMS:N_PARAMS + 3]
    tl = prm[N_PARAMS + 3:N_PARAMS + 3 + m]
    v = np.zeros(m)  # (J_m W)ᵀ u
    fro = 0.0
    for j in range(m):
        w = 1.0 / tl[j]
        for r in range(3):
            b = J6[r, 3 + j] * w
            v[j] += b * u[r]
            fro += b * b
    nv = math.sqrt(v @ v)
    if nv <= _SINGULAR * math.sqrt(fro):
        return math.nan
    h = 1.0 / nv
    Jtu = np.zeros(m)
    for j in range(m):
        for r in range(3):
            Jtu[j] += J6[r, 3 + j] * u[r]
    for k in range(m):  # ∂s/∂q_k = 2 Σ_ij u_i ∂J_ij/∂q_k w²_j (Jᵀu)_j, ∂J_:j/∂q_k = a_min × v_max
        ds = 0.0
        for j in range(m):
            lo, hi = min(j, k) + 3, max(j, k) + 3
            a0, a1, a2 = J6[3, lo], J6[4, lo], J6[5, lo]
            v0, v1, v2 = J6[0, hi], J6[1, hi], J6[2, hi]
            d0, d1, d2 = a1 * v2 - a2 * v1, a2 * v0 - a0 * v2, a0 * v1 - a1 * v0
            ds += (u[0] * d0 + u[1] * d1 + u[2] * d2) * (1.0 / tl[j] ** 2 * Jtu[j])
        grad_out[k] = -0.5 * h**3 * (2.0 * ds)
    return h


@jit
def velocity_bounds(q, bnd, T, lo, hi):
    """`rhi.control.mobile.bounds.velocity_bounds_unchecked` (A.13), written into lo, hi (n,)."""
    for i in range(q.shape[0]):
        d_lo = _nmax(q[i] - bnd[0, i], 0.0)
        d_hi = _nmax(bnd[1, i] - q[i], 0.0)
        a = _nmax(_nmax(-d_lo / T, bnd[2, i]), -math.sqrt(2.0 * bnd[5, i] * d_lo))
        b = _nmin(_nmin(d_hi / T, bnd[3, i]), math.sqrt(-2.0 * bnd[4, i] * d_hi))
        lo[i], hi[i] = _nmin(a, 0.0), _nmax(b, 0.0)


@jit(inline=True)
def velocity_tick(prm, bnd, ints, joints, fc, stage, q, xd, dxd, x, dq, rec):
    """One `WeightedDistributionController.step` at stage (TRACK, DM_CARTESIAN, DM_NULL).

    Args:
        prm: settings (P_* slots, then the DM vector).
        bnd: (6, n) q_min, q_max, dq_min, dq_max, ddq_min, ddq_max.
        ints: the device's `pack` integer constants (`point_terms`).
        joints: its per-joint constants.
        fc: its frame constants.
        stage: the stage's code.
        q: (n,) configuration [x_b, y_b, θ_b, q_m].
        xd: (3,) desired position [m].
        dxd: (3,) desired velocity [m/s].
        x: (3,) the end-effector position [m], written.
        dq: (n,) the commanded generalized velocities, written.
        rec: (3,) γ, η, H₂, written.

    Returns:
        OK, or RAISES (nothing written that the Python loop keeps).
    """
    n = q.shape[0]
    m = n - 3
    J6, drift = np.empty((6, n)), np.empty(3)
    point_terms(ints, joints, fc, q, np.zeros(n), x, J6, drift)
    Jq = np.ascontiguousarray(J6[:3])
    P = mecanum(q[2], prm[P_R], prm[P_L])
    J = np.empty((3, 4 + m))
    J[:, :4] = np.ascontiguousarray(Jq[:, :3]) @ P
    J[:, 4:] = Jq[:, 3:]
    h = math.nan
    grad = np.empty(m)
    null = stage == DM_NULL
    dx = np.zeros(3)
    if stage == DM_CARTESIAN:
        h = dm_terms(J6, prm, grad)
        if h != h:
            return RAISES
        f = 1.0 if prm[P_PRINTED] == 0.0 else h**-4.5
        gx = (grad @ np.ascontiguousarray(np.linalg.pinv(np.ascontiguousarray(Jq[:, 3:])))) * f  # A.10
        for k in range(3):
            at = N_PARAMS + 3 + m + 3 * k
            if prm[at] != 0.0 and prm[at + 1] <= x[k] <= prm[at + 2]:
                dx[k] = prm[P_KC] * gx[k]  # A.18
    else:
        for k in range(3):
            dx[k] = dxd[k] + prm[P_KX] * (xd[k] - x[k])
        if null or prm[P_DM] != 0.0:
            h = dm_terms(J6, prm, grad)
            if h != h:
                return RAISES
            if null:
                f = 1.0 if prm[P_PRINTED] == 0.0 else h**-4.5
                for i in range(m):
                    grad[i] = prm[P_KN] * grad[i] * f  # v_n of A.20
    vlo, vhi = np.empty(n), np.empty(n)
    velocity_bounds(q, bnd, prm[P_DT], vlo, vhi)
    held = np.zeros(m, np.bool_)
    if null:
        for i in range(m):
            held[i] = (grad[i] > 0 and vhi[3 + i] <= _HELD) or (grad[i] < 0 and vlo[3 + i] >= -_HELD)
    gamma = eta = math.nan
    dist, weighting, ns = int(prm[P_DIST]), int(prm[P_WEIGHT]), int(prm[P_NULL])
    if dist == PINV:
        Jp = np.ascontiguousarray(np.linalg.pinv(J))
    elif dist == PINV_GENERALIZED:
        S = np.zeros((4 + m, n))
        S[:4, :3] = np.linalg.pinv(P)
        for i in range(m):
            S[4 + i, 3 + i] = 1.0
        Jp = S @ np.ascontiguousarray(np.linalg.pinv(Jq))
    else:
        J0 = distribution_pinv(0.0, J, Jq, P, weighting)
        v0 = J0 @ dx
        if null:
            v0 = v0 + null_motion(J, Jq, P, J0, grad, held, ns)
        eta = 0.0
        for i in range(m):
            a = abs(v0[4 + i])
            if a > 0:
                r = a / abs(vhi[3 + i] if v0[4 + i] >= 0 else -vlo[3 + i])
                eta = _nmax(eta, r)
        gamma = 0.0 if eta <= prm[P_EPS] else _nmin(eta, 1.0)
        Jp = J0 if gamma == 0.0 else distribution_pinv(gamma, J, Jq, P, weighting)
    v = Jp @ dx
    if null:
        vn = null_motion(J, Jq, P, Jp, grad, held, ns)  # A.19
        a, c = np.empty(n), np.empty(n)
        a[:3], a[3:] = P @ vn[:4], vn[4:]
        c[:3], c[3:] = P @ v[:4], v[4:]
        v = v + scale_factor(a, c, vlo, vhi, np.ones(n, np.bool_))[0] * vn
    dqb = P @ v[:4]
    ratio = -math.inf
    for i in range(3):
        ratio = _nmax(ratio, abs(dqb[i]) / _nmax(abs(vhi[i] if dqb[i] >= 0 else vlo[i]), _EPS))
    if ratio > 1.0:
        for i in range(3):
            dqb[i] = dqb[i] / ratio
    for i in range(3):
        dq[i] = dqb[i]
    for i in range(m):
        dq[3 + i] = min(max(v[4 + i], vlo[3 + i]), vhi[3 + i])  # np.clip
    rec[R_GAMMA], rec[R_ETA], rec[R_DM] = gamma, eta, h
    return OK
