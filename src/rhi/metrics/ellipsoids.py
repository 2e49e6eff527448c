"""Velocity and force manipulability ellipsoids and the scalar measures read off them.

Matrix convention: a symmetric positive semi-definite ``A`` (..., m, m) stands for the
ellipsoid ``{x : xᵀ A⁻¹ x <= 1}``, whose semi-axes are ``sqrt(eig(A))``. So the
velocity ellipsoid ``JJᵀ`` has semi-axes equal to the singular values of ``J``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from rhi.errors import InvalidInput, Singular
from rhi.metrics._common import (
    FloatArray,
    axis_ratio,
    direction,
    gram,
    inverse_gram,
    inverse_transmitted,
    jacobian,
    principal_axes_of_psd,
    radius_of_map,
    singular_values,
    square,
    torque_weights,
    volume_of_map,
)


def velocity_ellipsoid(J: ArrayLike) -> FloatArray:
    """Velocity manipulability ellipsoid (VME) ``JJᵀ`` (thesis eqs. 3.5, 4.2).

    Args:
        J: (..., m, n) Jacobian [(m/s)/(rad/s)].

    Returns:
        (..., m, m) symmetric PSD matrix; ``ẋᵀ(JJᵀ)⁻¹ẋ <= 1`` is the set of end-effector
        velocities reachable with ``|q̇| <= 1`` rad/s.
    """
    return gram(jacobian("J", J))


def effective_manipulability(J: ArrayLike, u: ArrayLike) -> FloatArray:
    """Effective manipulability ``ρ = (uᵀ(JJᵀ)†u)^(-1/2)`` (thesis eq. 3.6).

    The radius of the VME along ``u``: the end-effector speed along ``u`` obtained with
    a unit joint-velocity norm.

    Args:
        J: (..., m, n) Jacobian [(m/s)/(rad/s)].
        u: (..., m) direction; normalised internally, must be non-zero.

    Returns:
        (...,) ρ [m/s per rad/s]. At a singular configuration ρ is 0 when ``u`` has a
        component along a lost VME axis (the limit from nearby configurations) and is
        the radius of the flattened VME otherwise; never NaN.

    Raises:
        InvalidInput: bad shapes, non-finite entries or zero-length ``u``.
    """
    J = jacobian("J", J)
    u = direction("u", u, J.shape[-2])
    return radius_of_map(J, u)


def velocity_transmission(J: ArrayLike, u: ArrayLike) -> FloatArray:
    """Velocity transmission ratio ``σ = (uᵀ(JJᵀ)⁻¹u)^(-1/2)`` along ``u`` (thesis eq. 4.4).

    Eq. 4.4 as printed, ``(uᵀ(JJᵀ)u)^(-1/2)``, is identical to eq. 4.6, which
    contradicts the text ("σ is the reciprocal of λ"). This implements the velocity
    transmission of the thesis's reference [129]: the VME radius along ``u``, equal to
    `effective_manipulability`. ``σ·λ <= 1`` with equality along the VME principal axes.

    Args:
        J: (..., m, n) Jacobian.
        u: (..., m) direction; normalised internally, must be non-zero.

    Returns:
        (...,) σ [m/s per rad/s]; 0 along a direction lost at a singularity.
    """
    return effective_manipulability(J, u)


def reflected_friction(J: ArrayLike, u: ArrayLike) -> FloatArray:
    """Reflected friction factor ``λ = (uᵀ(JJᵀ)u)^(-1/2) = 1/|Jᵀu|`` (thesis eqs. 4.5, 4.6).

    The radius along ``u`` of the reflected friction ellipsoid ``F_xᵀ(JJᵀ)F_x <= 1``: the
    end-effector force along ``u`` that a unit joint-friction torque norm balances.

    Args:
        J: (..., m, n) Jacobian.
        u: (..., m) direction; normalised internally, must be non-zero.

    Returns:
        (...,) λ [N per N m]; ``inf`` where ``|Jᵀu| <= 1e-12 |J|_F`` (a singular
        configuration whose structure carries the load along ``u``).
    """
    J = jacobian("J", J)
    return inverse_transmitted(J, direction("u", u, J.shape[-2]))


def manipulability(J: ArrayLike) -> FloatArray:
    """Yoshikawa manipulability ``μ = sqrt(det(JJᵀ)) = σ₁σ₂…σ_m`` (thesis eq. 4.7).

    Args:
        J: (..., m, n) Jacobian.

    Returns:
        (...,) μ >= 0 (product of the singular values of ``J``); 0 at a singularity and
        whenever ``n < m``.
    """
    return volume_of_map(jacobian("J", J))


def log_det_gradient(J: ArrayLike, dJ: ArrayLike) -> FloatArray:
    """``∇_q log det(J Jᵀ) = 2 Σ_ij ((J Jᵀ)⁻¹ J)_ij ∂J_ij/∂q`` = 2 ∇ log μ (thesis eqs. 5.14, B.14).

    The one implementation of this gradient: `rhi.control.Manipulability` (½ of it: log μ) and the
    mobile controllers' ∇ det(J Jᵀ) (det(J Jᵀ) times it) use it.

    Args:
        J: (..., m, n) Jacobian of full row rank.
        dJ: (..., m, n, n) its derivative, [..., i, j, k] = ∂J_ij/∂q_k.

    Returns:
        (..., n) the gradient.

    Raises:
        InvalidInput: misshapen or non-finite input.
        Singular: J J ᵀ is singular.
    """
    J = jacobian("J", J)
    dJ = np.asarray(dJ, dtype=float)
    if dJ.shape[-3:] != J.shape[-2:] + (J.shape[-1],) or not np.isfinite(dJ).all():
        raise InvalidInput(f"dJ: expected finite values of shape (..., {J.shape[-2]}, {J.shape[-1]}, {J.shape[-1]}), "
                           f"got {dJ.shape}")
    try:
        W = np.linalg.solve(J @ np.swapaxes(J, -1, -2), J)  # (J Jᵀ)⁻¹ J
    except np.linalg.LinAlgError:
        raise Singular("J: J Jᵀ is singular") from None
    return 2.0 * np.einsum("...ij,...ijk->...k", W, dJ)


def isotropy(J: ArrayLike) -> FloatArray:
    """Isotropy index, inverse condition number ``1/κ = σ_min/σ_max`` (thesis eq. 4.9).

    Args:
        J: (..., m, n) Jacobian.

    Returns:
        (...,) value in [0, 1]; 1 for an isotropic ``J``, 0 at a singularity, when
        ``n < m`` and for ``J = 0``.
    """
    return axis_ratio(singular_values(jacobian("J", J)))


def force_ellipsoid(J: ArrayLike, torque_max: ArrayLike | None = None) -> FloatArray:
    """Torque-weighted force manipulability ellipsoid ``M̂ = (J W W Jᵀ)⁻¹`` (thesis eqs. 6.7, 6.9).

    ``W = diag(1 / torque_max)``, so ``Fᵀ M̂⁻¹ F <= 1`` is the set of end-effector forces
    whose static torques ``JᵀF`` satisfy ``|W JᵀF| <= 1``. With ``torque_max=None``,
    ``W = I`` and this is the plain FME ``(JJᵀ)⁻¹`` of eq. 6.7.

    Args:
        J: (..., m, n) Jacobian [m/rad].
        torque_max: (n,) or (..., n) joint torque limits ``T_i`` [N m], all > 0, or a
            scalar for every joint, or None.

    Returns:
        (..., m, m) symmetric positive definite ``M̂`` [N² per (N m)²]; its semi-axes
        ``sqrt(eig(M̂))`` are the extreme force capabilities [N].

    Raises:
        InvalidInput: bad shapes, non-finite entries or a limit <= 0.
        Singular: ``J`` does not have full row rank (the FME is unbounded).
    """
    J = jacobian("J", J)
    w = torque_weights("torque_max", torque_max, J.shape[-1])
    B = J if w is None else J * w[..., None, :]
    return inverse_gram("J", B)


def directional_manipulability(J: ArrayLike, u: ArrayLike, torque_max: ArrayLike) -> FloatArray:
    """Directional manipulability ``DM = [uᵀ J Wᵀ W Jᵀ u]^(-1/2)`` (thesis eq. A.8).

    ``W = diag(1 / torque_max)``. DM is the radius along ``u`` of the torque-weighted
    force ellipsoid of `force_ellipsoid`: the largest force along ``u`` whose torques
    satisfy ``|W JᵀF| <= 1``. App. A.4.3 passes ``W_τ = diag(1,1,1,1,2.5,2.5,2.5)``
    directly, i.e. ``torque_max = [1, 1, 1, 1, 0.4, 0.4, 0.4]``.

    Args:
        J: (..., m, n) Jacobian [m/rad].
        u: (..., m) direction; normalised internally, must be non-zero.
        torque_max: (n,) or (..., n) torque limits [N m], all > 0 (or a scalar).

    Returns:
        (...,) DM [N]; ``inf`` where ``|W Jᵀ u| <= 1e-12 |W Jᵀ|_F`` (a singular
        configuration whose structure carries the load along ``u``).

    Raises:
        InvalidInput: bad shapes, non-finite entries, zero ``u`` or a limit <= 0.
    """
    J = jacobian("J", J)
    u = direction("u", u, J.shape[-2])
    if torque_max is None:
        raise InvalidInput("torque_max: required (the (n,) joint torque limits [N m])")
    w = torque_weights("torque_max", torque_max, J.shape[-1])
    return inverse_transmitted(J * w[..., None, :], u)


def ellipsoid_axes(A: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Principal semi-axes of the ellipsoid ``{x : xᵀ A⁻¹ x <= 1}`` (for plotting).

    Args:
        A: (..., m, m) symmetric positive semi-definite matrix, e.g. `velocity_ellipsoid`
            or `force_ellipsoid`.

    Returns:
        ``(lengths, directions)``: lengths (..., m) ``sqrt(eig(A))`` in descending order,
        and directions (..., m, m) whose column ``i`` is the unit axis of ``lengths[i]``,
        signed so that its largest-magnitude component is positive.

    Raises:
        InvalidInput: bad shape or non-finite entries.
        NotSPD: ``A`` is not symmetric or has a negative eigenvalue.
    """
    A = square("A", A)
    lengths, V = principal_axes_of_psd("A", A)
    k = np.argmax(np.abs(V), axis=-2, keepdims=True)
    sign = np.where(np.take_along_axis(V, k, axis=-2) < 0, -1.0, 1.0)
    return lengths, V * sign

