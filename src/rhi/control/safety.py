"""The null-space safety torque (damping, joint-limit barrier) that acts whatever the allocation holds.

Thesis Algorithm 2 scales the whole tertiary torque by β and sets β = 0 when the joints ASCM
holds at a limit leave no redundancy; then the null-space damping and the joint-limit barrier
switch off with the objective, and the self-motion driven by ASCM's null-space torque runs
free (issue 13, item 5). These functions give the safety torque the part that the held joints
would block, making room for it in the allocated torque (`rhi.control.controller`, step 5).
"""

from __future__ import annotations

import numpy as np

from rhi.control.saturation import negligible, scaling_alpha


def safety_room(tau, b, delta, *, torque_min, torque_max, skip: bool = False) -> tuple[np.ndarray, float]:
    """Add a null-space safety torque (damping, joint-limit barrier) that acts whatever the allocation holds.

    Returns ``τ' = b + δ + γ (τ − b)`` with the largest γ ∈ [0, 1] that keeps τ' in the box:
    the allocated part ``α a + Z y`` of τ (eq. 7.9) gives way to δ, so the task force becomes
    γ α F_render + F_extra and δ, a null-space torque, leaves it unchanged. Joints the
    allocation held at a limit leave it when δ points inwards. When even ``b + δ`` leaves the
    box, δ itself is scaled by the largest σ ∈ [0, 1] with ``τ + σ δ`` in the box (γ = 1).

    Args:
        tau: (n,) allocated torque [N m], within the box.
        b: (n,) unscaled torque of the allocation [N m].
        delta: (n,) safety torque, already projected into the task's null space [N m].
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        skip: return (τ, 1) unchanged (the allocation had to clip b).

    Returns:
        (τ' (n,) [N m], γ).
    """
    if skip or not np.any(np.abs(delta) > negligible(delta)):
        return tau, 1.0
    lo, hi = torque_min, torque_max
    c = b + delta
    gamma = scaling_alpha(tau - b, c, lo=lo, hi=hi)
    if gamma is None:
        sigma = scaling_alpha(delta, np.clip(tau, lo, hi), lo=lo, hi=hi)
        return tau + (0.0 if sigma is None else sigma) * delta, 1.0
    return np.clip(c + gamma * (tau - b), lo, hi), gamma


def held_part(Z, saturated, d) -> np.ndarray:
    """The part of a null-space torque d that keeping the held joints 𝒮 unchanged removes: Z Z_𝒮⁺ d_𝒮.

    ``d − held_part`` is what `tertiary` keeps of d (the torques in range(Z) with zero
    entries on 𝒮); with no redundancy left (rank Z_𝒮 = n − m) the held part is all of d.

    Args:
        Z: (n, r) orthonormal null-space basis.
        saturated: (n,) bool, the held joints 𝒮.
        d: (n,) torque in range(Z) [N m].

    Returns:
        (n,) [N m].
    """
    if not saturated.any():
        return np.zeros_like(d)
    c = Z.T @ d
    ZS = Z[saturated]
    return Z @ (np.linalg.pinv(ZS) @ (ZS @ c))


__all__ = ["held_part", "safety_room"]
