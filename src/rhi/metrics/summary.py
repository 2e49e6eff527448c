"""Every measure of one configuration from one factorisation of each matrix (what `rhi.all_measures` reports)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from rhi._linalg import torque_null_projector
from rhi.errors import InvalidInput, Singular
from rhi.metrics._common import (
    FloatArray,
    axis_ratio,
    cholesky,
    direction,
    gram,
    inverse_gram,
    inverse_transmitted,
    jacobian,
    pad_axes,
    positive,
    radius_along,
    square,
    whiten,
)
from rhi.metrics.force import lp_force, scaling_optimum, torque_box
from rhi.metrics.inverses import right_inverse


@dataclass(frozen=True)
class Measures:
    """The measures of `measure_all` at one configuration (floats in SI units; None where J has rank < m)."""

    u: FloatArray
    rank: int
    velocity_ellipsoid: FloatArray
    effective_manipulability: float
    effective_inertia: float
    apparent_inertia: FloatArray | None
    manipulability: float
    isotropy: float
    reflected_friction: float
    force_ellipsoid: FloatArray | None
    directional_manipulability: float
    max_force_scaling: float
    max_force: float | None


def measure_all(
    J: ArrayLike, M: ArrayLike, u: ArrayLike, *, torque_min: ArrayLike, torque_max: ArrayLike, lp: bool = False
) -> Measures:
    """Every measure of `rhi.metrics` at one configuration, each equal to its own function's value.

    The inputs are checked once; one SVD of J serves ρ = σ, μ, 1/κ and the rank, one Cholesky factor
    ``M = L Lᵀ`` serves Λ, M_x and the dynamic projector, and the torque-weighted map J W serves DM and M̂
    (``W = diag(1 / max(|torque_min|, |torque_max|))``).

    Args:
        J: (m, n) Jacobian [m/rad].
        M: (n, n) joint-space inertia [kg m²], symmetric positive definite.
        u: (m,) direction; normalised internally, must be non-zero.
        torque_min: (n,) lower torque limits [N m], each <= 0.
        torque_max: (n,) upper torque limits [N m], each >= 0.
        lp: also solve `max_force`'s linear program with the dynamic projector (≈ 1 ms).

    Returns:
        The `Measures`: u (the unit direction), rank (of J), velocity_ellipsoid,
        effective_manipulability (= velocity_transmission), effective_inertia, apparent_inertia,
        manipulability, isotropy, reflected_friction, force_ellipsoid, directional_manipulability,
        max_force_scaling and max_force (None unless `lp`).

    Raises:
        InvalidInput: bad shapes (a batch included), non-finite entries, zero ``u`` or a joint whose
            torque limits are both 0.
        InfeasibleLimits: ``torque_min > torque_max``, ``torque_min > 0`` or ``torque_max < 0``.
        NotSPD: ``M`` is not symmetric positive definite.
        RhiError: the LP solver failed.
    """
    J = jacobian("J", J)
    if J.ndim != 2:
        raise InvalidInput(f"J: expected shape (m, n) (one configuration), got {J.shape}")
    m, n = J.shape
    M = square("M", M, n)
    if M.ndim != 2:
        raise InvalidInput(f"M: expected shape ({n}, {n}) (one configuration), got {M.shape}")
    u = direction("u", u, m)
    if u.ndim != 1:
        raise InvalidInput(f"u: expected shape ({m},) (one configuration), got {u.shape}")
    lo, hi = torque_box(torque_min, torque_max, n)
    if lo.ndim != 1 or hi.ndim != 1:
        raise InvalidInput(f"torque_min/torque_max: expected shape ({n},), got {lo.shape} and {hi.shape}")
    positive("torque_max", np.maximum(np.abs(lo), np.abs(hi)))
    return measure_checked(J, M, u, lo, hi, lp=lp)


def measure_checked(J: FloatArray, M: FloatArray, u: FloatArray, lo: FloatArray, hi: FloatArray, *,
                    lp: bool = False) -> Measures:
    """`measure_all` of arrays already checked, such as a device's own J, M and limits (no check repeated).

    Args:
        J: (m, n) finite Jacobian [m/rad].
        M: (n, n) finite joint-space inertia [kg m²] (`NotSPD` if it is not symmetric positive definite).
        u: (m,) unit direction.
        lo: (n,) lower torque limits [N m], each <= 0.
        hi: (n,) upper torque limits [N m], each >= 0, with max(|lo|, |hi|) > 0 per joint.
        lp: also solve `max_force`'s linear program.
    """
    m, n = J.shape
    w = 1.0 / np.maximum(np.abs(lo), np.abs(hi))
    U, s, _ = np.linalg.svd(J, full_matrices=True)
    axes = pad_axes(s, m)
    rho = float(radius_along(axes, U, u))
    L = cholesky("M", M)
    B = whiten(J, L)  # B Bᵀ = J M⁻¹ Jᵀ
    JW = J * w
    t = u @ J
    f_s, tau_s = scaling_optimum(J, t, lo, hi)

    def full_rank(fn):
        try:
            return fn()
        except Singular:
            return None

    r_B = float(inverse_transmitted(B, u))
    return Measures(
        u=u,
        rank=int((s > s.max(initial=0.0) * max(m, n) * np.finfo(float).eps).sum()),
        velocity_ellipsoid=gram(J),
        effective_manipulability=rho,
        effective_inertia=r_B * r_B,
        apparent_inertia=full_rank(lambda: inverse_gram("J", B)),
        manipulability=float(axes.prod()),
        isotropy=float(axis_ratio(axes)),
        reflected_friction=float(inverse_transmitted(J, u)),
        force_ellipsoid=full_rank(lambda: inverse_gram("J", JW)),
        directional_manipulability=float(inverse_transmitted(JW, u)),
        max_force_scaling=float(f_s),
        max_force=full_rank(lambda: float(lp_force(t, torque_null_projector(J, right_inverse(B, L)),
                                                   lo, hi, f_s, tau_s)[0])) if lp else None,
    )
