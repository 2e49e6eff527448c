"""One adaptive-motion-distribution + tertiary control step for the 10-DoF wmm (thesis App. B).

Replays the states of a 0.25 m circle run (beyond the arm's workspace: the base is
switched on and off, joints saturate, the tertiary objective is active) through
`AMDController.step` and prints the median and p99 step time against the 200 µs target.
In the same run it times a naive implementation of the same step (dense NumPy: the
∂J/∂q from `Device.jacobian_derivative`, the full m³ Hessian of B.18, `np.linalg.pinv`
for every inverse and the literal projector of B.10) and prints the ratio.

    PYTHONPATH=src python benchmarks/bench_mobile.py
"""

from __future__ import annotations

import time

import numpy as np

import rhi
from rhi.control.mobile import (
    AMDConfig,
    AMDController,
    WMMKinematics,
    acceleration_bounds,
    auxiliary_projector,
    chain_jacobian_derivatives,
    manipulability_det_gradient,
    manipulability_det_hessian,
    scale_factor,
)

TARGET_US = 200.0
PI = np.pi
Q0 = np.array([0, 0, 0, 0, PI / 6, 0, PI / 2, 0, -PI / 6, 0])


def circle(t: float, x0: np.ndarray, R: float = 0.25, w: float = PI / 20):
    """x_d, ẋ_d, ẍ_d of the thesis's circle (§B.4.2)."""
    c, s = np.cos(w * t), np.sin(w * t)
    return (x0 + np.array([-R * (c - 1), -R * s, 0.0]), np.array([R * w * s, -R * w * c, 0.0]),
            np.array([R * w * w * c, R * w * w * s, 0.0]))


def record(dev: rhi.Device, duration: float, dt: float) -> list[tuple]:
    """States (t, q, q̇, x_d, ẋ_d, ẍ_d) of a kinematic AMD run."""
    ctl = AMDController(dev, AMDConfig(dt=dt))
    x0 = dev.fk(Q0)
    q, dq = Q0.copy(), np.zeros(10)
    out = []
    for k in range(int(duration / dt)):
        t = k * dt
        target = circle(t, x0)
        out.append((t, q.copy(), dq.copy(), *target))
        ddq = ctl.step(t, q, dq, *target).ddq
        q, dq = q + dq * dt + 0.5 * ddq * dt * dt, dq + ddq * dt
    return out


def naive_step(dev: rhi.Device, kin: WMMKinematics, cfg: AMDConfig, bounds, state: tuple, base_active: bool) -> np.ndarray:
    """The same law written directly from the equations with dense NumPy (the baseline)."""
    t, q, dq, xd, dxd, ddxd = state
    n, nb = 10, 3
    J = dev.jacobian(q)
    dJ = dev.jacobian_derivative(q)  # ∂J/∂q from Pinocchio's Jacobian time variation, column by column
    b = np.einsum("ijk,j,k->i", dJ, dq, dq)
    ddx = ddxd + cfg.kd * (dxd - J @ dq) + cfg.kp * (xd - dev.fk(q))
    lo, hi = acceleration_bounds(q, dq, bounds, cfg.dt)
    Jm = J[:, nb:]
    sigma = np.linalg.svd(Jm, compute_uv=False)[-1]
    active = np.ones(n, bool)
    active[:nb] = base_active or sigma < cfg.sigma_min
    qN = np.zeros(n)
    ddq = np.zeros(n)
    for _ in range(n):  # B.9 with the selection matrix and np.linalg.pinv
        JSp = np.linalg.pinv(J @ np.diag(active.astype(float)))
        ddq = JSp @ (ddx - b) + (np.eye(n) - JSp @ J) @ qN
        s, i = scale_factor(JSp @ ddx, ddq - JSp @ ddx, lo=lo, hi=hi, active=active)
        if s >= 1.0 or i < 0:
            break
        qN[i] = hi[i] if ddq[i] > hi[i] else lo[i]
        active[i] = False
    dJm, d2Jm = chain_jacobian_derivatives(kin.jacobian6(q)[1][:, nb:])
    g = manipulability_det_gradient(Jm, dJm)  # B.14
    H = manipulability_det_hessian(Jm, dJm, d2Jm)  # B.18, full m³ tensor
    qa = np.zeros(n)
    qa[nb:] = cfg.gamma1 * H @ dq[nb:] + cfg.gamma2 * (cfg.gamma1 * g - dq[nb:])
    P_N = np.eye(n) - np.linalg.pinv(J) @ J
    lam = auxiliary_projector(P_N, active) @ qa  # B.10
    beta, _ = scale_factor(lam, ddq, lo=lo, hi=hi)
    return np.clip(ddq + beta * lam, lo, hi)


def main(duration: float = 20.0, dt: float = 0.005, naive_every: int = 10) -> None:
    dev = rhi.device("wmm")
    states = record(dev, duration, dt)
    cfg = AMDConfig(dt=dt)
    ctl = AMDController(dev, cfg)
    fast = np.empty(len(states))
    active = np.empty(len(states), bool)
    for k, st in enumerate(states):
        t0 = time.perf_counter()
        cmd = ctl.step(*st)
        fast[k] = time.perf_counter() - t0
        active[k] = cmd.base_active
    fast *= 1e6
    sub = list(range(0, len(states), naive_every))
    naive = np.empty(len(sub))
    kin = WMMKinematics(dev)
    for j, k in enumerate(sub):
        t0 = time.perf_counter()
        naive_step(dev, kin, cfg, ctl.bounds, states[k], bool(active[k]))
        naive[j] = time.perf_counter() - t0
    naive *= 1e6
    med, p99 = np.median(fast), np.percentile(fast, 99)
    print(f"wmm AMD + tertiary step ({len(fast)} steps, base active in {100 * active.mean():.0f} %): "
          f"median {med:6.1f} µs, p99 {p99:6.1f} µs; median / {TARGET_US:.0f} µs target = {med / TARGET_US:.2f}x")
    print(f"naive dense-NumPy step ({len(naive)} steps): median {np.median(naive):6.1f} µs, "
          f"p99 {np.percentile(naive, 99):6.1f} µs; speed-up of rhi {np.median(naive) / med:.1f}x")


if __name__ == "__main__":
    main()
