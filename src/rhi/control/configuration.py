"""Static redundancy resolution: the configuration a null-space controller converges to."""

from __future__ import annotations

import numpy as np
from scipy.optimize import LinearConstraint, NonlinearConstraint, minimize

from rhi._validate import as_array
from rhi.control.objectives import Objective
from rhi.devices.model import Device
from rhi.errors import Unreachable


def optimal_configuration(
    device: Device,
    x,
    objective: Objective,
    q0,
    *,
    tol: float = 1e-9,
    max_iter: int = 200,
    exact_start: bool = False,
) -> np.ndarray:
    """Minimise ν(q) over the self-motion manifold f(q) = x within the joint limits.

    This is the fixed point of gradient projection (thesis eq. 3.20–3.21) computed
    directly with SciPy's SLSQP: equality constraint f(q) = x (analytic Jacobian),
    joint box bounds and the device's linear joint inequalities.

    Args:
        device: redundant device.
        x: (m,) end-effector position [m].
        objective: secondary objective with `value` and `gradient`.
        q0: (n,) starting configuration (need not satisfy f(q0) = x).
        tol: SLSQP's convergence tolerance.
        max_iter: SLSQP's iteration limit.
        exact_start: start SLSQP exactly at q0 (e.g. a simulated end configuration, off f(q) = x by
            the run's drift) and return its point without projecting it back by IK (within 1e-7 m of
            x), so the answer tells whether q0 is itself a constrained local minimum. False: start
            from the IK solution nearest q0 and project the answer onto f(q) = x.

    Returns:
        q: (n,) optimal configuration; the start when SLSQP does not improve on it.

    Raises:
        Unreachable: no configuration within the limits reaches x (not with `exact_start`).
    """
    x = as_array("x", x, shape_tail=(device.m,))
    q0 = as_array("q0", q0, shape_tail=(device.n,))
    if not exact_start:  # feasible start nearest q0: no joint-centring term (it would move the start along the self-motion)
        q0 = device.ik(x, q0, k_null=0.0)  # raises Unreachable
    cons = [
        NonlinearConstraint(
            lambda q: device.fk(q) - x, 0.0, 0.0, jac=lambda q: device.jacobian(q)
        )
    ]
    if device.linear_limits is not None:
        L = device.linear_limits
        cons.append(LinearConstraint(L.C, L.lower, L.upper))
    bounds = list(zip(device.q_min, device.q_max))
    res = minimize(
        lambda q: objective.value(device, q),
        q0,
        jac=lambda q: objective.gradient(device, q),
        method="SLSQP",
        bounds=bounds,
        constraints=cons,
        options={"maxiter": max_iter, "ftol": tol},
    )
    if exact_start:
        qs = np.clip(res.x, device.q_min, device.q_max)
        ok = np.linalg.norm(device.fk(qs) - x) < 1e-7 and device.within_limits(qs)
        return qs if ok and objective.value(device, qs) <= objective.value(device, q0) else q0
    # the best feasible point found: SLSQP's answer projected back onto f(q) = x, or the start
    try:
        q = device.ik(x, np.clip(res.x, device.q_min, device.q_max), k_null=0.0, restarts=0)
    except Unreachable:
        return q0
    return q if objective.value(device, q) <= objective.value(device, q0) else q0
