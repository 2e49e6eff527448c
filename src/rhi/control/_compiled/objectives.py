"""Static null-space objectives and joint-limit barriers inside the whole tick (`rhi.control._compiled.whole`).

The objectives the controller would otherwise compute in Python every tick (`gradient_at`):
FME matching to a fixed desired FME (`rhi.control.FMEMatching`, eqs. 6.9–6.10, through
`rhi.control._compiled.step.fme_gradient`, the gradient the FME schedule uses) and the joint-limit
barrier (`rhi.control.JointLimitBarrier`). Their settings travel in one float vector:

    [k_fme, k_barrier, r, C (r × n), lower (r), upper (r),
     k_fme × (gain, w2 (n), M_des (m × m)), k_barrier × (gain, kind, margin, weight)]

with C, lower, upper the barrier's limit rows (`rhi.control.barrier.limit_rows`, ±inf where a
side is unlimited) and kind 0 (quadratic) or 1 (inverse). `pack` builds it.
"""

from __future__ import annotations

import numpy as np

from rhi.control._compiled.step import fme_gradient
from rhi.jit import jit

#: Head slots of the objective vector: counts of FME terms, barrier terms and limit rows.
OBJ_FME, OBJ_BARRIER, OBJ_ROWS = range(3)
N_OBJ = 3
#: Barrier kinds (`JointLimitBarrier.kind`).
QUADRATIC, INVERSE = 0, 1


def pack(n: int, m: int, fme: list[tuple[float, np.ndarray, np.ndarray]],
         barriers: list[tuple[float, int, float, float]], rows: tuple[np.ndarray, np.ndarray, np.ndarray]
         ) -> np.ndarray:
    """The objective vector of `objectives`.

    Args:
        n: joints.
        m: task rows.
        fme: (gain, w2 (n,) [1/(N m)²], M_des (m, m)) of each static FME-matching term.
        barriers: (gain [N m], kind, margin δ [rad], weight w) of each joint-limit barrier.
        rows: (C (r, n), lower (r,), upper (r,)) limit rows of the barriers (r = 0 without one).
    """
    C, lower, upper = rows
    parts = [np.array([len(fme), len(barriers), C.shape[0]], dtype=float), C.ravel(), lower, upper]
    for gain, w2, D in fme:
        parts += [np.array([gain]), np.broadcast_to(w2, (n,)), np.asarray(D, dtype=float).reshape(m * m)]
    for bar in barriers:
        parts.append(np.array(bar, dtype=float))
    return np.ascontiguousarray(np.concatenate(parts), dtype=np.float64)


@jit(inline=True)
def objectives(obj, q, J, dJ, tau_s, tau_to):
    """Add −Σ gain ∂ν_lim/∂q of the barriers to tau_s and −Σ gain ∂ν/∂q of the FME terms to tau_to [N m], in place.

    Args:
        obj: the objective vector (see the module).
        q: (n,) joint positions [rad].
        J: (m, n) Jacobian.
        dJ: (m, n, n) its derivative ∂J/∂q.
        tau_s: (n,) safety torque, added to.
        tau_to: (n,) objective torque, added to.
    """
    m, n = J.shape
    kf, kb, r = int(obj[OBJ_FME]), int(obj[OBJ_BARRIER]), int(obj[OBJ_ROWS])
    o = N_OBJ + r * (n + 2)
    for _ in range(kf):
        gain = obj[o]
        grad = fme_gradient(obj[o + 1 + n:o + 1 + n + m * m].reshape((m, m)), J, dJ, obj[o + 1:o + 1 + n])
        for i in range(n):
            tau_to[i] -= gain * grad[i]
        o += 1 + n + m * m
    lower, upper = N_OBJ + r * n, N_OBJ + r * n + r
    for _ in range(kb):
        gain, inverse, margin, weight = obj[o], obj[o + 1] == INVERSE, obj[o + 2], obj[o + 3]
        o += 4
        for k in range(r):  # ∂ν/∂q = Cᵀ (∂ν/∂d_lo − ∂ν/∂d_hi), d_lo = C q − lower, d_hi = upper − C q
            c = 0.0
            for j in range(n):
                c += obj[N_OBJ + k * n + j] * q[j]
            s = _slope(c - obj[lower + k], inverse, margin, weight) - _slope(obj[upper + k] - c, inverse, margin,
                                                                             weight)
            if s != 0.0:
                for j in range(n):
                    tau_s[j] -= gain * obj[N_OBJ + k * n + j] * s


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
