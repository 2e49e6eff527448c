"""Static redundancy resolution: the configuration a null-space controller converges to."""

from __future__ import annotations

import itertools

import numpy as np
from scipy.optimize import LinearConstraint, NonlinearConstraint, minimize

from rhi._validate import as_array
from rhi.control.barrier import limit_rows
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


#: The flow's largest step per joint [rad]: small against the distances between basins.
STEP = 0.05
#: How far [rad] SLSQP may move the flow's configuration when it settles it (else the flow goes on).
SETTLE = 0.02


def null_space_descent(
    device: Device,
    x,
    objective: Objective,
    q0,
    *,
    tol: float = 1e-12,
    max_iter: int = 3000,
) -> np.ndarray:
    """The configuration the null-space controller settles at from q0 with the end-effector held at x.

    With the handle held, the gradient-projection torque τ_N = (I − JᵀJ#ᵀ)(−∂ν/∂q) (thesis eqs. 6.3–6.6)
    accelerates the joints by M⁻¹τ_N, which J maps to zero: the configuration flows down ν along the
    self-motion manifold f(q) = x and settles in the basin of q0 (a minimiser over all of f(q) = x may
    lie in another basin the controller never reaches). This follows that flow, q̇ = −M⁻¹(I − JᵀJ#ᵀ)∂ν/∂q,
    with backtracking steps, each projected back onto f(q) = x; at a joint limit the flow slides along
    it (of the subsets of the limits q sits on, the motion that crosses none and descends fastest). Near
    the end (the flow's rate of descent down to 1 % of its first), SLSQP from the flow's configuration
    (`optimal_configuration`, ``exact_start=True``) settles it to ``tol`` where it moves no joint by more than
    `SETTLE`; otherwise the flow goes on (to 1 % of that rate, and so on).

    Args:
        device: redundant device.
        x: (m,) end-effector position [m].
        objective: `value(device, q)` and `gradient(device, q)`.
        q0: (n,) start configuration (projected onto f(q) = x first, without null-space motion).
        tol: SLSQP's tolerance for the final settling.
        max_iter: flow steps at most.

    Returns:
        q: (n,) within the limits, f(q) = x to 1e-9 m, ν(q) ≤ ν of the projected start.

    Raises:
        Unreachable: no configuration within the limits reaches x from q0.
    """
    x = as_array("x", x, shape_tail=(device.m,))
    q = device.ik(x, as_array("q0", q0, shape_tail=(device.n,)), k_null=0.0)  # raises Unreachable
    C, lower, upper = limit_rows(device)
    rows = np.vstack([C, -C])  # rows @ q >= bound
    bound = np.concatenate([lower, -upper])
    keep = np.isfinite(bound)
    rows, bound = rows[keep], bound[keep]
    value, h, settle_at = objective.value(device, q), np.inf, None
    for _ in range(max_iter):
        g = np.asarray(objective.gradient(device, q), dtype=float)
        J = device.jacobian_theta(q @ device.A.T + device.b)  # = device.jacobian(q), q checked by its step
        v, pinned = _descent_direction(g, J, device.mass_matrix(q), rows, rows @ q - bound)
        rate = float(-g @ v)  # −dν/dt along the flow
        settle_at = 1e-2 * rate if settle_at is None else settle_at
        h = min(h, STEP / max(float(np.max(np.abs(v))), 1e-300))  # no joint moves more than STEP per step
        if rate <= settle_at or h < 1e-14:  # the flow has slowed down: settle it with SLSQP if SLSQP stays near
            q_set = optimal_configuration(device, x, objective, q, tol=tol, exact_start=True)
            if np.max(np.abs(q_set - q)) <= SETTLE or rate < 1e-12 or h < 1e-14:
                return q_set if np.max(np.abs(q_set - q)) <= SETTLE else q
            settle_at *= 1e-2  # SLSQP went further: follow the flow further first
        free = [r for r in range(len(bound)) if r not in pinned and rows[r] @ v < 0.0]
        step = min([h, *[max(0.0, (rows[r] @ q - bound[r]) / -(rows[r] @ v)) for r in free]])
        q_new = _onto(device, x, q + step * v, rows[pinned], bound[pinned])
        v_new = objective.value(device, q_new) if q_new is not None else np.inf
        if q_new is not None and np.all(rows @ q_new - bound >= -1e-9) and v_new < value:
            q, value, h = q_new, v_new, 2.0 * h
        else:
            h *= 0.5
    return q


def _descent_direction(g, J, M, rows, slack) -> tuple[np.ndarray, list[int]]:
    """Fastest-descending −M⁻¹(I − Aᵀ(AM⁻¹Aᵀ)⁻¹AM⁻¹)g, A = J and the limits it slides on, crossing no active limit."""
    Mi = np.linalg.inv(M)
    active = [int(r) for r in np.flatnonzero(slack < 1e-7)]
    best: tuple[np.ndarray, list[int]] = (np.zeros_like(g), [])
    best_rate = 0.0
    for k in range(min(len(active), len(g) - J.shape[0]) + 1):
        for pinned in itertools.combinations(active, k):
            A = np.vstack([J, rows[list(pinned)]]) if pinned else J
            S = A @ Mi @ A.T
            if pinned and np.linalg.cond(S) > 1e12:  # a limit row dependent on J and the others
                continue
            v = -(Mi @ g - Mi @ A.T @ np.linalg.solve(S, A @ (Mi @ g)))
            rate = float(-g @ v)
            if rate > best_rate and all(rows[r] @ v >= -1e-12 for r in active if r not in pinned):
                best, best_rate = (v, list(pinned)), rate
        if best_rate > 0.0 and not active:
            break
    return best


def _onto(device: Device, x, q, rows, bound, iters: int = 30) -> np.ndarray | None:
    """Least-norm Newton steps onto f(q) = x and rows @ q = bound; None if it does not converge to 1e-12."""
    At, b = device.A.T, device.b
    for _ in range(iters):
        th = q @ At + b  # = device.theta(q), without re-validating q (finite: a flow step from a checked q)
        e = np.concatenate([x - device.fk_theta(th), bound - rows @ q])
        if np.linalg.norm(e) < 1e-12:
            return q
        A = np.vstack([device.jacobian_theta(th), rows])
        q = q + A.T @ np.linalg.solve(A @ A.T, e)
    return None
