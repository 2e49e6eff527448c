"""GM, GC (eqs. 4.8, 4.10) and GM_T (eq. 4.18) of a planar master–slave pair in one compiled pass.

A design evaluation of §4.4 integrates three local indices over a few hundred workspace
samples, and an optimisation evaluates tens of thousands of designs, most of them one at a
time (Nelder–Mead). Composed from `rhi.metrics` (`manipulability`, `isotropy`, `tmi`,
`global_index`) that costs about a hundred NumPy calls per design; the arrays are small,
so the calls' overhead, not the arithmetic, was the time. `planar_indices` computes the
same quantities sample by sample in one Numba loop:

* the singular values and left singular vectors of each two-row Jacobian as
  `rhi.metrics._svd2` does (row pivot, one re-orthogonalised Gram–Schmidt step, the
  triangle's singular values without cancellation, the principal-axis angle);
* μ = σ₁σ₂ (eq. 4.7), 1/κ = σ₂/σ₁ (eq. 4.9, 0 for J = 0);
* the TMI λ of eqs. 4.12–4.17 with `rhi.metrics._common.radius_along`'s rule for lost axes;
* the weighted means over the reached samples (unreached samples count 0, as in `indices`).

`tests/test_design.py` checks it against the `rhi.metrics` composition (`device_indices`,
`teleoperation_index`) to round-off.
"""

from __future__ import annotations

import math

import numpy as np

from rhi._validate import as_array
from rhi.errors import InvalidInput, Unreachable
from rhi.jit import jit
from rhi.metrics import SINGULAR_RTOL

_RTOL = SINGULAR_RTOL
_DIR_ATOL = 1e-10  # rhi.metrics._common.DIRECTION_ATOL


@jit
def _axes(J, k, out_s, out_u):  # pragma: no cover - compiled
    """Singular values (descending) into out_s (2,) and left singular vectors (columns) into out_u (2, 2)."""
    n = J.shape[2]
    scale = 0.0
    for i in range(2):
        for j in range(n):
            a = abs(J[k, i, j])
            if a > scale:
                scale = a
    if scale == 0.0:
        out_s[0] = 0.0
        out_s[1] = 0.0
        out_u[0, 0], out_u[0, 1], out_u[1, 0], out_u[1, 1] = 1.0, 0.0, 0.0, 1.0
        return
    n1 = 0.0
    n2 = 0.0
    for j in range(n):
        x = J[k, 0, j] / scale
        y = J[k, 1, j] / scale
        n1 += x * x
        n2 += y * y
    swap = n2 > n1
    ia, ib = (1, 0) if swap else (0, 1)
    f = math.sqrt(max(n1, n2))
    g = 0.0
    for j in range(n):
        g += (J[k, ib, j] / scale) * ((J[k, ia, j] / scale) / f)
    c = 0.0
    for j in range(n):
        e = (J[k, ia, j] / scale) / f
        c += ((J[k, ib, j] / scale) - g * e) * e
    hh = 0.0
    for j in range(n):
        e = (J[k, ia, j] / scale) / f
        w = ((J[k, ib, j] / scale) - g * e) - c * e
        hh += w * w
    g = g + c
    h = math.sqrt(hh)
    s1 = 0.5 * (math.hypot(f + h, g) + math.hypot(f - h, g))
    s2 = f * h / s1 if s1 > 0 else 0.0
    out_s[0] = s1 * scale
    out_s[1] = s2 * scale
    theta = 0.5 * math.atan2(2.0 * f * g, f * f - g * g - h * h)
    ct = math.cos(theta)
    st = math.sin(theta)
    if swap:
        out_u[0, 0], out_u[1, 0], out_u[0, 1], out_u[1, 1] = st, ct, ct, -st
    else:
        out_u[0, 0], out_u[1, 0], out_u[0, 1], out_u[1, 1] = ct, st, -st, ct


@jit
def _radius(s, U, u0, u1):  # pragma: no cover - compiled
    """Radius of the ellipse with semi-axes s (2,) along the columns of U (2, 2) in the unit direction (u0, u1)."""
    q = 0.0
    for j in range(2):
        c = U[0, j] * u0 + U[1, j] * u1
        if s[j] <= _RTOL * s[0]:  # a lost axis
            if abs(c) > _DIR_ATOL:
                return 0.0
        else:
            w = c / s[j]
            q += w * w
    return 1.0 / math.sqrt(q) if q > 0 else 0.0


