"""Apparent (Cartesian) inertia of a manipulator and its value along a direction."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from rhi.errors import InvalidInput
from rhi.metrics._common import (
    SMALL_BATCH_MIN,
    FloatArray,
    direction,
    inertia_along,
    inverse_gram,
    inverse_transmitted,
    jacobian,
    square,
    whitened,
)


def _checked(J: ArrayLike, M: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """J (..., m, n) and M (..., n, n) as float arrays whose batch shapes broadcast."""
    J = jacobian("J", J)
    M = square("M", M)
    if M.shape[-1] != J.shape[-1]:
        raise InvalidInput(f"M: expected shape (..., {J.shape[-1]}, {J.shape[-1]}) to match J, got {M.shape}")
    try:
        np.broadcast_shapes(J.shape[:-2], M.shape[:-2])
    except ValueError:
        raise InvalidInput(f"M: batch shape {M.shape[:-2]} does not broadcast with J's {J.shape[:-2]}") from None
    return J, M


def _whitened_jacobian(J: ArrayLike, M: ArrayLike) -> FloatArray:
    """Return ``B = J L⁻ᵀ`` with ``M = L Lᵀ``, so that ``B Bᵀ = J M⁻¹ Jᵀ``."""
    return whitened("M", *_checked(J, M))


def apparent_inertia(J: ArrayLike, M: ArrayLike) -> FloatArray:
    """Apparent (end-effector) inertia ``M_x = (J M⁻¹ Jᵀ)⁻¹`` (thesis eq. 3.12).

    Args:
        J: (..., m, n) Jacobian [m/rad].
        M: (..., n, n) joint-space inertia matrix [kg m²], symmetric positive definite.

    Returns:
        (..., m, m) symmetric positive definite Cartesian inertia [kg].

    Raises:
        InvalidInput: bad shapes or non-finite entries.
        NotSPD: ``M`` is not symmetric positive definite.
        Singular: ``J`` does not have full row rank.
    """
    return inverse_gram("J", _whitened_jacobian(J, M))


def effective_inertia(J: ArrayLike, M: ArrayLike, u: ArrayLike) -> FloatArray:
    """Effective apparent inertia ``Λ = (uᵀ M_x⁻¹ u)⁻¹ = (uᵀ J M⁻¹ Jᵀ u)⁻¹`` (thesis eq. 3.13).

    The mass felt at the end-effector when pushing along ``u``; computed without
    inverting ``M_x``, so it is defined at singular configurations too.

    Args:
        J: (..., m, n) Jacobian [m/rad].
        M: (..., n, n) joint-space inertia matrix [kg m²], symmetric positive definite.
        u: (..., m) direction; normalised internally, must be non-zero.

    Returns:
        (...,) Λ [kg]; ``inf`` where ``|L⁻¹Jᵀu| <= 1e-12 |L⁻¹Jᵀ|_F`` (``M = LLᵀ``), i.e.
        where ``Jᵀu = 0``: a singular configuration that cannot accelerate along ``u``.

    Raises:
        InvalidInput: bad shapes, non-finite entries or zero-length ``u``.
        NotSPD: ``M`` is not symmetric positive definite.
    """
    J, M = _checked(J, M)
    u = direction("u", u, J.shape[-2])
    lead = np.broadcast_shapes(J.shape[:-2], M.shape[:-2], u.shape[:-1])
    if math.prod(lead) >= SMALL_BATCH_MIN:
        return inertia_along("M", J, M, u)
    r = inverse_transmitted(whitened("M", J, M), u)
    return r * r
