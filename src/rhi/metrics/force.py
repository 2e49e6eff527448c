"""Force-feedback capability along a direction under a joint-torque box (thesis §7.3)."""

from __future__ import annotations

from typing import Literal, overload

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import as_array, limits_pair
from rhi.errors import InfeasibleLimits, InvalidInput, RhiError
from rhi.metrics._common import SINGULAR_RTOL, FloatArray, direction, frobenius_norm, jacobian
from rhi.metrics.inverses import nullspace_projector

#: A null-space projector: "dynamic" (J#, eq. 7.5) or "pseudoinverse" (J⁺).
ProjectorKind = Literal["dynamic", "pseudoinverse"]
#: `ProjectorKind`, or None: no null-space torques.
Projector = ProjectorKind | None


def torque_box(torque_min: ArrayLike, torque_max: ArrayLike, n: int) -> tuple[FloatArray, FloatArray]:
    """The checked limits ``(torque_min, torque_max)``, each (..., n) [N m], with ``torque_min <= 0 <= torque_max``."""
    lo, hi = limits_pair("torque_min", torque_min, "torque_max", torque_max, n)
    lo = as_array("torque_min", lo, shape_tail=(n,))
    hi = as_array("torque_max", hi, shape_tail=(n,))
    if (lo > 0).any():
        raise InfeasibleLimits("torque_min: every entry must be <= 0 (zero torque must be admissible)")
    if (hi < 0).any():
        raise InfeasibleLimits("torque_max: every entry must be >= 0 (zero torque must be admissible)")
    return lo, hi


