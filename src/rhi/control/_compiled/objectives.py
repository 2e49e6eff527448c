"""Null-space objectives and joint-limit barriers inside the whole tick (`rhi.control._compiled.whole`).

The objectives the controller would otherwise compute in Python every tick (`gradient_at`):
FME matching to a desired FME (`rhi.control.FMEMatching`, eqs. 6.9–6.10, through
`rhi.control._compiled.step.fme_gradient`, the gradient the FME schedule uses; one that changes with the
user's intent, `rhi.control.intent_control.IntentFME`, is written at `fme_slot` before the tick), the joint-limit
barrier (`rhi.control.JointLimitBarrier`) and the Jacobian objectives of chapter 5 on the joint-limit
penalised Jacobian J^q = J diag(P(q)) (eqs. 4.19–4.20): JBLD matching of J^q J^qᵀ to a desired D that
may change every tick (`rhi.control.TMIMatching`, eq. 5.11: D the slave's ME; the caller writes it at
`desired_slot` before the tick), −log μ and −μ (`rhi.control.Manipulability`, eq. 5.14). Their settings
travel in one float vector:

    [k_fme, k_barrier, r, k_jac, C (r × n), lower (r), upper (r),
     k_fme × (gain, w2 (n), M_des (m × m)), k_barrier × (gain, kind, margin, weight, hold),
     k_jac × (code, gain, k_q, q_min (n), q_max (n), D (m × m))]

with C, lower, upper the barrier's limit rows (`rhi.control.barrier.limit_rows`, ±inf where a
side is unlimited), kind 0 (quadratic) or 1 (inverse), hold ΔT [s] of the sampled-exact form
(`rhi.control.JointLimitBarrier.sampled_gradient`; 0: the gradient), code `JBLD`, `LOG_MU` or `MU` and k_q 0 for
the plain Jacobian. `pack` builds it.
"""

from __future__ import annotations

import math

import numpy as np

from rhi.control._compiled.step import _contract, fme_gradient, vme_gradient
from rhi.devices._compiled.terms import inv, mm
from rhi.jit import jit, stack_empty

#: Head slots of the objective vector: counts of FME terms, barrier terms, limit rows and Jacobian objectives.
OBJ_FME, OBJ_BARRIER, OBJ_ROWS, OBJ_JAC = range(4)
N_OBJ = 4
#: Barrier kinds (`JointLimitBarrier.kind`).
QUADRATIC, INVERSE = 0, 1
#: Slots of one barrier term: gain, kind, margin, weight, hold.
N_BAR = 5
#: Jacobian objective codes: JBLD(D, J^q J^qᵀ) (eq. 5.11), −log μ(J^q), −μ(J^q) (eq. 5.14).
JBLD, LOG_MU, MU = 0, 1, 2


def pack(n: int, m: int, fme: list[tuple[float, np.ndarray, np.ndarray]],
         barriers: list[tuple[float, int, float, float, float]], rows: tuple[np.ndarray, np.ndarray, np.ndarray],
         jac: list[tuple[int, float, float, np.ndarray, np.ndarray, np.ndarray]] = ()) -> np.ndarray:  # type: ignore[assignment]
    """The objective vector of `objectives`.

    Args:
        n: joints.
        m: task rows.
        fme: (gain, w2 (n,) [1/(N m)²], M_des (m, m)) of each static FME-matching term.
        barriers: (gain [N m], kind, margin δ [rad], weight w, hold ΔT [s]) of each joint-limit barrier.
        rows: (C (r, n), lower (r,), upper (r,)) limit rows of the barriers (r = 0 without one).
        jac: (code, gain, k_q (0: no penalty), q_min (n,), q_max (n,) [rad], D (m, m)) of each Jacobian objective.
    """
    C, lower, upper = rows
    parts = [np.array([len(fme), len(barriers), C.shape[0], len(jac)], dtype=float), C.ravel(), lower, upper]
    for gain, w2, D in fme:
        parts += [np.array([gain]), np.broadcast_to(w2, (n,)), np.asarray(D, dtype=float).reshape(m * m)]
    for bar in barriers:
        parts.append(np.array(bar, dtype=float))
    for code, gain, k_q, q_min, q_max, D in jac:
        parts += [np.array([code, gain, k_q], dtype=float), q_min, q_max, np.asarray(D, dtype=float).reshape(m * m)]
    return np.ascontiguousarray(np.concatenate(parts), dtype=np.float64)


