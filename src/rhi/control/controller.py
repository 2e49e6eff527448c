"""The null-space haptic controller: primary law + prioritised null-space objectives + saturation handling.

One tick (`NullSpaceController.step`) computes, from the joint sensors and the sensor dict:

1. the primary task-space force (F_render, F_extra) and τ_m = Jᵀ(F_render + F_extra) + g(q)
   (eqs. 6.5, 7.2–7.4);
2. the actuator saturation observer V of τ_m (eq. 6.14) and, when a desired-FME schedule
   is configured, the hysteresis and cosine transition Ω (eqs. 6.15–6.19) giving
   M_des = Ω M_Free + (1 − Ω) M_Stiff for the FME-matching objective (eq. 6.10);
3. the allocation of τ_m within the torque box: none / simple scaling / ASCM (Algorithm 1) /
   LP optimum, with force scaling α (eq. 7.9);
4. the objective torque τ_to = −Σ β_i ∂ν_i/∂q − k_D q̇ (eqs. 3.20–3.21, 6.6, 7.17), projected
   into the null space of the task and of ASCM and scaled by the β of Algorithm 2 (eq. 7.16).

Torques never leave the torque box. Non-finite sensor values stop the controller (zero
torque, latched) and record why in the state.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np

from rhi.control.objectives import FMEMatching, Objective, _spd
from rhi.control.primary import PrimaryLaw
from rhi.control.saturation import (
    Allocation,
    TransitionConfig,
    TransitionState,
    allocate_lp,
    allocate_none,
    allocate_scaling,
    ascm,
    aso_volume,
    check_torque_limits,
    null_basis,
    tertiary,
    transition_step,
)
from rhi.device import Device
from rhi.errors import InvalidInput
from rhi.metrics import dynamic_pinv, nullspace_projector, weighted_pinv

Saturation = Literal["none", "scaling", "ascm", "lp"]


@dataclasses.dataclass(frozen=True)
class ObjectiveTerm:
    """A null-space objective with its gradient step size (β of eq. 6.6, Λ of eq. 7.17)."""

    objective: Objective
    gain: float

    def __post_init__(self) -> None:
        if not np.isfinite(self.gain) or self.gain < 0:
            raise InvalidInput(f"gain: must be finite and >= 0, got {self.gain!r}")


@dataclasses.dataclass(frozen=True, eq=False)
class FMESchedule:
    """Desired-FME matching switched by the ASO between M_Free^des and M_Stiff^des (thesis §6.3).

    Attributes:
        free: (m, m) SPD M_Free^des (eq. 6.12).
        stiff: (m, m) SPD M_Stiff^des (eq. 6.13).
        gain: gradient step β of eq. 6.6 (thesis: 20).
        transition: thresholds ε₁, ε₂, ρ and ASO shape S.
    """

    free: np.ndarray
    stiff: np.ndarray
    gain: float = 20.0
    transition: TransitionConfig = dataclasses.field(default_factory=TransitionConfig)

    def __post_init__(self) -> None:
        free = _spd("free", self.free)
        stiff = _spd("stiff", self.stiff)
        if free.shape != stiff.shape:
            raise InvalidInput(f"free/stiff: shapes differ, {free.shape} vs {stiff.shape}")
        if not np.isfinite(self.gain) or self.gain < 0:
            raise InvalidInput(f"gain: must be finite and >= 0, got {self.gain!r}")
        object.__setattr__(self, "free", free)
        object.__setattr__(self, "stiff", stiff)

    @property
    def distance(self) -> float:
        """‖M_Free − M_Stiff‖_F (eq. 6.19)."""
        return float(np.linalg.norm(self.free - self.stiff))

    def desired(self, omega: float) -> np.ndarray:
        """Ω M_Free + (1 − Ω) M_Stiff (eq. 6.16)."""
        return omega * self.free + (1.0 - omega) * self.stiff


@dataclasses.dataclass(frozen=True)
class ControllerConfig:
    """Everything the controller needs besides the device.

    Attributes:
        primary: the task-space law.
        objectives: null-space objectives with step sizes (τ_to = −Σ gain ∂ν/∂q).
        fme: optional ASO-switched FME matching (adds FMEMatching(M_des(t)) to the objectives).
        damping: null-space joint damping k_D [N m s/rad] (eqs. 3.20, 6.6).
        saturation: "none" | "scaling" | "ascm" | "lp".
        projector: "dynamic" (J# = M⁻¹Jᵀ(JM⁻¹Jᵀ)⁻¹) or "kinematic" (J⁺).
        torque_min, torque_max: (n,) limits [N m]; None: the device's.
        gravity_compensation: add g(q) to τ_m.
        aso_shape: S of eq. 6.14 when no FME schedule is given.
    """

    primary: PrimaryLaw
    objectives: Sequence[ObjectiveTerm] = ()
    fme: FMESchedule | None = None
    damping: float = 0.1
    saturation: Saturation = "ascm"
    projector: Literal["dynamic", "kinematic"] = "dynamic"
    torque_min: np.ndarray | None = None
    torque_max: np.ndarray | None = None
    gravity_compensation: bool = True
    aso_shape: float = 50.0


@dataclasses.dataclass
class ControllerState:
    """Explicit controller state, updated by every tick (inspect it; replace it to reset).

    Attributes:
        t: time of the last tick [s].
        transition: FME transition state.
        omega: activation Ω of the desired FME (1: free, 0: stiff).
        V: ASO volume of the last τ_m.
        alpha: force scaling of the last tick.
        beta: tertiary scaling of the last tick.
        saturated: (n,) joints ASCM held at a limit.
        tau: (n,) last commanded torque [N m].
        stopped: latched safe stop (zero torque).
        fault: why it stopped.
        ticks: number of ticks.
    """

    t: float = -math.inf
    transition: TransitionState = dataclasses.field(default_factory=TransitionState)
    omega: float = 1.0
    V: float = 1.0
    alpha: float = 1.0
    beta: float = 0.0
    saturated: np.ndarray | None = None
    tau: np.ndarray | None = None
    stopped: bool = False
    fault: str | None = None
    ticks: int = 0


class NullSpaceController:
    """Primary law + null-space objectives + saturation handling for a redundant haptic interface.

    Args:
        device: the device model (Jacobian, dJ/dq, inertia, gravity).
        config: the controller configuration.
        state: initial state (default: fresh).

    Raises:
        InvalidInput / InfeasibleLimits / NotSPD: bad configuration, naming the argument.
    """

    def __init__(self, device: Device, config: ControllerConfig, state: ControllerState | None = None) -> None:
        if config.saturation not in ("none", "scaling", "ascm", "lp"):
            raise InvalidInput(f"saturation: expected 'none', 'scaling', 'ascm' or 'lp', got {config.saturation!r}")
        if config.projector not in ("dynamic", "kinematic"):
            raise InvalidInput(f"projector: expected 'dynamic' or 'kinematic', got {config.projector!r}")
        if not np.isfinite(config.damping) or config.damping < 0:
            raise InvalidInput(f"damping: must be finite and >= 0, got {config.damping!r}")
        if not np.isfinite(config.aso_shape) or config.aso_shape <= 0:
            raise InvalidInput(f"aso_shape: must be finite and > 0, got {config.aso_shape!r}")
        lo = device.torque_min if config.torque_min is None else config.torque_min
        hi = device.torque_max if config.torque_max is None else config.torque_max
        self.lo, self.hi = check_torque_limits(lo, hi, device.n)
        if config.fme is not None and config.fme.free.shape != (device.m, device.m):
            raise InvalidInput(f"fme: desired FMEs must be ({device.m}, {device.m}), got {config.fme.free.shape}")
        self.device = device
        self.config = config
        self._fme = None if config.fme is None else FMEMatching(config.fme.free, self.hi)
        self.state = state or ControllerState()
        self._sensors = tuple(config.primary.required_sensors())

    def reset(self) -> None:
        """Fresh state (clears a safe stop)."""
        self.state = ControllerState()

    def _stop(self, why: str) -> np.ndarray:
        s = self.state
        s.stopped, s.fault = True, why
        s.tau = np.zeros(self.device.n)
        return s.tau

    def step(self, t: float, q, dq, sensors: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """One control tick.

        Args:
            t: time [s].
            q: (n,) joint positions [rad].
            dq: (n,) joint velocities [rad/s].
            sensors: named readings the primary law needs (e.g. "force": (m,) [N]).

        Returns:
            τ: (n,) joint torques [N m], within [torque_min, torque_max]; zeros after a safe stop.
        """
        s = self.state
        dev, cfg = self.device, self.config
        if s.stopped:
            return np.zeros(dev.n)
        sensors = sensors or {}
        q = np.asarray(q, dtype=float)
        dq = np.asarray(dq, dtype=float)
        if q.shape != (dev.n,) or dq.shape != (dev.n,):
            raise InvalidInput(f"q/dq: expected shape ({dev.n},), got {q.shape} and {dq.shape}")
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(dq)) and math.isfinite(t)):
            return self._stop(f"non-finite joint reading at t={t}: q={q.tolist()}, dq={dq.tolist()}")
        for name in self._sensors:
            if name not in sensors:
                raise InvalidInput(f"sensors: missing {name!r} required by the primary law")
            if not np.all(np.isfinite(np.asarray(sensors[name], dtype=float))):
                return self._stop(f"non-finite sensor {name!r} at t={t}: {np.asarray(sensors[name]).tolist()}")

        J = dev.jacobian(q)
        x = dev.fk(q)
        M = dev.mass_matrix(q) if cfg.projector == "dynamic" else None
        F_r, F_x = cfg.primary.forces(t, x, J @ dq, sensors)
        a = J.T @ F_r
        b = J.T @ F_x
        if cfg.gravity_compensation:
            b = b + dev.gravity(q)

        # ASO and desired-FME transition
        tr = cfg.fme.transition if cfg.fme is not None else None
        s.V = aso_volume(a + b, self.lo, self.hi, tr.S if tr else cfg.aso_shape)
        if cfg.fme is not None:
            s.transition, s.omega = transition_step(s.transition, t, s.V, cfg.fme.distance, tr)

        # allocation within the torque box
        Z = null_basis(J, M)
        if cfg.saturation == "ascm":
            al = ascm(a, b, Z, self.lo, self.hi)
        elif cfg.saturation == "lp":
            al = allocate_lp(a, b, Z, self.lo, self.hi)
        elif cfg.saturation == "scaling":
            al = allocate_scaling(a, b, self.lo, self.hi)
        else:
            al = allocate_none(a, b, self.lo, self.hi)

        # null-space objectives (tertiary, in the null space of the task and of ASCM)
        tau_to = -cfg.damping * dq
        dJ = None
        if cfg.fme is not None and cfg.fme.gain > 0:
            dJ = dev.jacobian_derivative(q)
            tau_to = tau_to - cfg.fme.gain * self._fme.gradient_from(J, dJ, cfg.fme.desired(s.omega))
        for term in cfg.objectives:
            if term.gain > 0:
                tau_to = tau_to - term.gain * np.asarray(term.objective.gradient(dev, q), dtype=float)
        if not np.all(np.isfinite(tau_to)):
            return self._stop(f"non-finite null-space objective torque at t={t}")
        N = nullspace_projector(J, M)
        delta, beta = tertiary(al.tau, al.saturated, Z, tau_to, self.lo, self.hi, N)
        tau = np.clip(al.tau + delta, self.lo, self.hi)

        s.t, s.alpha, s.beta, s.saturated, s.tau = t, al.alpha, beta, al.saturated, tau
        s.ticks += 1
        return tau

    def last_allocation(self) -> tuple[float, float]:
        """(α, β) of the last tick."""
        return self.state.alpha, self.state.beta


def output_force(J: np.ndarray, tau: np.ndarray, M: np.ndarray | None = None) -> np.ndarray:
    """Task-space force produced by joint torques, J#ᵀ τ (dynamic) or J⁺ᵀ τ (kinematic) [N]: (m,)."""
    return (weighted_pinv(J) if M is None else dynamic_pinv(J, M)).T @ tau


__all__ = [
    "Allocation",
    "ControllerConfig",
    "ControllerState",
    "FMESchedule",
    "NullSpaceController",
    "ObjectiveTerm",
    "output_force",
]
