"""Distances between symmetric positive definite matrices and desired ellipsoids to match."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from rhi.errors import InvalidInput, NotSPD
from rhi.metrics._common import FloatArray, cholesky, direction, positive, square


def spd_matrix(name: str, A: ArrayLike) -> FloatArray:
    """A as one (m, m) symmetric positive definite float matrix; InvalidInput / NotSPD naming `name` otherwise."""
    A = square(name, A)
    if A.ndim != 2:
        raise InvalidInput(f"{name}: expected a square (m, m) matrix, got shape {A.shape}")
    cholesky(name, A)
    return A


def _logdet_spd(name: str, A: FloatArray) -> FloatArray:
    """``log det A`` of a symmetric positive definite ``A`` via its Cholesky factor."""
    L = cholesky(name, A)
    return 2.0 * np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), axis=-1)


def jbld(A: ArrayLike, B: ArrayLike) -> FloatArray:
    """Jensen-Bregman LogDet divergence ``logdet((A+B)/2) − ½ logdet(AB)`` (thesis eqs. 3.22, 6.10).

    Symmetric in ``A`` and ``B``, zero iff ``A = B``, positive otherwise.

    Args:
        A: (..., m, m) symmetric positive definite matrix.
        B: (..., m, m) symmetric positive definite matrix (leading axes broadcast with A).

    Returns:
        (...,) divergence >= 0 (rounding below zero is clipped to 0).

    Raises:
        InvalidInput: bad shapes or non-finite entries.
        NotSPD: ``A`` or ``B`` is not symmetric positive definite (named in the message).
    """
    A = square("A", A)
    B = square("B", B, A.shape[-1])
    try:
        np.broadcast_shapes(A.shape[:-2], B.shape[:-2])
    except ValueError:
        raise InvalidInput(f"B: batch shape {B.shape[:-2]} does not broadcast with A's {A.shape[:-2]}") from None
    la = _logdet_spd("A", A)
    lb = _logdet_spd("B", B)
    lm = _logdet_spd("(A+B)/2", 0.5 * (A + B))
    return np.maximum(lm - 0.5 * (la + lb), 0.0)


def jbld_spd(A: FloatArray, B: FloatArray) -> float:
    """`jbld` of two (m, m) float matrices symmetric by construction (an objective's, once per evaluation).

    Equal to `jbld` to the last bit (the same symmetrised Cholesky factors, for m = 2 in closed form as
    LAPACK computes them, and the same logarithms), without its shape and symmetry checks, which are
    most of its time on 2 × 2 matrices. Raises `NotSPD` where a matrix is not positive definite.
    """
    if A.shape == (2, 2) and B.shape == (2, 2):
        d = np.log(np.array([*_cholesky2("A", A), *_cholesky2("B", B), *_cholesky2("(A+B)/2", 0.5 * (A + B))]))
        la, lb, lm = 2.0 * (d[0] + d[1]), 2.0 * (d[2] + d[3]), 2.0 * (d[4] + d[5])
    else:
        la, lb, lm = (float(_logdet_spd(name, X)) for name, X in (("A", A), ("B", B), ("(A+B)/2", 0.5 * (A + B))))
    return float(max(lm - 0.5 * (la + lb), 0.0))


def _cholesky2(name: str, A: FloatArray) -> tuple[float, float]:
    """Diagonal (L00, L11) of the Cholesky factor of the symmetrised 2 × 2 A, as LAPACK's; `NotSPD` otherwise."""
    a, b, d = float(A[0, 0]), 0.5 * (float(A[1, 0]) + float(A[0, 1])), float(A[1, 1])
    if not a > 0.0:
        raise NotSPD(f"{name}: not positive definite")
    l0 = math.sqrt(a)
    l1 = b * (1.0 / l0)
    r = d - l1 * l1
    if not (r > 0.0 and math.isfinite(r) and math.isfinite(l0)):
        raise NotSPD(f"{name}: not positive definite")
    return l0, math.sqrt(r)


def desired_fme(u: ArrayLike, major: ArrayLike, minor: ArrayLike) -> FloatArray:
    """Desired ellipsoid ``U diag(major, minor, …, minor) Uᵀ`` with its first axis along ``u``.

    ``U`` is the left singular basis of ``u`` (thesis eq. 6.11), so the result equals
    ``major·uuᵀ + minor·(I − uuᵀ)`` for unit ``u``. Covers ``M_Free^des`` of eq. 6.12
    (``major=ζ`` along the motion, ``minor=K`` across) and ``M_Stiff^des`` of eq. 6.13
    (``major=K`` along the contact force, ``minor=ζ`` across). ``major`` and ``minor``
    are eigenvalues, i.e. squared semi-axis lengths; "major" names the axis along
    ``u``, which need not be the longest.

    Args:
        u: (..., m) direction; normalised internally, must be non-zero.
        major: scalar or (...,) eigenvalue along ``u``, > 0.
        minor: scalar or (...,) eigenvalue across ``u``, > 0.

    Returns:
        (..., m, m) symmetric positive definite matrix.

    Raises:
        InvalidInput: non-finite input, zero-length ``u`` or a non-positive eigenvalue.
    """
    u = direction("u", u, None)
    a = positive("major", major)
    b = positive("minor", minor)
    m = u.shape[-1]
    uu = u[..., :, None] * u[..., None, :]
    a = a[..., None, None]
    b = b[..., None, None]
    return a * uu + b * (np.eye(m) - uu)


def desired_vme(u: ArrayLike, beta: ArrayLike) -> FloatArray:
    """Desired velocity manipulability ellipsoid ``M_des`` (thesis eq. 3.23).

    ``M_des = U diag(Σ, β, …, β) Uᵀ`` with ``u = UΣVᵀ``; ``u`` is normalised, so the
    eigenvalue along ``u`` is ``Σ = 1`` and every other eigenvalue is ``β`` (minor
    semi-axes ``sqrt(β)``). The thesis uses β = 0.01 (§3.5).

    Args:
        u: (..., m) desired direction of motion; normalised internally.
        beta: scalar or (...,) eigenvalue of the minor axes, > 0 (β = 0 would be the
            ideal line ellipsoid, which is singular).

    Returns:
        (..., m, m) symmetric positive definite matrix.

    Raises:
        InvalidInput: non-finite input, zero-length ``u`` or ``beta <= 0``.
    """
    positive("beta", beta)
    return desired_fme(u, 1.0, beta)

