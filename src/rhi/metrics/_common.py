"""Shared checks and numerical kernels of `rhi.metrics` (private).

Conventions used throughout the subpackage:

* A Jacobian ``J`` has shape ``(..., m, n)`` (``m`` task rows, ``n`` joints); leading
  axes broadcast against the leading axes of every other batched argument.
* A symmetric positive semi-definite matrix ``A`` of shape ``(..., m, m)`` stands for
  the ellipsoid ``{x : x^T A^+ x <= 1}``; its semi-axes are ``sqrt(eig(A))``.
* A matrix (or the whitened Jacobian of a weighted inverse) counts as singular when its
  smallest singular value is at most ``SINGULAR_RTOL`` times its largest.
"""

from __future__ import annotations

import math
from typing import Any, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from rhi._validate import all_finite, as_array, unit_vector
from rhi.errors import InvalidInput, NotSPD, Singular
from rhi.metrics._svd2 import singular_values2, svd2

FloatArray = NDArray[np.floating[Any]]

#: Relative threshold below which a singular value counts as zero.
SINGULAR_RTOL: float = 1e-12
#: Relative tolerance of the symmetry check on matrices that must be symmetric.
SYMMETRY_RTOL: float = 1e-9
#: Components of a unit direction smaller than this along a lost ellipsoid axis are ignored.
DIRECTION_ATOL: float = 1e-10

_TINY = np.finfo(float).tiny


def jacobian(name: str, J: ArrayLike) -> FloatArray:
    """Return ``J`` as a finite float array of shape ``(..., m, n)`` with m, n >= 1."""
    arr = as_array(name, J, ndim_min=2)
    if arr.shape[-1] == 0 or arr.shape[-2] == 0:
        raise InvalidInput(f"{name}: expected shape (..., m, n) with m, n >= 1, got {arr.shape}")
    return arr


def square(name: str, A: ArrayLike, size: int | None = None) -> FloatArray:
    """Return ``A`` as a finite float array of shape ``(..., k, k)`` (``k == size`` if given)."""
    arr = as_array(name, A, ndim_min=2)
    k = arr.shape[-1]
    if arr.shape[-2] != k or k == 0 or (size is not None and k != size):
        want = "(..., k, k)" if size is None else f"(..., {size}, {size})"
        raise InvalidInput(f"{name}: expected shape {want}, got {arr.shape}")
    return arr


def direction(name: str, u: ArrayLike, m: int | None) -> FloatArray:
    """Unit vectors: ``u`` of shape ``(..., m)`` (any m if None) normalised to unit length."""
    return unit_vector(name, u, m)


def positive(name: str, value: ArrayLike, *, shape_tail: tuple[int | None, ...] = ()) -> FloatArray:
    """Return ``value`` as a finite float array whose entries are all > 0."""
    arr = as_array(name, value, shape_tail=shape_tail)
    if (arr <= 0).any():
        raise InvalidInput(f"{name}: every entry must be > 0, got min {float(np.min(arr))!r}")
    return arr


def _first_bad(mask: np.ndarray) -> str:
    """Describe the first batch index where ``mask`` is True (for error messages)."""
    idx = np.argwhere(np.atleast_1d(mask))
    if mask.ndim == 0 or idx.size == 0:
        return ""
    return f" at batch index {tuple(int(i) for i in idx[0])}"


def check_symmetric(name: str, A: FloatArray) -> None:
    """Raise `NotSPD` naming ``name`` if ``A`` is not symmetric to `SYMMETRY_RTOL`."""
    asym = abs(A - A.swapaxes(-1, -2)).max(axis=(-2, -1))
    scale = abs(A).max(axis=(-2, -1))
    bad = asym > SYMMETRY_RTOL * np.maximum(scale, _TINY)
    if bad.any():
        raise NotSPD(f"{name}: not symmetric{_first_bad(bad)}")


def cholesky(name: str, A: FloatArray) -> FloatArray:
    """Lower Cholesky factor of the symmetric positive definite ``A``; `NotSPD` otherwise."""
    check_symmetric(name, A)
    A = 0.5 * (A + A.swapaxes(-1, -2))
    try:
        L = np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        raise NotSPD(f"{name}: not positive definite") from None
    if not all_finite(L) or (L.diagonal(axis1=-2, axis2=-1) <= 0).any():
        raise NotSPD(f"{name}: not positive definite")
    return L


