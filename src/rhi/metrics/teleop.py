"""Teleoperation manipulability ellipsoid (TME) and index (TMI) of a master-slave pair."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import as_array
from rhi.errors import InvalidInput
from rhi.metrics._common import (
    FloatArray,
    jacobian,
    principal_axes_of_map,
    principal_axes_of_psd,
    radius_along,
    square,
)


def _tme(J_master: ArrayLike, J_slave: ArrayLike, H: ArrayLike | None) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return ``(sigma, U, tmi)`` of the selected intersecting ellipsoid (eqs. 4.12-4.17)."""
    Jm = jacobian("J_master", J_master)
    Js = jacobian("J_slave", J_slave)
    m = Js.shape[-2]
    if H is None:
        if Jm.shape[-2] != m:
            raise InvalidInput(
                f"J_master: has {Jm.shape[-2]} rows but J_slave has {m}; pass H to map the master into the task frame"
            )
        HJ = Jm
    else:
        H = as_array("H", H, ndim_min=2, shape_tail=(m, Jm.shape[-2]))
        HJ = H @ Jm
    try:
        np.broadcast_shapes(HJ.shape[:-2], Js.shape[:-2])
    except ValueError:
        raise InvalidInput(f"J_slave: batch shape {Js.shape[:-2]} does not broadcast with J_master's") from None
    sM, UM = principal_axes_of_map(HJ)  # master ME in the task frame, eq. 4.11a
    sS, US = principal_axes_of_map(Js)  # slave ME, eq. 4.11b
    # eta_1: where the master's principal axes meet the slave ME (eq. 4.14), and vice versa (eq. 4.16)
    eta1 = radius_along(sS[..., None, :], US[..., None, :, :], np.swapaxes(UM, -1, -2))
    eta2 = radius_along(sM[..., None, :], UM[..., None, :, :], np.swapaxes(US, -1, -2))
    sig1 = np.minimum(eta1, sM)  # eq. 4.12
    sig2 = np.minimum(eta2, sS)  # eq. 4.15
    lam1 = np.prod(sig1, axis=-1)
    lam2 = np.prod(sig2, axis=-1)
    pick1 = lam1 >= lam2  # eq. 4.17; ties go to the master's axes
    sig = np.where(pick1[..., None], sig1, sig2)
    U = np.where(pick1[..., None, None], UM, US)
    return sig, U, np.maximum(lam1, lam2)


def teleoperation_ellipsoid(J_master: ArrayLike, J_slave: ArrayLike, H: ArrayLike | None = None) -> FloatArray:
    """Teleoperation manipulability ellipsoid (TME) of a master-slave pair (thesis eqs. 4.11-4.16).

    Two candidate ellipsoids inside the intersection of the master ME (in the task
    frame) and the slave ME are built: one on the master's principal axes (eq. 4.12),
    each semi-axis the smaller of the master's ``σ_i^M`` and the distance ``η_i¹`` to
    the slave ME boundary (eq. 4.14); one on the slave's axes (eqs. 4.15, 4.16). The
    one of larger volume (larger product of semi-axes, eq. 4.17) is the TME.

    Args:
        J_master: (..., m_M, n_M) Jacobian of the master (haptic interface).
        J_slave: (..., m, n_S) Jacobian of the slave, in the task frame.
        H: (..., m, m_M) map of master task velocities into the slave/task frame (a
            rotation, or a rotation-projection such as eq. 4.26); identity if None.

    Returns:
        (..., m, m) symmetric PSD matrix ``U diag(σ_I²) Uᵀ``: the ellipsoid
        ``ẋᵀ(·)⁻¹ẋ <= 1`` with semi-axes ``σ_I`` [m/s per rad/s]
        (use `ellipsoid_axes` to read them back).

    Raises:
        InvalidInput: bad shapes or non-finite entries.
    """
    sig, U, _ = _tme(J_master, J_slave, H)
    A = (U * sig[..., None, :] ** 2) @ np.swapaxes(U, -1, -2)
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def tmi(J_master: ArrayLike, J_slave: ArrayLike, H: ArrayLike | None = None) -> FloatArray:
    """Teleoperation manipulability index ``λ = max(∏ ₁σ_i^I, ∏ ₂σ_i^I)`` (thesis eq. 4.17).

    Args:
        J_master: (..., m_M, n_M) Jacobian of the master.
        J_slave: (..., m, n_S) Jacobian of the slave, in the task frame.
        H: (..., m, m_M) map of master task velocities into the task frame; identity if None.

    Returns:
        (...,) λ >= 0, the product of the TME semi-axes; 0 if either robot is singular
        in a way that flattens the intersection.

    Raises:
        InvalidInput: bad shapes or non-finite entries.
    """
    return _tme(J_master, J_slave, H)[2]


def joint_energy(tme: ArrayLike, xdot: ArrayLike, *, axes_squared: bool = False) -> FloatArray:
    """Teleoperation joint kinetic-energy measure ``|q̇|² = ẋᵀ(J_T J_Tᵀ)⁻¹ẋ`` (thesis eqs. 4.21, 4.22).

    Eq. 4.22 writes ``J_T J_Tᵀ = U_T Λ_T U_Tᵀ`` with ``Λ_T = diag(σ_1^I, …, σ_m^I)``, the
    TME semi-axis *lengths* (not their squares, unlike eq. 4.2's ``JJᵀ`` whose
    eigenvalues are ``σ_i²``). By default this follows eq. 4.22 literally:
    ``|q̇|² = Σ_i (u_iᵀẋ)² / σ_i``. With ``axes_squared=True`` it uses ``Λ_T = diag(σ_i²)``,
    i.e. ``ẋᵀ tme⁻¹ ẋ``, the form consistent with eq. 4.2.

    Args:
        tme: (..., m, m) teleoperation manipulability ellipsoid from
            `teleoperation_ellipsoid` (semi-axes ``σ_I``).
        xdot: (..., m) task-frame end-effector velocity [m/s].
        axes_squared: use ``σ_i²`` instead of the thesis's ``σ_i`` in ``Λ_T``.

    Returns:
        (...,) ``|q̇|²`` (units follow the chosen convention); 0 for ``ẋ = 0`` and ``inf``
        when ``ẋ`` has a component along a TME axis of zero length.

    Raises:
        InvalidInput: bad shapes or non-finite entries.
        NotSPD: ``tme`` is not symmetric positive semi-definite.
    """
    A = square("tme", tme)
    x = as_array("xdot", xdot, ndim_min=1, shape_tail=(A.shape[-1],))
    sig, U = principal_axes_of_psd("tme", A)
    axes = sig if axes_squared else np.sqrt(sig)  # semi-axes of the ellipsoid U Λ_T Uᵀ
    speed = np.linalg.norm(x, axis=-1)
    moving = speed > 0
    u = x / np.where(moving, speed, 1.0)[..., None]
    u = np.where(moving[..., None], u, np.eye(A.shape[-1])[0])
    r = radius_along(axes, U, u)
    with np.errstate(divide="ignore"):
        ratio = np.where(r > 0, speed / np.where(r > 0, r, 1.0), np.inf)
    return np.where(moving, ratio**2, 0.0)