def _setup(
    J: ArrayLike, u: ArrayLike, torque_min: ArrayLike, torque_max: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Validate and return ``(J, t = Jᵀu, lo, hi)``."""
    J = jacobian("J", J)
    m, n = J.shape[-2:]
    u = direction("u", u, m)
    lo, hi = torque_box(torque_min, torque_max, n)
    try:
        np.broadcast_shapes(J.shape[:-2], u.shape[:-1], lo.shape[:-1], hi.shape[:-1])
    except ValueError:
        raise InvalidInput("J/u/torque_min/torque_max: batch shapes do not broadcast") from None
    t = np.einsum("...ij,...i->...j", J, u)
    return J, t, lo, hi


def scaling_optimum(J: FloatArray, t: FloatArray, lo: FloatArray, hi: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Closed-form largest ``f >= 0`` with ``lo <= f t <= hi``, and the torque ``f t``."""
    eps = SINGULAR_RTOL * frobenius_norm(J)[..., None]
    pos = t > eps
    loaded = pos | (t < -eps)
    ratio = np.where(loaded, np.where(pos, hi, lo) / np.where(loaded, t, 1.0), np.inf)
    f = ratio.min(axis=-1)
    torque = np.where(np.isinf(f), 0.0, f)[..., None] * np.where(loaded, t, 0.0)
    return f, torque


@overload
def max_force_scaling(
    J: ArrayLike, u: ArrayLike, *, torque_min: ArrayLike, torque_max: ArrayLike, return_torque: Literal[False] = ...
) -> FloatArray: ...
@overload
def max_force_scaling(
    J: ArrayLike, u: ArrayLike, *, torque_min: ArrayLike, torque_max: ArrayLike, return_torque: Literal[True]
) -> tuple[FloatArray, FloatArray]: ...
def max_force_scaling(
    J: ArrayLike, u: ArrayLike, *, torque_min: ArrayLike, torque_max: ArrayLike, return_torque: bool = False
) -> FloatArray | tuple[FloatArray, FloatArray]:
    """Largest force along ``u`` by simple scaling, ``τ = Jᵀ(f u)`` in the torque box (thesis §7.3, Fig. 7.1b).

    ``f = min_i`` of ``torque_max_i/(Jᵀu)_i`` over ``(Jᵀu)_i > 0`` and
    ``torque_min_i/(Jᵀu)_i`` over ``(Jᵀu)_i < 0``: the static force reached when the
    desired force is scaled down until the first actuator saturates, without using
    null-space torques.

    Args:
        J: (..., m, n) Jacobian [m/rad].
        u: (..., m) force direction; normalised internally, must be non-zero.
        torque_min: (n,) or (..., n) lower torque limits [N m], each <= 0.
        torque_max: (n,) or (..., n) upper torque limits [N m], each >= 0.
        return_torque: also return the joint torques at the optimum.

    Returns:
        f (...,) [N], or ``(f, torque)`` with torque (..., n) [N m]. ``f = inf`` (torque 0)
        where ``|(Jᵀu)_i| <= 1e-12 |J|_F`` for every joint: a singular configuration
        whose structure carries any load along ``u``.

    Raises:
        InvalidInput: bad shapes, non-finite entries or zero-length ``u``.
        InfeasibleLimits: ``torque_min > torque_max``, ``torque_min > 0`` or ``torque_max < 0``.
    """
    J, t, lo, hi = _setup(J, u, torque_min, torque_max)
    f, torque = scaling_optimum(J, t, lo, hi)
    return (f, torque) if return_torque else f


@overload
def max_force(
    J: ArrayLike,
    u: ArrayLike,
    *,
    torque_min: ArrayLike,
    torque_max: ArrayLike,
    projector: Projector = ...,
    M: ArrayLike | None = ...,
    return_torque: Literal[False] = ...,
) -> FloatArray: ...
@overload
def max_force(
    J: ArrayLike,
    u: ArrayLike,
    *,
    torque_min: ArrayLike,
    torque_max: ArrayLike,
    projector: Projector = ...,
    M: ArrayLike | None = ...,
    return_torque: Literal[True],
) -> tuple[FloatArray, FloatArray]: ...
def max_force(
    J: ArrayLike,
    u: ArrayLike,
    *,
    torque_min: ArrayLike,
    torque_max: ArrayLike,
    projector: Projector = "dynamic",
    M: ArrayLike | None = None,
    return_torque: bool = False,
) -> FloatArray | tuple[FloatArray, FloatArray]:
    """Largest force along ``u`` using null-space torques, the optimum ASCM approaches (thesis eqs. 7.5-7.9).

    Solves the linear program ``max f`` subject to
    ``torque_min <= f Jᵀu + N τ_N <= torque_max`` with ``f >= 0`` and ``τ_N`` free, where
    ``N`` is the torque null-space projector of eq. 7.5: ``I − JᵀJ#ᵀ`` with the
    dynamically consistent ``J#`` (``projector="dynamic"``, needs ``M``), ``I − JᵀJ⁺ᵀ``
    (``"pseudoinverse"``), or no null space (``None``, identical to `max_force_scaling`).
    The optimal torque produces the end-effector force ``f u``: ``J#ᵀτ = f u`` (dynamic)
    or ``J⁺ᵀτ = f u`` (pseudoinverse). Solved with HiGHS, one LP per configuration;
    constraints hold to the solver's feasibility tolerance (about 1e-9 N m).

    Args:
        J: (..., m, n) Jacobian [m/rad].
        u: (..., m) force direction; normalised internally, must be non-zero.
        torque_min: (n,) or (..., n) lower torque limits [N m], each <= 0.
        torque_max: (n,) or (..., n) upper torque limits [N m], each >= 0.
        projector: "dynamic", "pseudoinverse" or None.
        M: (..., n, n) joint-space inertia [kg m²], required for (and only used by)
            ``projector="dynamic"``.
        return_torque: also return the optimal joint torques.

    Returns:
        f (...,) [N], or ``(f, torque)`` with torque (..., n) [N m]. Always
        ``>= max_force_scaling``.

    Raises:
        InvalidInput: bad shapes, non-finite entries, zero ``u``, an unknown
            ``projector`` or ``M`` missing/superfluous.
        InfeasibleLimits: ``torque_min > torque_max``, ``torque_min > 0`` or ``torque_max < 0``.
        NotSPD: ``M`` is not symmetric positive definite.
        Singular: ``J`` does not have full row rank (with a projector).
        RhiError: the LP solver failed.
    """
    if projector not in ("dynamic", "pseudoinverse", None):
        raise InvalidInput(f"projector: expected 'dynamic', 'pseudoinverse' or None, got {projector!r}")
    if projector == "dynamic" and M is None:
        raise InvalidInput("M: the joint-space inertia matrix is required with projector='dynamic'")
    if projector != "dynamic" and M is not None:
        raise InvalidInput(f"M: only used with projector='dynamic', got projector={projector!r}")
    J, t, lo, hi = _setup(J, u, torque_min, torque_max)
    f_s, tau_s = scaling_optimum(J, t, lo, hi)
    if projector is None:
        return (f_s, tau_s) if return_torque else f_s
    N = nullspace_projector(J, M if projector == "dynamic" else None)
    force, torque = lp_force(t, N, lo, hi, f_s, tau_s)
    return (force, torque) if return_torque else force


def lp_force(
    t: FloatArray, N: FloatArray, lo: FloatArray, hi: FloatArray, f_s: FloatArray, tau_s: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The LP of `max_force` on checked arrays: ``(f (...,), torque (..., n))``.

    Args:
        t: (..., n) ``Jᵀu``.
        N: (..., n, n) the torque null-space projector.
        lo: (..., n) lower torque limits [N m].
        hi: (..., n) upper torque limits [N m].
        f_s: (...,) the closed-form `max_force_scaling` optimum [N] (kept where the solver's tolerance
            leaves the LP below it).
        tau_s: (..., n) its torques [N m].
    """
    from scipy.optimize import linprog  # deferred: scipy.optimize costs ~0.4 s of `import rhi`

    n = t.shape[-1]
    batch = np.broadcast_shapes(t.shape[:-1], lo.shape[:-1], hi.shape[:-1], N.shape[:-2])
    t_b = np.broadcast_to(t, batch + (n,))
    lo_b = np.broadcast_to(lo, batch + (n,))
    hi_b = np.broadcast_to(hi, batch + (n,))
    N_b = np.broadcast_to(N, batch + (n, n))
    f_s = np.broadcast_to(f_s, batch)
    tau_s = np.broadcast_to(tau_s, batch + (n,))
    force = np.empty(batch)
    torque = np.empty(batch + (n,))
    c = np.zeros(n + 1)
    c[0] = -1.0
    bounds = [(0.0, None)] + [(None, None)] * n
    for idx in np.ndindex(*batch):
        A = np.concatenate([t_b[idx][:, None], N_b[idx]], axis=1)
        res = linprog(
            c,
            A_ub=np.concatenate([A, -A]),
            b_ub=np.concatenate([hi_b[idx], -lo_b[idx]]),
            bounds=bounds,
            method="highs",
        )
        if res.status != 0:
            raise RhiError(f"max_force: LP failed at batch index {idx}: {res.message}")
        f_lp = float(res.x[0])
        if f_lp >= f_s[idx]:
            force[idx] = f_lp
            torque[idx] = A @ res.x
        else:  # solver tolerance below the closed-form feasible point
            force[idx] = f_s[idx]
            torque[idx] = tau_s[idx]
    return force, torque
