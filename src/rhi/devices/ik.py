"""Inverse kinematics of a `Device`: weighted pseudoinverse with a null-space centering term (thesis eqs. 3.3–3.4).

`Device.ik` calls `ik`; the functions take the device and use only its public model
(forward kinematics and Jacobian in chain coordinates θ, limits, actuation map).
"""

from __future__ import annotations

import numpy as np

from rhi._validate import as_array
from rhi.devices.terms import DeviceModel, eye
from rhi.errors import InvalidInput, Unreachable


def ik(device: DeviceModel, x, q0, *, weights=None, tol: float = 1e-9, max_iter: int = 200, k_null: float = 0.1,
       restarts: int = 8) -> np.ndarray:
    """Inverse kinematics by the weighted pseudoinverse with a null-space term (thesis eq. 3.3–3.4).

    Iterates q ← q + J†(x − f(q)) + (I − J†J) q̇₀ with J† = Q⁻¹Jᵀ(JQ⁻¹Jᵀ)⁻¹ and
    q̇₀ = −k_null ∇h(q), h the normalised squared distance from the middle of every
    finite joint range and linear joint inequality. Joints held at a bound leave the
    solve (active set); the last iterations drop the null-space term to converge to
    `tol`. If the iteration from q0 ends in a local minimum, it restarts from seeded
    configurations spread over the joint box.

    Args:
        device: the device.
        x: (m,) target position [m].
        q0: (n,) initial configuration.
        weights: (n,) diagonal of Q (default ones).
        tol: position tolerance [m].
        max_iter: iterations per start.
        k_null: null-space gain.
        restarts: further starting points tried after q0.

    Returns:
        q: (n,) configuration within the joint limits with ‖f(q) − x‖ ≤ tol.

    Raises:
        Unreachable: no solution within the limits was found from any start.
    """
    dev = device
    x = as_array("x", x, shape_tail=(dev.m,))
    if x.ndim != 1:
        raise InvalidInput(f"x: expected shape ({dev.m},), got {x.shape}; call ik per target")
    q0 = as_array("q0", q0, shape_tail=(dev.n,))
    if q0.ndim != 1:
        raise InvalidInput(f"q0: expected shape ({dev.n},), got {q0.shape}")
    w = np.ones(dev.n) if weights is None else as_array("weights", weights, shape_tail=(dev.n,))
    if np.any(w <= 0):
        raise InvalidInput("weights: must be positive")
    Qinv = np.diag(1.0 / w)
    lo = np.where(np.isfinite(dev.q_min), dev.q_min, -np.pi)
    hi = np.where(np.isfinite(dev.q_max), dev.q_max, np.pi)
    starts = np.vstack([q0, np.random.default_rng(0).uniform(lo, hi, size=(restarts, dev.n))])
    centering = _centering_constants(dev)
    best = np.inf
    for start in starts:
        q, err = _ik_from(dev, x, start, Qinv, tol, max_iter, k_null, centering)
        if err <= tol and dev.within_limits(q, 1e-9):
            return q
        best = min(best, err)
    raise Unreachable(
        f"x: target {np.round(x, 5).tolist()} not reached within the joint limits of {dev.name} "
        f"from {len(starts)} starting configurations (best residual {best:.3g} m)"
    )


def _ik_from(dev: DeviceModel, x, q, Qinv, tol, max_iter, k_null, centering) -> tuple[np.ndarray, float]:
    q = np.clip(q, dev.q_min, dev.q_max)
    err = np.inf
    At, b = dev.A.T, dev.b
    for it in range(max_iter):
        th = q @ At + b  # = theta(q), without re-validating q
        e = x - dev.fk_theta(th)
        err = float(np.linalg.norm(e))
        # null-space centering during the first half, pure Newton steps to finish
        center = it < max_iter // 2 and dev.n > dev.m
        if err <= tol and not center:
            break
        step, null = _ik_step(dev, dev.jacobian_theta(th), e, Qinv, q, k_null if center else 0.0, centering)
        if err <= tol and np.max(np.abs(null), initial=0.0) < 1e-6:
            break
        s = float(np.max(np.abs(step)))  # keep the linearisation valid
        q = np.clip(q + step * min(1.0, 0.5 / s) if s > 0 else q, dev.q_min, dev.q_max)
    return q, err


def _ik_step(dev: DeviceModel, J, e, Qinv, q, k_null, centering):
    """One step of eq. 3.4 with joints blocked at a bound removed from the solve (active set).

    Returns (step, null-space part), each (n,).
    """
    free = np.ones(dev.n, dtype=bool)
    eye_m, eye_n = eye(dev.m), eye(dev.n)
    grad = _centering_gradient(q, centering) if k_null else None
    for _ in range(dev.n):
        Jf = J * free
        JQ = Jf @ Qinv
        Jp = JQ.T @ np.linalg.solve(JQ @ Jf.T + 1e-10 * eye_m, eye_m)
        null = -k_null * ((eye_n - Jp @ Jf) @ grad) * free if k_null else np.zeros(dev.n)
        step = Jp @ e + null
        blocked = free & (((q <= dev.q_min) & (step < 0)) | ((q >= dev.q_max) & (step > 0)))
        if not blocked.any():
            break
        free &= ~blocked
    return step, null


def _centering_gradient(q: np.ndarray, constants) -> np.ndarray:
    """∇h for h(q) = Σ ((q_i − mid_i)/range_i)² + Σ ((c_j q − mid_j)/range_j)² over finite limits.

    Args:
        q: (n,) configuration [rad or m].
        constants: `_centering_constants` of the device.
    """
    finite, mid, den, lin = constants
    g = np.where(finite, 2 * (q - mid) / den, 0.0)
    if lin is not None:
        C, Ct, mid_l, den_l = lin
        g = g + Ct @ (2 * (C @ q - mid_l) / den_l)
    return g


def _centering_constants(dev: DeviceModel):
    """Constant parts of `_centering_gradient` (finite mask, mid-ranges, squared ranges)."""
    finite = np.isfinite(dev.q_min) & np.isfinite(dev.q_max)
    lo, hi = np.where(finite, dev.q_min, 0.0), np.where(finite, dev.q_max, 0.0)
    lin = None
    if dev.linear_limits is not None:
        L = dev.linear_limits
        lin = (L.C, L.C.T, 0.5 * (L.lower + L.upper), np.maximum(L.upper - L.lower, 1e-9) ** 2)
    return finite, 0.5 * (lo + hi), np.maximum(hi - lo, 1e-9) ** 2, lin
