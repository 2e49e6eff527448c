"""Joint-limit penalisation of the Jacobian (Tsai-style column penalties)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import as_array, limits_pair
from rhi.errors import InfeasibleLimits, InvalidInput
from rhi.metrics._common import FloatArray, jacobian, positive


def joint_limit_penalty(q: ArrayLike, *, q_min: ArrayLike, q_max: ArrayLike, k_q: ArrayLike) -> FloatArray:
    """Joint-wise joint-limit penalty ``P_i`` (thesis eq. 4.20).

    ``P_i = (1 − exp(−4 k_q (q_i − q_min,i)(q_max,i − q_i) / (q_max,i − q_min,i)²)) / (1 − exp(−k_q))``.
    ``P_i`` is 1 at the mid-range ``(q_min,i + q_max,i)/2`` and 0 at either limit; ``k_q``
    shapes the curve in between. Outside the limits the formula turns negative; the
    result is clipped to 0 there (a joint beyond its limit contributes no motion).

    Args:
        q: (..., n) joint positions [rad or m].
        q_min: (n,) or (..., n) lower joint limits, same unit as ``q``.
        q_max: (n,) or (..., n) upper joint limits, each strictly above ``q_min``. A joint with
            ``q_min = −inf`` and ``q_max = +inf`` (continuous) has P_i = 1.
        k_q: scalar or (..., n) shape coefficient, > 0.

    Returns:
        (..., n) penalties in [0, 1].

    Raises:
        InvalidInput: bad shapes, non-finite entries or ``k_q <= 0``.
        InfeasibleLimits: ``q_min >= q_max`` for some joint.
    """
    q = as_array("q", q, ndim_min=1)
    n = q.shape[-1]
    lo, hi = limits_pair("q_min", q_min, "q_max", q_max, n)
    if lo.shape[-1:] != (n,) or hi.shape[-1:] != (n,):
        raise InvalidInput(f"q_min/q_max: expected {n} entries, got shapes {lo.shape} and {hi.shape}")
    if np.any(lo == np.inf) or np.any(hi == -np.inf):
        raise InvalidInput("q_min/q_max: q_min = +inf or q_max = -inf leaves no range")
    if np.any(lo >= hi):
        raise InfeasibleLimits("q_min/q_max: every q_min must be strictly below q_max")
    k = positive("k_q", k_q)
    bounded = np.isfinite(lo) & np.isfinite(hi)  # a joint without a limit (continuous) is never penalised
    lo_b, hi_b = np.where(bounded, lo, -1.0), np.where(bounded, hi, 1.0)
    x = -4.0 * k * (q - lo_b) * (hi_b - q) / (hi_b - lo_b) ** 2
    p = -np.expm1(x) / -np.expm1(-k)
    one_sided = ~bounded & (np.isfinite(lo) | np.isfinite(hi))
    if np.any(one_sided):
        raise InvalidInput("q_min/q_max: a joint with only one finite limit has no mid-range for eq. 4.20")
    return np.where(bounded, np.clip(p, 0.0, 1.0), 1.0)


def penalized_jacobian(
    J: ArrayLike, q: ArrayLike, *, q_min: ArrayLike, q_max: ArrayLike, k_q: ArrayLike
) -> FloatArray:
    """Joint-limit constrained Jacobian ``J^q``, column ``i`` scaled by ``P_i`` (thesis eq. 4.19).

    Args:
        J: (..., m, n) Jacobian.
        q: (..., n) joint positions [rad or m].
        q_min: (n,) or (..., n) lower joint limits.
        q_max: (n,) or (..., n) upper joint limits.
        k_q: scalar or (..., n) shape coefficient of `joint_limit_penalty`, > 0.

    Returns:
        (..., m, n) penalised Jacobian.

    Raises:
        InvalidInput: bad shapes, non-finite entries or ``k_q <= 0``.
        InfeasibleLimits: ``q_min >= q_max`` for some joint.
    """
    J = jacobian("J", J)
    p = joint_limit_penalty(q, q_min=q_min, q_max=q_max, k_q=k_q)
    if p.shape[-1] != J.shape[-1]:
        raise InvalidInput(f"q: expected {J.shape[-1]} joint values to match J, got shape {p.shape}")
    return J * p[..., None, :]
