"""The manipulability measures the mobile controllers optimise, and their joint-space derivatives (thesis App. A, B).

* Directional manipulability H₂ (eq. A.8, the value is `rhi.metrics.directional_manipulability`),
  its joint-space gradient (A.9) and Cartesian gradient (A.10): the DM enhancement of App. A.
* Determinant manipulability H = det(J Jᵀ) (`rhi.metrics.manipulability` squared), its
  gradient (B.14) and Hessian (B.15–B.18): the tertiary objective of App. B. These are the
  readable references; the AMD controller runs the O(m²) kernel
  `rhi.control.mobile.kinematics.det_terms`, tested against them.

Derivative conventions: ``dJ[..., i, j, k] = ∂J_ij/∂q_k``, ``d2J[..., i, j, k, l] = ∂²J_ij/∂q_k∂q_l``.
"""

from __future__ import annotations

import numpy as np

from rhi._validate import as_array, unit_vector
from rhi.errors import InvalidInput
from rhi.metrics import directional_manipulability, log_det_gradient, manipulability


def dm_value(J, u, torque_max) -> np.ndarray:
    """Directional manipulability H₂ = [uᵀ J W_τᵀ W_τ Jᵀ u]^(-1/2), W_τ = diag(1/τ_lim) (thesis eq. A.8).

    `rhi.metrics.directional_manipulability`, except that it raises where Jᵀu = 0 (there
    the metric is inf and its gradient undefined).

    Args:
        J: (..., r, m) arm position Jacobian [m/rad].
        u: (..., r) direction (normalised internally).
        torque_max: (m,) τ_lim [N m]; App. A.4.3 uses `W_TAU_LIMITS`.

    Returns:
        (...,) H₂ [N].

    Raises:
        InvalidInput: bad shapes or values, or Jᵀu = 0 (singular along u).
    """
    h = directional_manipulability(J, u, torque_max)
    if not np.all(np.isfinite(h)):
        raise InvalidInput("J: Jᵀu = 0, the directional manipulability is unbounded (singular along u)")
    return h


def dm_gradient(J, dJ, u, torque_max) -> np.ndarray:
    """Joint-space gradient of the directional manipulability (thesis eq. A.9).

    ∂H₂/∂q_k = −½ s^(−3/2) ∂s/∂q_k = −H₂³ uᵀ ∂J/∂q_k W² Jᵀ u, with s = uᵀ J W² Jᵀ u
    (u constant). Eq. A.9 prints the factor as H₂^(−3/2); with H₂ = s^(−1/2) the chain
    rule gives s^(−3/2) = H₂³, which is what finite differences confirm.

    Args:
        J: (..., r, m) arm Jacobian.
        dJ: (..., r, m, m) ∂J/∂q.
        u: (..., r) direction.
        torque_max: (m,) τ_lim [N m].

    Returns:
        (..., m) ∇_{q_m} H₂ [N/rad].
    """
    h = dm_value(J, u, torque_max)
    J = as_array("J", J, ndim_min=2)
    u = unit_vector("u", u, J.shape[-2])
    dJ = as_array("dJ", dJ, shape_tail=J.shape[-2:] + (J.shape[-1],))
    w2 = np.broadcast_to(1.0 / as_array("torque_max", torque_max) ** 2, J.shape[:-2] + (J.shape[-1],))
    v = np.einsum("...ij,...i->...j", J, u)  # Jᵀu
    ds = 2.0 * np.einsum("...i,...ijk,...j->...k", u, dJ, w2 * v)
    return -0.5 * h[..., None] ** 3 * ds


def dm_cartesian_gradient(J, dJ, u, torque_max) -> np.ndarray:
    """Cartesian gradient ∇_x H₂ = ∇_{q_m} H₂ J_m⁺ (thesis eq. A.10).

    The change of H₂ per unit end-effector displacement when the arm follows it with the
    minimum-norm joint motion q̇_m = J_m⁺ ẋ.

    Args:
        J: (..., r, m) arm Jacobian (full row rank).
        dJ: (..., r, m, m) ∂J/∂q.
        u: (..., r) direction.
        torque_max: (m,) τ_lim [N m].

    Returns:
        (..., r) ∇_x H₂ [N/m].
    """
    g = dm_gradient(J, dJ, u, torque_max)
    return np.einsum("...k,...kr->...r", g, np.linalg.pinv(np.asarray(J, dtype=float)))


