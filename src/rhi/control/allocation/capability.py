"""The static force capability of an allocation strategy along a direction (Fig. 7.1's peak force)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import numpy as np

from rhi.control.allocation.base import allocation_method
from rhi.control.allocation.lp import LPOptimum
from rhi.control.saturation import check_torque_limits, null_basis
from rhi.errors import InvalidInput
from rhi.metrics import max_force, max_force_scaling


def force_capability(
    J, u, *, torque_min, torque_max, method: str = "ascm", projector: Literal["dynamic", "pseudoinverse"] = "dynamic",
    M=None, samples: int = 41,
) -> float:
    """Largest force along u a static allocation method renders, over a ramp of requests [N].

    Requests ``f u`` for f from the simple-scaling capability up to 1.5× the LP optimum
    (`rhi.metrics.max_force`), and returns the peak output ``α f`` — what a quasi-static
    force ramp, as in Fig. 7.1, shows as the peak force. "scaling" and "lp" are exact
    (closed form / LP); any other registered strategy but "none" (which does not keep the force's
    direction) runs the ramp, e.g. "ascm" (Algorithm 1).

    Args:
        J: (m, n) Jacobian [m/rad].
        u: (m,) direction; normalised internally.
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        method: "scaling" | "ascm" | "lp" | another registered strategy (`rhi.control.allocation`).
        projector: "dynamic" (J#, eq. 7.5; needs M) or "pseudoinverse" (J⁺).
        M: (n, n) inertia [kg m²], required for (and only used by) ``projector="dynamic"``.
        samples: requests in the ramp (for the strategies without a closed form).

    Raises:
        InvalidInput: an unknown method or projector, or M missing/superfluous.
    """
    if method == "none":
        raise InvalidInput("method: 'none' clips the torque and does not keep the force direction; no capability")
    strategy = allocation_method(method, argument="method")
    if projector not in ("dynamic", "pseudoinverse"):
        raise InvalidInput(f"projector: expected 'dynamic' or 'pseudoinverse', got {projector!r}")
    lo, hi = check_torque_limits(torque_min=torque_min, torque_max=torque_max, n=np.shape(J)[-1])
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    f_s = float(max_force_scaling(J, u, torque_min=lo, torque_max=hi))
    if method == "scaling":
        return f_s
    f_lp = float(max_force(J, u, torque_min=lo, torque_max=hi, projector=projector, M=M))
    if isinstance(strategy, LPOptimum):  # whatever its solver
        return f_lp
    Z = null_basis(np.asarray(J, dtype=float), M)
    t = np.asarray(J, dtype=float).T @ u
    b = np.zeros_like(t)
    return ramp_peak(lambda f: strategy.allocate(f * t, b, Z, torque_min=lo, torque_max=hi).alpha, f_s, f_lp, samples)


def ramp_peak(alpha: Callable[[float], float], f_s: float, f_lp: float, samples: int) -> float:
    """The peak output α(f) f over the ramp of requests f from f_s to 1.5 f_lp, then f_lp itself [N].

    The quasi-static force ramp of Fig. 7.1 (`force_capability`); a peak at most round-off above the LP
    optimum f_lp is f_lp.

    Args:
        alpha: the force scaling α an allocation gives the request f u [N].
        f_s: the simple-scaling capability [N] (the ramp's start, and the least peak).
        f_lp: the LP optimum [N].
        samples: requests in the ramp.
    """
    best = f_s
    for f in np.concatenate([np.linspace(f_s, 1.5 * f_lp, samples), [f_lp]]):
        best = max(best, alpha(f) * f)
    return min(best, f_lp) if best <= f_lp * (1 + 1e-9) else best


__all__ = ["force_capability", "ramp_peak"]
