"""Closed-form SVD of a batch of two-row matrices (private; the planar maps' hot path).

A planar device's task Jacobian has two rows. NumPy's batched ``svd`` calls LAPACK once per
matrix (≈ 2.5 µs each), which made the SVD most of a workspace map's or a design
evaluation's time. Here the batch is reduced with array operations only:

1. scale each matrix by its largest entry (no overflow or underflow in the squares);
2. pivot the longer row first and reduce ``B = L Q`` (one Gram–Schmidt step with one
   re-orthogonalisation, as accurate as a Householder step for two rows), so that
   ``L = [[f, 0], [g, h]]`` with ``f >= 0``, ``h >= 0``;
3. singular values of the triangle as LAPACK's ``dlasv2`` does: ``σ₁ = (√((f+h)² + g²) +
   √((f−h)² + g²)) / 2`` and ``σ₂ = f h / σ₁``, both to a few ulps (no cancellation);
4. left singular vectors from the angle of the principal axis of ``L Lᵀ``.

The singular values agree with LAPACK's to round-off (relative ≈ 1e-15 for ``σ₁`` and
``κ``·1e-16 for ``σ₂``, as LAPACK's own); the directions agree up to the sign of each
column, and like LAPACK's they are only as well determined as the gap ``σ₁ − σ₂``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.floating[Any]]


def _triangle(B: FloatArray) -> tuple[FloatArray, ...]:
    """``(scale, swap, f, g, h, s1, s2)`` of B (..., 2, n): ``B / scale = P [[f, 0], [g, h]] Q`` (steps 1–3)."""
    scale = np.abs(B).max(axis=(-2, -1))
    zero = scale == 0.0
    Bs = B / np.where(zero, 1.0, scale)[..., None, None]
    r1, r2 = Bs[..., 0, :], Bs[..., 1, :]
    n1 = np.einsum("...i,...i->...", r1, r1)
    n2 = np.einsum("...i,...i->...", r2, r2)
    swap = n2 > n1
    sw = swap[..., None]
    a, b = np.where(sw, r2, r1), np.where(sw, r1, r2)  # a: the longer row (> 0 unless B = 0)
    f = np.sqrt(np.maximum(n1, n2))
    e = a / np.where(zero, 1.0, f)[..., None]
    g = np.einsum("...i,...i->...", b, e)
    w = b - g[..., None] * e
    c = np.einsum("...i,...i->...", w, e)  # re-orthogonalise once
    w -= c[..., None] * e
    g = g + c
    h = np.sqrt(np.einsum("...i,...i->...", w, w))
    s1 = 0.5 * (np.hypot(f + h, g) + np.hypot(f - h, g))
    s2 = f * h / np.where(s1 > 0, s1, 1.0)
    return scale, swap, f, g, h, s1, s2


def singular_values2(B: FloatArray) -> FloatArray:
    """Singular values (..., 2), descending, of B (..., 2, n), n >= 2, finite."""
    scale, _, _, _, _, s1, s2 = _triangle(B)
    return np.stack([s1, s2], axis=-1) * scale[..., None]


def svd2(B: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Singular values ``s`` (..., 2), descending, and left singular vectors ``U`` (..., 2, 2) of B (..., 2, n).

    Args:
        B: (..., 2, n) finite matrices, n >= 2.

    Returns:
        ``(s, U)``; column k of U is the direction of ``s[..., k]``.
    """
    scale, swap, f, g, h, s1, s2 = _triangle(B)
    theta = 0.5 * np.arctan2(2.0 * f * g, f * f - g * g - h * h)  # principal axis of L Lᵀ (step 4)
    ct, st = np.cos(theta), np.sin(theta)
    U = np.empty(B.shape[:-2] + (2, 2))
    # rows of U follow the pivot: B = P L Q with P swapping the rows when `swap`
    U[..., 0, 0], U[..., 1, 0] = np.where(swap, st, ct), np.where(swap, ct, st)
    U[..., 0, 1], U[..., 1, 1] = np.where(swap, ct, -st), np.where(swap, -st, ct)
    return np.stack([s1, s2], axis=-1) * scale[..., None], U
