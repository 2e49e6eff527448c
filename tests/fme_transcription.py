"""A second, independent transcription of ch. 6's configuration matching on the 4-DoF RHI (issue 23, Fig. 6.10).

Plain NumPy, written from the thesis text: the Jacobian of eq. 6.20 and the position it integrates to,
the torque-weighted FME of eq. 6.9 and ν of eq. 6.10 (`transcription.fme_weighted`, `transcription.jbld`),
J# of eq. 6.4, and the null-space controller of eqs. 6.2–6.6 run as what it is: with the handle held,
τ_N = (I − JᵀJ#ᵀ)(−∇c) accelerates the joints by M⁻¹τ_N, which J maps to zero, so the configuration
flows down the cost along the self-motion manifold (here integrated as an overdamped flow with a
backtracking step). F_max along u by force scaling (§6.3.1: scale the desired force until the first
actuator saturates) is min_i T_i/|(Jᵀu)_i|.

It imports nothing of rhi's objectives, optimisers, IK or metrics. Inputs it takes as data: the link
lengths and the torque limits (§6.4), the joint limits (§5.4), the mass matrix (only the flow's path,
not its fixed point, depends on it), and the joint-limit barrier rhi states as its own choice in
`rhi.experiments.ch6` (½ Σ max(0, δ − d)², δ = 0.1 rad, gain 100 beside β = 20), which the thesis's
law does not have and without which every match at X₀ lies outside the limits.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

import numpy as np
import transcription as tr

#: §6.4 / eq. 6.20: link lengths d_i [m]; programmed torque limits T_i [N m].
D = (0.254, 0.141, 0.21, 0.181)
T = np.array([3.0, 3.0, 1.0, 1.0])
#: §5.4 joint limits [rad]: box and the two parallelogram rows 35° ≤ q1 − q2 + 90° ≤ 145°, 35° ≤ q3 − q4 + 90° ≤ 145°.
Q_MIN = np.radians([-55.0, 0.0, -55.0, -20.0])
Q_MAX = np.radians([90.0, 145.0, 115.0, 80.0])
LINEAR = ((np.array([1.0, -1.0, 0.0, 0.0]), np.radians(-55.0), np.radians(55.0)),
          (np.array([0.0, 0.0, 1.0, -1.0]), np.radians(-55.0), np.radians(55.0)))


def jacobian(q: np.ndarray, d=D) -> np.ndarray:
    """Eq. 6.20, (2, 4) [m/rad]."""
    d1, d2, d3, d4 = d
    q1, q2, q3, q4 = q
    return np.array([
        [-d1 * np.sin(q1), d2 * np.cos(q2) - d3 * np.sin(q2 + q3) + d4 * np.cos(q2 + q4),
         -d3 * np.sin(q2 + q3), d4 * np.cos(q2 + q4)],
        [d1 * np.cos(q1), d2 * np.sin(q2) + d3 * np.cos(q2 + q3) + d4 * np.sin(q2 + q4),
         d3 * np.cos(q2 + q3), d4 * np.sin(q2 + q4)],
    ])


def fk(q: np.ndarray, d=D) -> np.ndarray:
    """The handle position whose derivative is eq. 6.20 [m] (origin at the rehab robot's first joint)."""
    d1, d2, d3, d4 = d
    q1, q2, q3, q4 = q
    return np.array([d1 * np.cos(q1) + d2 * np.sin(q2) + d3 * np.cos(q2 + q3) + d4 * np.sin(q2 + q4),
                     d1 * np.sin(q1) - d2 * np.cos(q2) + d3 * np.sin(q2 + q3) - d4 * np.cos(q2 + q4)])


def limit_distances(q: np.ndarray) -> np.ndarray:
    """Distances of q to every lower and upper limit, box and linear rows [rad]."""
    rows = [q - Q_MIN, Q_MAX - q]
    rows += [np.array([c @ q - lo, hi - c @ q]) for c, lo, hi in LINEAR]
    return np.concatenate(rows)


def within(q: np.ndarray) -> bool:
    """Every §5.4 limit holds (1e-9 rad)."""
    return bool(np.all(limit_distances(q) >= -1e-9))


def barrier(q: np.ndarray, margin: float = 0.1) -> float:
    """The joint-limit penalty rhi states as its choice, ½ Σ max(0, δ − d)² (not a thesis equation)."""
    p = np.maximum(0.0, margin - limit_distances(q))
    return float(0.5 * p @ p)


def matching_cost(M_des: np.ndarray, *, beta: float = 20.0, limit_gain: float = 100.0,
                  weights: np.ndarray = T) -> Callable[[np.ndarray], float]:
    """c(q) = β ν(q) + G ν_lim(q): eq. 6.10 with M̂ of eq. 6.9 (W = diag(1/T_i)) and the barrier."""
    return lambda q: beta * tr.jbld(tr.fme_weighted(jacobian(q), weights), M_des) + limit_gain * barrier(q)


def _limit_rows() -> tuple[tuple[np.ndarray, float], ...]:
    """Every §5.4 limit as a row c and bound b with c·q ≥ b: the lower limits, then the upper ones negated."""
    eye = np.eye(4)
    rows = [(eye[i], Q_MIN[i]) for i in range(4)] + [(-eye[i], -Q_MAX[i]) for i in range(4)]
    rows += [(c, lo) for c, lo, _ in LINEAR] + [(-c, -hi) for c, _, hi in LINEAR]
    return tuple(rows)


LIMIT_ROWS = _limit_rows()


def onto(x: np.ndarray, q: np.ndarray, pinned=(), iters: int = 50) -> np.ndarray | None:
    """Newton's least-norm steps from q onto f(q) = x and onto each pinned limit (indices of `LIMIT_ROWS`), or None."""
    q = np.array(q, dtype=float)
    rows = [LIMIT_ROWS[r] for r in pinned]
    for _ in range(iters):
        e = np.concatenate([x - fk(q), [b - c @ q for c, b in rows]])
        if np.linalg.norm(e) < 1e-12:
            return q
        A = np.vstack([jacobian(q), *[c[None, :] for c, _ in rows]])
        q = q + np.linalg.pinv(A) @ e
    return None


def flow_direction(g: np.ndarray, J: np.ndarray, M: np.ndarray, q: np.ndarray):
    """The null-space motion −M⁻¹(I − JᵀJ#ᵀ)g, held on the limits it would cross: (v, pinned row indices).

    With A = J, −M⁻¹(I − JᵀJ#ᵀ)g = −(M⁻¹ − M⁻¹Aᵀ(AM⁻¹Aᵀ)⁻¹AM⁻¹)g (eqs. 6.3–6.4). At a hard stop the stop's
    reaction joins A: of every set of the limits q sits on, the motion that crosses none of them and
    descends fastest (the projection onto the feasible cone; a stop slides the flow, never holds it off).
    """
    Mi = np.linalg.inv(M)
    active = [r for r, (c, b) in enumerate(LIMIT_ROWS) if c @ q - b < 1e-7]
    best, best_rate = (np.zeros_like(g), []), 0.0
    for k in range(len(active) + 1):
        for pinned in itertools.combinations(active, k):
            A = np.vstack([J, *[LIMIT_ROWS[r][0][None, :] for r in pinned]])
            if np.linalg.matrix_rank(A) < A.shape[0]:
                continue
            v = -(Mi - Mi @ A.T @ np.linalg.solve(A @ Mi @ A.T, A @ Mi)) @ g
            if all(LIMIT_ROWS[r][0] @ v >= -1e-12 for r in active if r not in pinned) and -g @ v > best_rate:
                best, best_rate = (v, list(pinned)), -g @ v
    return best


def null_space_flow(cost: Callable[[np.ndarray], float], mass: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                    q0: np.ndarray, *, iters: int = 20000, tol: float = 1e-9, max_move: float = 0.02) -> np.ndarray:
    """Eqs. 6.2–6.6 with the handle held at x: q̇ ∝ M⁻¹(I − JᵀJ#ᵀ)(−∂c/∂q) until it stops.

    Each step moves along that direction (`flow_direction`: sliding along a limit it reaches, as on a
    hard stop) by at most `max_move` [rad] per joint, stops at the first limit it would cross, returns
    onto f(q) = x (and onto the limits it slides on) by `onto`, and is accepted when the cost decreases
    (the step doubles after a success, halves after a failure). Stops when the direction's size is
    below tol or the step underflows.

    Returns:
        q: (4,) the configuration the flow settles at [rad].
    """
    q = onto(x, q0)
    if q is None or not within(q):
        raise ValueError("start does not reach x within the limits")
    c, h = cost(q), 1e-4
    for _ in range(iters):
        J, M = jacobian(q), mass(q)
        v, pinned = flow_direction(tr.gradient_fd(cost, q), J, M, q)
        if np.linalg.norm(M @ v) < tol or h < 1e-14:
            break
        step = min(h, max_move / np.max(np.abs(v)))  # a small move per step: the flow, not a jump across basins
        for r, (c_r, b) in enumerate(LIMIT_ROWS):  # stop at the first limit the step would cross
            rate = c_r @ v
            if rate < -1e-15 and r not in pinned:
                step = min(step, max(0.0, (c_r @ q - b) / -rate))
        q_new = onto(x, q + step * v, pinned)
        if q_new is not None and within(q_new) and cost(q_new) < c:
            q, c, h = q_new, cost(q_new), 2.0 * h
        else:
            h *= 0.5
    return q


def fmax_scaling(q: np.ndarray, u: np.ndarray, torque: np.ndarray = T) -> float:
    """§6.3.1's force scaling: the largest f with |Jᵀ u f| ≤ T per joint [N]."""
    a = np.abs(jacobian(q).T @ (u / np.linalg.norm(u)))
    return float(np.min(torque[a > 0] / a[a > 0]))