@jit
def _sums(Jm, Js, ok, weights):  # pragma: no cover - compiled
    """Σ w μ, Σ w (1/κ), Σ w λ over the reached samples."""
    sM = np.empty(2)
    UM = np.empty((2, 2))
    sS = np.empty(2)
    US = np.empty((2, 2))
    gm = 0.0
    gc = 0.0
    gt = 0.0
    for k in range(Jm.shape[0]):
        if not ok[k]:
            continue
        _axes(Jm, k, sM, UM)
        _axes(Js, k, sS, US)
        w = weights[k]
        gm += w * (sM[0] * sM[1])
        gc += w * (sM[1] / sM[0] if sM[0] > 0 else 0.0)
        lam1 = 1.0
        lam2 = 1.0
        for i in range(2):
            lam1 *= min(_radius(sS, US, UM[0, i], UM[1, i]), sM[i])  # eqs. 4.12, 4.14
            lam2 *= min(_radius(sM, UM, US[0, i], US[1, i]), sS[i])  # eqs. 4.15, 4.16
        gt += w * max(lam1, lam2)  # eq. 4.17
    return gm, gc, gt


@jit
def _sums_many(Jm, Js, ok, weights, out):  # pragma: no cover - compiled
    """`_sums` of each design i of Jm (P, N, 2, n_M), ok (P, N) into out[i] (3,)."""
    for i in range(Jm.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _sums(Jm[i], Js, ok[i], weights)


def planar_indices(J_master: np.ndarray, J_slave: np.ndarray, ok: np.ndarray, weights: np.ndarray) -> dict[str, float]:
    """GM, GC of the master (eqs. 4.8, 4.10) and GM_T of the pair (eq. 4.18) over the workspace samples.

    The same numbers as `device_indices` and `teleoperation_index` (to round-off), in one pass.

    Args:
        J_master: (N, 2, n_M) (penalized) master Jacobians in the task frame.
        J_slave: (N, 2, n_S) (penalized) slave Jacobians.
        ok: (N,) whether both robots reached the sample; unreached samples contribute 0.
        weights: (N,) area weights [m²], positive sum.

    Returns:
        {"GM", "GC", "GM_T", "coverage"}.

    Raises:
        InvalidInput: shapes that do not match, or non-finite Jacobians or weights.
        Unreachable: no sample was reached.
    """
    Jm = as_array("J_master", J_master, ndim_min=3)
    if Jm.ndim != 3:
        raise InvalidInput(f"J_master: expected (N, 2, n), got {Jm.shape}")
    return planar_indices_many(Jm[None], J_slave, np.asarray(ok)[None], weights)[0]


def planar_indices_many(J_master: np.ndarray, J_slave: np.ndarray, ok: np.ndarray,
                        weights: np.ndarray) -> list[dict[str, float]]:
    """`planar_indices` of P master designs over the same samples and slave, in one compiled call.

    Args:
        J_master: (P, N, 2, n_M) (penalized) master Jacobians of each design.
        J_slave: (N, 2, n_S) (penalized) slave Jacobians.
        ok: (P, N) whether both robots reached each sample, per design.
        weights: (N,) area weights [m²], positive sum.

    Returns:
        One {"GM", "GC", "GM_T", "coverage"} per design.

    Raises:
        InvalidInput: shapes that do not match, or non-finite Jacobians or weights.
        Unreachable: a design reached no sample.
    """
    Jm = as_array("J_master", J_master, ndim_min=4)
    Js = as_array("J_slave", J_slave, ndim_min=3)
    n = Js.shape[0]
    if Jm.ndim != 4 or Js.ndim != 3 or Jm.shape[1:3] != (n, 2) or Js.shape[1] != 2:
        raise InvalidInput(f"J_master/J_slave: expected (N, 2, n) each with the same N, got {Jm.shape[1:]} and {Js.shape}")
    ok = np.ascontiguousarray(ok, dtype=np.bool_)
    w = as_array("weights", weights)
    if ok.shape != Jm.shape[:2] or w.shape != (n,):
        raise InvalidInput(f"ok/weights: expected shape ({n},) each, got {ok.shape[1:]} and {w.shape}")
    if not ok.any(axis=-1).all():
        raise Unreachable("workspace: inverse kinematics failed at every workspace sample")
    sums = np.empty((Jm.shape[0], 3))
    _sums_many(np.ascontiguousarray(Jm), np.ascontiguousarray(Js), ok, np.ascontiguousarray(w), sums)
    total = float(np.sum(w))
    return [{"GM": float(gm / total), "GC": float(gc / total), "GM_T": float(gt / total),
             "coverage": float(np.sum(w[k]) / total)} for (gm, gc, gt), k in zip(sums, ok, strict=True)]
