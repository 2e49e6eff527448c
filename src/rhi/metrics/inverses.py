"""Generalised inverses of a Jacobian and the null-space projectors built from them."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from rhi._linalg import torque_null_projector
from rhi.errors import InvalidInput
from rhi.metrics._common import FloatArray, cholesky, full_row_rank_pinv, jacobian, square, whiten


def _weighted(J: ArrayLike, Q: ArrayLike | None, q_name: str) -> tuple[FloatArray, FloatArray]:
    """Return ``(J, J_dagger)`` for the ``Q``-weighted right inverse of ``J``."""
    J = jacobian("J", J)
    if Q is None:
        return J, full_row_rank_pinv("J", J)
    Q = square(q_name, Q)
    if Q.shape[-1] != J.shape[-1]:
        raise InvalidInput(f"{q_name}: expected shape (..., {J.shape[-1]}, {J.shape[-1]}) to match J, got {Q.shape}")
    try:
        np.broadcast_shapes(J.shape[:-2], Q.shape[:-2])
    except ValueError:
        raise InvalidInput(f"{q_name}: batch shape {Q.shape[:-2]} does not broadcast with J's {J.shape[:-2]}") from None
    L = cholesky(q_name, Q)
    return J, right_inverse(whiten(J, L), L)


def right_inverse(B: FloatArray, L: FloatArray) -> FloatArray:
    """``J† = L⁻ᵀ B⁺`` (..., n, m) from the whitened ``B = J L⁻ᵀ`` (..., m, n) and the factor ``Q = L Lᵀ``.

    Raises:
        Singular: B loses rank.
    """
    return np.linalg.solve(np.swapaxes(L, -1, -2), full_row_rank_pinv("J", B))


def weighted_pinv(J: ArrayLike, Q: ArrayLike | None = None) -> FloatArray:
    """Weighted pseudo-inverse ``J† = Q⁻¹Jᵀ(JQ⁻¹Jᵀ)⁻¹`` (thesis eq. 3.4).

    ``J† ẋ`` is the joint velocity of least ``Q``-weighted norm that produces ``ẋ``
    (the solution of eq. 3.3). With ``Q=None`` this is the Moore-Penrose inverse.

    Args:
        J: (..., m, n) Jacobian [m/rad or (m/s)/(rad/s)].
        Q: (..., n, n) symmetric positive definite weight, or None for the identity.

    Returns:
        (..., n, m) weighted right inverse, ``J @ J† = I``.

    Raises:
        InvalidInput: bad shapes or non-finite entries.
        NotSPD: ``Q`` is not symmetric positive definite.
        Singular: ``J`` does not have full row rank.
    """
    return _weighted(J, Q, "Q")[1]


def dynamic_pinv(J: ArrayLike, M: ArrayLike) -> FloatArray:
    """Dynamically consistent inverse ``J# = M⁻¹Jᵀ(JM⁻¹Jᵀ)⁻¹`` (thesis eqs. 3.20, 5.3).

    Args:
        J: (..., m, n) Jacobian.
        M: (..., n, n) joint-space inertia matrix [kg m²], symmetric positive definite.

    Returns:
        (..., n, m) inverse ``J#``; ``J#ᵀ`` maps joint torques to the end-effector
        force they produce dynamically.

    Raises:
        InvalidInput: bad shapes or non-finite entries.
        NotSPD: ``M`` is not symmetric positive definite.
        Singular: ``J`` does not have full row rank.
    """
    return _weighted(J, M, "M")[1]


def nullspace_projector(J: ArrayLike, M: ArrayLike | None = None) -> FloatArray:
    """Torque-level null-space projector ``I − JᵀJ#ᵀ`` (thesis eqs. 3.20, 7.5).

    With ``M`` the projector is dynamically consistent: projected torques produce no
    end-effector acceleration (``J M⁻¹ N = 0``). With ``M=None`` it is the kinematic
    projector ``I − JᵀJ⁺ᵀ`` (symmetric; projected torques lie in the null space of ``J``
    and produce no end-effector force statically).

    Args:
        J: (..., m, n) Jacobian.
        M: (..., n, n) joint-space inertia matrix [kg m²], or None.

    Returns:
        (..., n, n) projector ``N`` with ``N @ N = N`` and ``N @ Jᵀ = 0``.

    Raises:
        InvalidInput: bad shapes or non-finite entries.
        NotSPD: ``M`` is not symmetric positive definite.
        Singular: ``J`` does not have full row rank.
    """
    J, Jinv = _weighted(J, M, "M")
    return torque_null_projector(J, Jinv)


def velocity_nullspace_projector(J: ArrayLike, Q: ArrayLike | None = None) -> FloatArray:
    """Velocity-level null-space projector ``I − J†J`` (thesis eq. 3.4).

    Args:
        J: (..., m, n) Jacobian.
        Q: (..., n, n) symmetric positive definite weight of ``J†``, or None.

    Returns:
        (..., n, n) projector ``P`` with ``J @ P = 0`` and ``P @ P = P``.

    Raises:
        InvalidInput: bad shapes or non-finite entries.
        NotSPD: ``Q`` is not symmetric positive definite.
        Singular: ``J`` does not have full row rank.
    """
    J, Jinv = _weighted(J, Q, "Q")
    n = J.shape[-1]
    return np.eye(n) - Jinv @ J
