"""Measures of a palpation run at a rendered one-sided wall: the energy terms and the wall's force.

The energy terms are exact under the zero-order hold (`rhi.experiments.beyond.passivity` states each). The
wall's force is measured away from the joint stops: where a self-motion runs a joint past its range limit the
plant's stop hits the mechanism, and the force the hand feels then is that impact, not the rendered wall.
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices import batch
from rhi.devices.model import Device

#: Ticks this close [s] to a joint in its range stop count as a stop impact, not the rendered wall.
STOP_MARGIN = 0.02


def moving_average(a: np.ndarray, w: int) -> np.ndarray:
    """The moving average of a over w samples (n,), the window shortened at the ends."""
    k = np.ones(w) / w
    return np.convolve(a, k, mode="same") / np.convolve(np.ones(len(a)), k, mode="same")


def wall_force(F: np.ndarray, contact: np.ndarray, stop: np.ndarray, dt: float) -> dict[str, float]:
    """The rendered wall's force away from the joint stops [N] (a stop impact is the plant's stop, not the wall).

    Args:
        F: (N,) the force along u [N].
        contact: (N,) bool, ticks in contact with the ideal wall.
        stop: (N,) bool, ticks with a joint past its range limit (in the plant's stop).
        dt: the tick [s].

    Returns:
        force_peak_wall: the largest force at least `STOP_MARGIN` from any stop contact; contact_peak: the median
        over the contacts of each contact's largest force away from the stops; peak_at_stop: 1.0 where the largest
        force of the run is a stop impact; peak_time: its time from the start [s].
    """
    w = int(round(STOP_MARGIN / dt))
    near = np.convolve(stop.astype(float), np.ones(2 * w + 1), mode="same") > 0 if stop.any() else stop
    free = ~near
    edges = np.flatnonzero(np.diff(np.r_[0, contact.astype(np.int8), 0]))
    peaks = [float(np.max(F[a:b][free[a:b]])) for a, b in zip(edges[::2], edges[1::2]) if free[a:b].any()]
    k = int(np.argmax(F))
    return {"force_peak_wall": float(np.max(F[free])) if free.any() else math.nan,
            "contact_peak": float(np.median(peaks)) if peaks else math.nan,
            "peak_at_stop": float(near[k]), "peak_time": k * dt}


def energies(dev: Device, log, friction, stiffness: float, *, x0: np.ndarray, u: np.ndarray,
             damping: float) -> dict[str, float]:
    """Energy terms of one run at a one-sided wall [J]; positive: energy into the mechanism.

    Args:
        dev: the device.
        log: the run's `rhi.sim.Log`.
        friction: the plant's joint friction (``damping`` [N m s/rad], ``frictionloss`` [N m] per joint).
        stiffness: the wall K_e [N/m].
        x0: (m,) the wall's point [m].
        u: (m,) its normal into the wall.
        damping: the rendered damping B^d [N s/m].

    Returns:
        W (the hand's work), motors (Σ τ(k)ᵀ(q(k+1) − q(k))), task ((J#ᵀτ)ᵀΔx at the handle), null (the rest),
        wall_zoh (Σ F_eᵀΔx + ΔU of the sampled wall), friction (the plant's joint losses), damping (B^d's losses).
    """
    q, tau, dt = log.q, log.tau, float(log.t[1] - log.t[0])
    dq = np.diff(q, axis=0)
    motors = float(np.einsum("ki,ki->", tau[:-1], dq))
    # in batch: x, J and M of every row; the task force J#ᵀτ = Λ J M⁻¹ τ, Λ = (J M⁻¹ Jᵀ)⁻¹ (DeviceTerms.Jsharp)
    d = batch.terms(dev, q, ("x", "J", "M"))
    x, J, M = d["x"], d["J"][:-1], d["M"][:-1]
    MiJt = np.linalg.solve(M, np.swapaxes(J, 1, 2))
    F = np.linalg.solve(J @ MiJt, np.einsum("knm,kn->km", MiJt, tau[:-1])[..., None])[..., 0]
    task = float(np.einsum("ki,ki->", F, np.diff(x, axis=0)))
    U = 0.5 * stiffness * np.maximum((x - x0) @ u, 0.0) ** 2
    wall = float(np.einsum("ki,ki->", log.F_env[:-1], np.diff(x, axis=0))) + U[-1] - U[0]
    v = log.dq
    fric = float(np.sum(friction.damping * v**2 + friction.frictionloss * np.abs(v)) * dt)
    damp = float(damping * np.sum(log.xdot**2) * dt)
    return {"W": float(log.work[-1]), "motors": motors, "task": task, "null": motors - task,
            "wall_zoh": wall, "friction": fric, "damping": damp}


__all__ = ["STOP_MARGIN", "energies", "moving_average", "wall_force"]