def fme_slot(obj: np.ndarray, n: int, m: int, i: int) -> int:
    """Where M_des (m × m, row-major) of FME term i starts in the objective vector `obj`."""
    return N_OBJ + int(obj[OBJ_ROWS]) * (n + 2) + i * (1 + n + m * m) + 1 + n


def desired_slot(obj: np.ndarray, n: int, m: int, i: int) -> int:
    """Where the desired D (m × m, row-major) of Jacobian objective i starts in the objective vector `obj`."""
    kf, kb, r = int(obj[OBJ_FME]), int(obj[OBJ_BARRIER]), int(obj[OBJ_ROWS])
    return N_OBJ + r * (n + 2) + kf * (1 + n + m * m) + N_BAR * kb + i * (3 + 2 * n + m * m) + 3 + 2 * n


@jit(inline=True)
def objectives(obj, q, dq, J, dJ, tau_s, tau_to):
    """Add −Σ gain ∂ν_lim/∂q of the barriers to tau_s and −Σ gain ∂ν/∂q of the FME terms to tau_to [N m], in place.

    A barrier with hold ΔT > 0 adds −gain ∇̄ν_lim, the discrete gradient along ΔT q̇ (sampled-exact form).

    Args:
        obj: the objective vector (see the module).
        q: (n,) joint positions [rad].
        dq: (n,) joint velocities [rad/s].
        J: (m, n) Jacobian.
        dJ: (m, n, n) its derivative ∂J/∂q.
        tau_s: (n,) safety torque, added to.
        tau_to: (n,) objective torque, added to.
    """
    m, n = J.shape
    kf, kb, r, kj = int(obj[OBJ_FME]), int(obj[OBJ_BARRIER]), int(obj[OBJ_ROWS]), int(obj[OBJ_JAC])
    o = N_OBJ + r * (n + 2)
    grad = stack_empty(n, np.float64)
    for _ in range(kf):
        gain = obj[o]
        fme_gradient(obj[o + 1 + n:o + 1 + n + m * m].reshape((m, m)), J, dJ, obj[o + 1:o + 1 + n], grad)
        for i in range(n):
            tau_to[i] -= gain * grad[i]
        o += 1 + n + m * m
    lower, upper = N_OBJ + r * n, N_OBJ + r * n + r
    for _ in range(kb):
        gain, inverse, margin, weight, hold = obj[o], obj[o + 1] == INVERSE, obj[o + 2], obj[o + 3], obj[o + 4]
        o += N_BAR
        for k in range(r):  # ∂ν/∂q = Cᵀ (∂ν/∂d_lo − ∂ν/∂d_hi), d_lo = C q − lower, d_hi = upper − C q
            c, v = 0.0, 0.0
            for j in range(n):
                c += obj[N_OBJ + k * n + j] * q[j]
                v += obj[N_OBJ + k * n + j] * dq[j]
            if hold > 0.0:
                s = (_divided(c - obj[lower + k], hold * v, inverse, margin, weight)
                     - _divided(obj[upper + k] - c, -hold * v, inverse, margin, weight))
            else:
                s = _slope(c - obj[lower + k], inverse, margin, weight) - _slope(obj[upper + k] - c, inverse, margin,
                                                                                 weight)
            if s != 0.0:
                for j in range(n):
                    tau_s[j] -= gain * obj[N_OBJ + k * n + j] * s
    for _ in range(kj):
        code, gain, k_q = obj[o], obj[o + 1], obj[o + 2]
        Jq, dJq = J, dJ
        if k_q != 0.0:
            Jq, dJq = _penalized(J, dJ, q, obj[o + 3:o + 3 + n], obj[o + 3 + n:o + 3 + 2 * n], k_q)
        grad = _jacobian_gradient(code, Jq, dJq, obj[o + 3 + 2 * n:o + 3 + 2 * n + m * m].reshape((m, m)))
        for i in range(n):
            tau_to[i] -= gain * grad[i]
        o += 3 + 2 * n + m * m


