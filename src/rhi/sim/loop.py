"""The simulation loop: controller at a fixed rate (1 kHz), plant substeps, hand, environments, logs."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Protocol

import numpy as np

from rhi.errors import InvalidInput
from rhi.sim.plant import Plant


class Controller(Protocol):
    """Anything with `step(t, q, dq, sensors) -> tau` (e.g. `rhi.control.NullSpaceController`)."""

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, sensors: dict) -> np.ndarray: ...


class ForceField(Protocol):
    """An environment or hand: the force on the handle."""

    def force(self, *args) -> np.ndarray: ...


@dataclasses.dataclass
class Log:
    """What a run recorded, one row per control tick (N ticks).

    Attributes:
        t: (N,) time [s].
        q, dq: (N, n) motor angles [rad] and velocities [rad/s] (the encoders).
        tau: (N, n) commanded torques [N m].
        x, xdot: (N, m) true handle position [m] and velocity [m/s] (MuJoCo).
        F_hand: (N, m) force the hand applied [N].
        F_env: (N, m) virtual-environment force sent to the controller [N].
        ft: (N, 6) F/T sensor (force [N], torque [N m]) in world axes.
        work: (N,) user work W = ∫ F_hᵀ ẋ dt up to each tick (eq. 5.15) [J].
        V, omega, alpha, beta: (N,) controller state (ASO, FME activation, force scaling,
            tertiary scaling); NaN where the controller has no such state.
        slave_x: (N, m_s) slave position [m] in teleoperation, else empty.
        fault: why the controller stopped, if it did.
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    x: np.ndarray
    xdot: np.ndarray
    F_hand: np.ndarray
    F_env: np.ndarray
    ft: np.ndarray
    work: np.ndarray
    V: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    slave_x: np.ndarray
    fault: str | None = None

    def to_csv(self, path) -> None:
        """Write the log as CSV (one column per scalar, header names like q1, x1, F_hand2)."""
        cols, names = [], []
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, np.ndarray) or v.size == 0:
                continue
            v = v.reshape(len(v), -1)
            cols.append(v)
            names += [f.name] if v.shape[1] == 1 else [f"{f.name}{i + 1}" for i in range(v.shape[1])]
        np.savetxt(path, np.hstack(cols), delimiter=",", header=",".join(names), comments="")


def simulate(
    plant: Plant,
    controller: Controller,
    *,
    duration: float,
    hand=None,
    virtual=None,
    physical=None,
    teleop=None,
    rate: float = 1000.0,
    progress: Callable[[int, int], None] | None = None,
) -> Log:
    """Run the controller against the plant for `duration` seconds.

    Each tick the controller receives the encoders q, dq and the sensors
    {"ft": (6,) F/T reading, "force": (m,) virtual-environment force}; the virtual force is
    computed from the *controller's* model (FK of the measured q), as a haptic rendering loop
    does. Between ticks the plant advances `round(1/(rate·timestep))` physics steps with the
    hand and the physical environment re-evaluated at every step.

    Args:
        plant: the simulated device (already `reset` to its start).
        controller: `step(t, q, dq, sensors) -> tau` (n,) [N m].
        duration: simulated time [s].
        hand: the user, `force(t, x, ẋ)` (e.g. `Hand`, `PushForce`); None: no hand.
        virtual: environment rendered by the controller, `force(x, ẋ)`; None: free space.
        physical: environment acting on the handle in the plant, `force(x, ẋ)` (e.g. a stop).
        teleop: a `Teleoperation` whose slave follows the master each tick.
        rate: control rate [Hz].
        progress: callback(done, total) every 1 % of the ticks.
    """
    if not np.isfinite(duration) or duration <= 0:
        raise InvalidInput(f"duration: must be > 0 [s], got {duration!r}")
    if not np.isfinite(rate) or rate <= 0:
        raise InvalidInput(f"rate: must be > 0 [Hz], got {rate!r}")
    sub = max(1, round(1.0 / (rate * plant.timestep)))
    dt = sub * plant.timestep
    N = int(round(duration / dt))
    n, m = plant.n, plant.m
    dev = getattr(controller, "device", plant.device)
    z = lambda *s: np.zeros((N, *s))  # noqa: E731
    log = Log(t=z(), q=z(n), dq=z(n), tau=z(n), x=z(m), xdot=z(m), F_hand=z(m), F_env=z(m), ft=z(6), work=z(),
              V=np.full(N, np.nan), omega=np.full(N, np.nan), alpha=np.full(N, np.nan), beta=np.full(N, np.nan),
              slave_x=z(teleop.slave.m) if teleop is not None else np.zeros((0,)))
    zero_m = np.zeros(m)
    W = 0.0
    every = max(1, N // 100)
    state = getattr(controller, "state", None)
    for k in range(N):
        t = plant.time
        q, dq = plant.q, plant.dq
        ft = plant.ft()
        if virtual is not None:
            kin = dev.terms(q, dq, check=False)
            F_env = virtual.force(kin.x, kin.xdot)
        else:
            F_env = zero_m
        tau = np.asarray(controller.step(t, q, dq, {"ft": ft, "force": F_env}), dtype=float)
        F_h = zero_m
        for s in range(sub):
            x, xdot = plant.x, plant.xdot
            F_h = hand.force(t + s * plant.timestep, x, xdot) if hand is not None else zero_m
            F = F_h + physical.force(x, xdot) if physical is not None else F_h
            plant.apply(tau, F)
            plant.step()
            W += float(F_h @ plant.xdot) * plant.timestep
        if teleop is not None:
            log.slave_x[k] = teleop.follow(dev.fk(q), dt)
        log.t[k], log.q[k], log.dq[k], log.tau[k] = t, q, dq, tau
        log.x[k], log.xdot[k], log.F_hand[k], log.F_env[k], log.ft[k] = plant.x, plant.xdot, F_h, F_env, ft
        log.work[k] = W
        if state is not None:
            log.V[k], log.omega[k] = state.V, state.omega
            log.alpha[k], log.beta[k] = state.alpha, state.beta
            if state.stopped and log.fault is None:
                log.fault = state.fault
        if progress is not None and (k % every == 0 or k == N - 1):
            progress(k + 1, N)
    return log