def whiten(J: FloatArray, L: FloatArray | None) -> FloatArray:
    """Return ``B = J L^{-T}`` so that ``B B^T = J Q^{-1} J^T`` for ``Q = L L^T`` (``J`` if no ``L``)."""
    if L is None:
        return J
    return np.linalg.solve(L, J.swapaxes(-1, -2)).swapaxes(-1, -2)


def whitened(name: str, J: FloatArray, M: FloatArray) -> FloatArray:
    """``B = J L^{-T}`` with the Cholesky factor ``M = L L^T`` of the SPD ``M`` (..., n, n); `NotSPD` naming ``name`` otherwise.

    Large batches take the compiled kernel of `rhi.metrics._small` (the same factor and solve, one loop).
    The batch axes of J (..., m, n) and M must broadcast.
    """
    lead = np.broadcast_shapes(J.shape[:-2], M.shape[:-2])
    if math.prod(lead) < SMALL_BATCH_MIN:
        return whiten(J, cholesky(name, M))
    from rhi.metrics._small import whiten as whiten_batch  # Numba: imported on the first large batch

    m, n = J.shape[-2:]
    Jb = np.ascontiguousarray(np.broadcast_to(J, lead + (m, n)), dtype=float).reshape(-1, m, n)
    Mb = np.ascontiguousarray(np.broadcast_to(M, lead + (n, n)), dtype=float).reshape(-1, n, n)
    B = np.empty_like(Jb)
    bad = np.empty(Jb.shape[0], dtype=np.int8)
    whiten_batch(Jb, Mb, SYMMETRY_RTOL, B, bad)
    if (bad == 1).any():
        raise NotSPD(f"{name}: not symmetric{_first_bad((bad == 1).reshape(lead))}")
    if bad.any():
        raise NotSPD(f"{name}: not positive definite")
    return B.reshape(lead + (m, n))


def inertia_along(name: str, J: FloatArray, M: FloatArray, u: FloatArray) -> FloatArray:
    """Λ (...,) = (uᵀ J M⁻¹ Jᵀ u)⁻¹ of a large batch by the compiled kernel of `rhi.metrics._small`.

    As ``1 / |Bᵀu|²`` with ``B = whitened(name, J, M)`` (inf where ``|Bᵀu| <= SINGULAR_RTOL |B|_F``).
    J (..., m, n), M (..., n, n) and unit u (..., m) broadcast over their batch axes; `NotSPD` naming ``name``.
    """
    from rhi.metrics._small import inertia_along as kernel  # Numba: imported on the first large batch

    m, n = J.shape[-2:]
    lead = np.broadcast_shapes(J.shape[:-2], M.shape[:-2], u.shape[:-1])
    Jb = np.ascontiguousarray(np.broadcast_to(J, lead + (m, n)), dtype=float).reshape(-1, m, n)
    Mb = np.ascontiguousarray(np.broadcast_to(M, lead + (n, n)), dtype=float).reshape(-1, n, n)
    ub = np.ascontiguousarray(np.broadcast_to(u, lead + (m,)), dtype=float).reshape(-1, m)
    lam = np.empty(Jb.shape[0])
    bad = np.empty(Jb.shape[0], dtype=np.int8)
    kernel(Jb, Mb, ub, SYMMETRY_RTOL, SINGULAR_RTOL, lam, bad)
    if (bad == 1).any():
        raise NotSPD(f"{name}: not symmetric{_first_bad((bad == 1).reshape(lead))}")
    if bad.any():
        raise NotSPD(f"{name}: not positive definite")
    return lam.reshape(lead)


def frobenius_norm(A: FloatArray) -> FloatArray:
    """Frobenius norm over the last two axes of ``A`` (..., m, n)."""
    return np.sqrt((A * A).sum(axis=(-2, -1)))