def manipulability_det(J) -> np.ndarray:
    """H = det(J Jᵀ) = μ², the squared Yoshikawa manipulability `rhi.metrics.manipulability` (thesis §B.3.2).

    Args:
        J: (..., r, m) Jacobian.

    Returns:
        (...,) H.
    """
    return manipulability(J) ** 2


def manipulability_det_gradient(J, dJ) -> np.ndarray:
    """∇H = det(Ψ) tr[Ψ⁻¹(∂J Jᵀ + J ∂Jᵀ)], Ψ = J Jᵀ (thesis eq. B.14).

    Args:
        J: (..., r, m) Jacobian of full row rank.
        dJ: (..., r, m, m) ∂J/∂q.

    Returns:
        (..., m) ∇_q H.
    """
    J = as_array("J", J, ndim_min=2)
    dJ = as_array("dJ", dJ, shape_tail=J.shape[-2:] + (J.shape[-1],))
    # tr(Ψ⁻¹ ∂_kΨ) = ∇ log det Ψ
    return np.linalg.det(J @ np.swapaxes(J, -1, -2))[..., None] * log_det_gradient(J, dJ)


def manipulability_det_hessian(J, dJ, d2J) -> np.ndarray:
    """∇²H of H = det(J Jᵀ) (thesis eqs. B.15–B.18).

    ∂_pq H = det Ψ [tr(Ψ⁻¹∂_qΨ) tr(Ψ⁻¹∂_pΨ) − tr(Ψ⁻¹∂_qΨ Ψ⁻¹∂_pΨ) + tr(Ψ⁻¹∂_pqΨ)] with
    ∂_pqΨ = ∂_pqJ Jᵀ + ∂_pJ ∂_qJᵀ + ∂_qJ ∂_pJᵀ + J ∂_pqJᵀ (B.15, B.17).

    Args:
        J: (..., r, m) Jacobian of full row rank.
        dJ: (..., r, m, m) ∂J/∂q.
        d2J: (..., r, m, m, m) ∂²J/∂q².

    Returns:
        (..., m, m) symmetric Hessian.
    """
    J = as_array("J", J, ndim_min=2)
    r, m = J.shape[-2:]
    dJ = as_array("dJ", dJ, shape_tail=(r, m, m))
    d2J = as_array("d2J", d2J, shape_tail=(r, m, m, m))
    batch = J.shape[:-2]
    Psi = J @ np.swapaxes(J, -1, -2)
    G = np.linalg.inv(Psi)
    dJk = np.moveaxis(dJ, -1, -3)  # (..., m_k, r, m)
    P1 = dJk @ np.swapaxes(J, -1, -2)[..., None, :, :]  # ∂_kJ Jᵀ: (..., m, r, r)
    dPsi = P1 + np.swapaxes(P1, -1, -2)
    M = G[..., None, :, :] @ dPsi  # Ψ⁻¹ ∂_kΨ
    t1 = np.trace(M, axis1=-2, axis2=-1)  # (..., m)
    Mf = M.reshape(batch + (m, r * r))
    t2 = Mf @ np.swapaxes(np.swapaxes(M, -1, -2).reshape(batch + (m, r * r)), -1, -2)  # tr(M_p M_q)
    W = (G @ J).reshape(batch + (1, r * m))
    t3 = (W @ d2J.reshape(batch + (r * m, m * m))).reshape(batch + (m, m))
    K = (G @ dJ.reshape(batch + (r, m * m))).reshape(batch + (r * m, m))
    t3 = 2.0 * t3 + 2.0 * np.swapaxes(K, -1, -2) @ dJ.reshape(batch + (r * m, m))
    det = np.linalg.det(Psi)[..., None, None]
    return det * (t1[..., :, None] * t1[..., None, :] - t2 + t3)