@jit
def _slope(d, inverse, margin, weight):
    """∂ν/∂d of one limit side at distance d [rad]: quadratic w ½ max(0, δ − d)², inverse w (δ/d − 1)² for d < δ."""
    if not inverse:
        g = -max(0.0, margin - d)
        return g if weight == 1.0 else weight * g
    if not d < margin:
        return 0.0
    dd = max(d, 1e-3 * margin)
    ratio = margin / dd
    return -2.0 * weight * (ratio - 1.0) * ratio / dd


@jit
def _side(d, inverse, margin, weight):
    """φ(d) of one limit side at distance d [rad] (`rhi.control.JointLimitBarrier.side_values`)."""
    if not inverse:
        p = max(0.0, margin - d)
        return weight * 0.5 * p * p
    if not d < margin:
        return 0.0
    ratio = margin / max(d, 1e-3 * margin)
    return weight * (ratio - 1.0) * (ratio - 1.0)


@jit
def _divided(d, dd, inverse, margin, weight):
    """(φ(d + dd) − φ(d))/dd of one side, φ'(d + dd/2) where |dd| ≤ 1e-9 δ (`JointLimitBarrier.sampled_gradient`)."""
    if abs(dd) <= 1e-9 * margin:
        return _slope(d + 0.5 * dd, inverse, margin, weight)
    return (_side(d + dd, inverse, margin, weight) - _side(d, inverse, margin, weight)) / dd


@jit
def _penalized(J, dJ, q, q_min, q_max, k_q):
    """(J^q, ∂J^q/∂q) with J^q = J diag(P(q)) (eqs. 4.19–4.20), as `rhi.control.manipulability.penalized`."""
    m, n = J.shape
    Jq, dJq = np.empty((m, n)), np.empty((m, n, n))
    c = -math.expm1(-k_q)
    for j in range(n):
        lo, hi = q_min[j], q_max[j]
        span2 = (hi - lo) ** 2
        p, dp = 1.0, 0.0
        if math.isfinite(span2):
            e = math.exp(-4.0 * k_q * (q[j] - lo) * (hi - q[j]) / span2)
            p = min(max((1.0 - e) / c, 0.0), 1.0)
            if lo < q[j] < hi:
                dp = e * 4.0 * k_q * (hi + lo - 2.0 * q[j]) / span2 / c
        for i in range(m):  # ∂J^q_k = ∂J_k diag(P) + J_k P'_k e_kᵀ: column j of each slice scaled, its diagonal entry
            Jq[i, j] = J[i, j] * p
            for k in range(n):
                dJq[i, j, k] = dJ[i, j, k] * p
            dJq[i, j, j] += J[i, j] * dp
    return Jq, dJq


@jit
def _jacobian_gradient(code, J, dJ, D):
    """∂ν/∂q: (n,) of the Jacobian objective `code` on J (m, n), ∂J/∂q (m, n, n) and the desired D (m, m)."""
    if code == JBLD:
        return vme_gradient(D, J, dJ)
    M = mm(J, J.T)
    g = _contract(mm(inv(M), J), dJ)  # ½ ∇ log det(J Jᵀ) = ∇ log μ
    if code == LOG_MU:
        return -g
    return -math.sqrt(_det(M)) * g


@jit
def _det(A):
    """det(A) of a small SPD matrix: the product of the pivots of a Gaussian elimination (no pivoting needed)."""
    k = A.shape[0]
    B = A.copy()
    det = 1.0
    for i in range(k):
        det *= B[i, i]
        for r in range(i + 1, k):
            f = B[r, i] / B[i, i]
            for c in range(i, k):
                B[r, c] -= f * B[i, c]
    return det