def _full_row_rank_svd(name: str, B: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Thin SVD ``(U, s, Vt)`` of ``B`` (..., m, n), which must have full row rank.

    Raises:
        Singular: ``B`` has fewer columns than rows or a singular value below
            ``SINGULAR_RTOL`` times its largest one.
    """
    m, n = B.shape[-2:]
    if n < m:
        raise Singular(f"{name}: {m} rows but only {n} columns, so it cannot have full row rank")
    U, s, Vt = np.linalg.svd(B, full_matrices=False)
    bad = s[..., -1] <= SINGULAR_RTOL * s[..., 0]
    if bad.any():
        raise Singular(f"{name}: singular (rank < {m} rows){_first_bad(bad)}")
    return U, s, Vt


def full_row_rank_pinv(name: str, B: FloatArray) -> FloatArray:
    """Moore-Penrose inverse ``B^T (B B^T)^{-1}`` of a full-row-rank ``B`` (raises as `_full_row_rank_svd`)."""
    U, s, Vt = _full_row_rank_svd(name, B)
    return Vt.swapaxes(-1, -2) @ (U.swapaxes(-1, -2) / s[..., :, None])


def inverse_gram(name: str, B: FloatArray) -> FloatArray:
    """Return ``(B B^T)^{-1}`` for a full-row-rank ``B`` (..., m, n), from `principal_axes_of_map`.

    Raises:
        Singular: as `_full_row_rank_svd`.
    """
    m, n = B.shape[-2:]
    if n < m:
        raise Singular(f"{name}: {m} rows but only {n} columns, so it cannot have full row rank")
    s, U = principal_axes_of_map(B)
    bad = s[..., -1] <= SINGULAR_RTOL * s[..., 0]
    if bad.any():
        raise Singular(f"{name}: singular (rank < {m} rows){_first_bad(bad)}")
    out = (U / s[..., None, :] ** 2) @ U.swapaxes(-1, -2)
    return 0.5 * (out + out.swapaxes(-1, -2))


def pad_axes(s: FloatArray, m: int) -> FloatArray:
    """Zero-pad the singular values ``s`` (..., k) of an (..., m, k) map to m semi-axes."""
    k = s.shape[-1]
    return s if k >= m else np.concatenate([s, np.zeros(s.shape[:-1] + (m - k,))], axis=-1)


#: Batches of at least this many maps take the closed forms and compiled kernels (`rhi.metrics._svd2`,
#: `rhi.metrics._small`): below it LAPACK's per-matrix calls cost less than their setup.
SMALL_BATCH_MIN = 64


def _batch_count(A: FloatArray) -> int:
    """Number of matrices in the batch A (..., k, l)."""
    return math.prod(A.shape[:-2])


def _closed_form(B: FloatArray) -> bool:
    """Whether B (..., m, n) is a batch of two-row maps large enough for the closed-form SVD."""
    return B.shape[-2] == 2 and B.shape[-1] >= 2 and _batch_count(B) >= SMALL_BATCH_MIN


def _jacobi(B: FloatArray) -> bool:
    """Whether B (..., m, n) is a batch of maps with 3 <= m <= n large enough for the compiled Jacobi SVD."""
    return 3 <= B.shape[-2] <= B.shape[-1] and _batch_count(B) >= SMALL_BATCH_MIN


def _svd_rows(B: FloatArray, want_u: bool) -> tuple[FloatArray, FloatArray]:
    """``(s, U)`` of B (..., m, n) from the compiled Jacobi SVD (`rhi.metrics._small.svd_rows`; U empty if not wanted)."""
    from rhi.metrics._small import svd_rows  # Numba: imported on the first large batch

    m = B.shape[-2]
    flat = np.ascontiguousarray(B, dtype=float).reshape((-1,) + B.shape[-2:])
    s = np.empty((flat.shape[0], m))
    U = np.empty((flat.shape[0], m, m) if want_u else (0, m, m))
    svd_rows(flat, want_u, s, U)
    return s.reshape(B.shape[:-1]), U.reshape(B.shape[:-2] + (m, m)) if want_u else U


#: `radius_rows` takes the triangle's values where ‖L‖_F ‖L⁻¹‖_F (>= the condition number) is at most this; the
#: SVD takes the others (far from `SINGULAR_RTOL`: the two agree to ~1e-16 times it, relative).
_TRIANGLE_COND_MAX = 1e4
#: Three-row maps take the closed form of their Gram G = BBᵀ where ‖G‖_F ‖G⁻¹‖_F is at most this (forming G squares
#: the condition number: the error stays ~1e-12 relative), the triangle the others.
_GRAM_COND_MAX = 1e4


def _triangular(B: FloatArray) -> bool:
    """Whether B (..., m, n) is a batch of maps with 2 <= m <= n large enough for the compiled triangle."""
    return 2 <= B.shape[-2] <= B.shape[-1] and _batch_count(B) >= SMALL_BATCH_MIN


def _triangle_measures(B: FloatArray, u: FloatArray | None) -> tuple[FloatArray, FloatArray]:
    """(ρ along u (...,), empty without u; μ (...,)) of a `_triangular` batch B (..., m, n), as the SVD route gives them."""
    from rhi.metrics._small import gram3_rows, radius_rows  # Numba: imported on the first large batch

    m, n = B.shape[-2:]
    lead = B.shape[:-2] if u is None else np.broadcast_shapes(B.shape[:-2], u.shape[:-1])
    flat = np.ascontiguousarray(np.broadcast_to(B, lead + (m, n)), dtype=float).reshape(-1, m, n)
    uf = (np.empty((0, m)) if u is None
          else np.ascontiguousarray(np.broadcast_to(u, lead + (m,)), dtype=float).reshape(-1, m))
    rho, mu, hard = np.empty(flat.shape[0]), np.empty(flat.shape[0]), np.empty(flat.shape[0], dtype=np.int8)
    if m == 3:  # the closed form first; the triangle for the maps it leaves
        gram3_rows(flat, uf, _GRAM_COND_MAX, rho, mu, hard)
        k = np.flatnonzero(hard)
        if k.size:
            rho_k, mu_k, hard_k = np.empty(k.size), np.empty(k.size), np.empty(k.size, dtype=np.int8)
            radius_rows(flat[k], uf[k] if u is not None else uf, _TRIANGLE_COND_MAX, rho_k, mu_k, hard_k)
            rho[k], mu[k], hard[k] = rho_k, mu_k, hard_k
    else:
        radius_rows(flat, uf, _TRIANGLE_COND_MAX, rho, mu, hard)
    k = np.flatnonzero(hard)
    if k.size:
        s, U = principal_axes_of_map(flat[k])
        mu[k] = s.prod(axis=-1)
        if u is not None:
            rho[k] = radius_along(s, U, uf[k])
    return (np.empty(0) if u is None else rho.reshape(lead)), mu.reshape(lead)


def radius_of_map(B: FloatArray, u: FloatArray) -> FloatArray:
    """Radius (uᵀ(BBᵀ)⁻¹u)^(-1/2) along unit u (..., m) of the ellipsoid BBᵀ, B (..., m, n): `radius_along` its axes."""
    if _triangular(B):
        return _triangle_measures(B, u)[0]
    return radius_along(*principal_axes_of_map(B), u)


def volume_of_map(B: FloatArray) -> FloatArray:
    """Product of the semi-axes (..., ) of the ellipsoid BBᵀ, B (..., m, n): √det(BBᵀ), 0 when n < m."""
    if _triangular(B):
        return _triangle_measures(B, None)[1]
    return singular_values(B).prod(axis=-1)


def singular_values(B: FloatArray) -> FloatArray:
    """Descending semi-axis lengths (..., m) of the ellipsoid ``B B^T``, as in `principal_axes_of_map`."""
    if _closed_form(B):
        return singular_values2(B)
    if _jacobi(B):
        return _svd_rows(B, False)[0]
    return pad_axes(np.linalg.svd(B, compute_uv=False), B.shape[-2])


def principal_axes_of_map(B: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Semi-axes and directions of the ellipsoid ``B B^T`` (i.e. of ``{B x : |x| <= 1}``).

    Returns:
        ``(s, U)``: ``s`` (..., m) descending semi-axis lengths (zero-padded when the map
        has fewer columns than rows) and ``U`` (..., m, m) orthonormal directions as columns.
        Large batches of two-row maps (planar tasks) take the closed form of `rhi.metrics._svd2`, those of
        maps with 3 <= m <= n rows (spatial tasks) the compiled Jacobi SVD of `rhi.metrics._small`
        (LAPACK's values to round-off; each direction up to its sign, as LAPACK's own).
    """
    if _closed_form(B):
        return svd2(B)
    if _jacobi(B):
        return _svd_rows(B, True)
    U, s, _ = np.linalg.svd(B, full_matrices=True)
    return pad_axes(s, B.shape[-2]), U


def principal_axes_of_psd(name: str, A: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Semi-axes ``sqrt(eig(A))`` (descending) and eigenvectors of a symmetric PSD ``A``.

    Raises:
        NotSPD: ``A`` is not symmetric or has an eigenvalue below ``-SINGULAR_RTOL``
            times its largest eigenvalue magnitude.
    """
    check_symmetric(name, A)
    A = 0.5 * (A + A.swapaxes(-1, -2))
    w, V = np.linalg.eigh(A)
    scale = abs(w).max(axis=-1, keepdims=True)
    if (w < -SINGULAR_RTOL * np.maximum(scale, _TINY)).any():
        raise NotSPD(f"{name}: has a negative eigenvalue (not positive semi-definite)")
    w = np.clip(w, 0.0, None)[..., ::-1]
    V = V[..., ::-1]
    return np.sqrt(w), V


def radius_along(s: FloatArray, U: FloatArray, u: FloatArray) -> FloatArray:
    """Radius ``(u^T A^{-1} u)^{-1/2}`` of the ellipsoid with semi-axes ``s`` along ``U``.

    ``u`` (..., m) must be unit length. Axes whose length is at most ``SINGULAR_RTOL``
    times the longest are *lost* (the ellipsoid is flat along them): the radius is 0
    when ``u`` has a component larger than ``DIRECTION_ATOL`` along a lost axis (the
    limit from nearby non-singular matrices) and that component is ignored otherwise.
    A zero ellipsoid has radius 0 everywhere. Scale-invariant: the semi-axes are divided by the longest
    before squaring, so semi-axes of 1e-200 or 1e200 neither underflow nor overflow.
    """
    c = np.einsum("...ij,...i->...j", U, u)
    top = s[..., :1]
    lost = s <= SINGULAR_RTOL * top  # every axis of a zero ellipsoid: q = 0, radius 0
    blocked = (lost & (abs(c) > DIRECTION_ATOL)).any(axis=-1)
    w = c * np.where(lost, 0.0, top / np.where(lost, 1.0, s))  # c_i s_max / s_i, 0 along lost axes
    q = (w * w).sum(axis=-1)  # s_max² uᵀA⁻¹u, in [|c|², |c|² / SINGULAR_RTOL²]
    nonzero = (q > 0) & ~blocked
    return np.where(nonzero, top[..., 0] / np.sqrt(np.where(nonzero, q, 1.0)), 0.0)


def gram(B: FloatArray) -> FloatArray:
    """The symmetric ``B Bᵀ`` (..., m, m) of B (..., m, n) (symmetrised against round-off)."""
    A = B @ B.swapaxes(-1, -2)
    return 0.5 * (A + A.swapaxes(-1, -2))


def inverse_transmitted(B: FloatArray, u: FloatArray) -> FloatArray:
    """``1 / |Bᵀu|`` (...,) of B (..., m, n) along unit u (..., m), ``inf`` where ``|Bᵀu| <= SINGULAR_RTOL |B|_F``."""
    return inverse_norm(np.einsum("...ij,...i->...j", B, u), frobenius_norm(B))


def axis_ratio(s: FloatArray) -> FloatArray:
    """Shortest over longest of the descending semi-axes ``s`` (..., m): 1/κ, 0 for a zero ellipsoid."""
    nonzero = s[..., 0] > 0
    return np.where(nonzero, s[..., -1] / np.where(nonzero, s[..., 0], 1.0), 0.0)


def inverse_norm(v: FloatArray, scale: FloatArray) -> FloatArray:
    """``1 / |v|`` along the last axis, ``inf`` where ``|v| <= SINGULAR_RTOL * scale``."""
    nv = np.sqrt((v * v).sum(axis=-1))
    zero = nv <= SINGULAR_RTOL * scale
    return np.where(zero, np.inf, 1.0 / np.where(zero, 1.0, nv))


@overload
def torque_weights(name: str, torque_max: None, n: int) -> None: ...
@overload
def torque_weights(name: str, torque_max: ArrayLike, n: int) -> FloatArray: ...
def torque_weights(name: str, torque_max: ArrayLike | None, n: int) -> FloatArray | None:
    """Return ``1 / torque_max`` of shape (..., n) (None stays None); limits must be > 0."""
    if torque_max is None:
        return None
    t = positive(name, torque_max, shape_tail=(n,) if np.ndim(torque_max) >= 1 else ())
    if t.ndim == 0:
        t = np.broadcast_to(t, (n,))
    return 1.0 / t
