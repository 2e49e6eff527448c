"""What a null-space controller is given and what it keeps: `ControllerConfig`, `ControllerState`.

And `ControllerParts`, what a tick reads of its controller: the compiled tick (`rhi.control.tick`) and the
reference tick (`rhi.control.reference`) take a `rhi.control.NullSpaceController` through it, so neither
imports the controller that calls them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Literal, Protocol

import numpy as np

from rhi.control.allocation import AllocationMethod, Saturation
from rhi.control.objectives import Objective, ObjectiveTerm
from rhi.control.passivity import PassivityState
from rhi.control.primary import PrimaryLaw
from rhi.control.schedule import ScheduledObjective
from rhi.control.tank import NullSpaceTank, TankState
from rhi.control.transition import TransitionState
from rhi.devices.model import Device


@dataclasses.dataclass(frozen=True)
class ControllerConfig:
    """Everything the controller needs besides the device.

    Attributes:
        primary: the task-space law (e.g. `ImpedanceControl`, `ForceRendering`, `SpringPalpation`).
        objectives: null-space objectives with step sizes (τ_to = −Σ gain ∂ν/∂q); at most one of them
            scheduled by the ASO (`rhi.control.schedule`, e.g. `FMESchedule`).
        damping: null-space joint damping k_D [N m s/rad] (eqs. 3.20, 6.6).
        saturation: the allocation strategy (`rhi.control.allocation`), by name — "none" | "scaling" |
            "ascm" | "lp" (the LP optimum, `rhi.control.allocation.lp`) or any registered one — or an
            `AllocationMethod` itself (e.g. ``LPOptimum(solver="active_set")``).
        projector: "dynamic" (J# = M⁻¹Jᵀ(JM⁻¹Jᵀ)⁻¹) or "pseudoinverse" (J⁺).
        torque_min, torque_max: (n,) limits [N m]; None: the device's.
        gravity_compensation: add the null-space part (I − JᵀJ#ᵀ) g(q) of the gravity torque;
            with a primary law that compensates G_x (eqs. 5.4, 7.2) the whole g(q) is compensated.
        aso_shape: S of eq. 6.14 when no scheduled objective gives its own.
        implementation: "fast" (default) or "reference" (the slow oracle; same torques).
        null_space: how the objectives' null-space torque meets the torque box: "scaled" (Algorithm 2,
            eq. 7.16: scaled by the largest β <= 1 that keeps the box, projected off ASCM's held joints)
            or "clipped" (chapter 6 as written, eqs. 6.2–6.6: τ = α τ_m + (I − JᵀJ#ᵀ)τ_S, then the
            programmed limits clip each joint).
        tank: the null-space energy tank (`rhi.control.tank`): the objectives' torque spends only the
            energy the null space has dissipated (the wall, the allocation and the safety torques are never
            scaled); None: off (the thesis's controller). Needs ``null_space="scaled"``.
    """

    primary: PrimaryLaw
    objectives: Sequence[ObjectiveTerm] = ()
    damping: float = 0.1
    saturation: Saturation | AllocationMethod = "ascm"
    projector: Literal["dynamic", "pseudoinverse"] = "dynamic"
    torque_min: np.ndarray | None = None
    torque_max: np.ndarray | None = None
    gravity_compensation: bool = True
    aso_shape: float = 50.0
    implementation: Literal["fast", "reference"] = "fast"
    null_space: Literal["scaled", "clipped"] = "scaled"
    tank: NullSpaceTank | None = None


@dataclasses.dataclass
class ControllerState:
    """Explicit controller state, updated by every tick (inspect it; replace it to reset).

    Attributes:
        t: time of the last tick [s].
        transition: the scheduled objective's transition state (`rhi.control.schedule`).
        omega: its activation Ω (1: free, 0: stiff; 1 without one).
        V: ASO volume of the last τ_m.
        alpha: force scaling of the last tick (of the allocation, times the room made for the safety torque).
        beta: tertiary scaling of the last tick (the objectives only; damping and limit barrier act whatever β).
        saturated: (n,) joints ASCM held at a limit.
        clipped: the unscaled torque b (damping, compensation, gravity) alone left the box, so
            the last torque was clipped and the task force is not α F_render + F_extra.
        tau: (n,) last commanded torque [N m].
        stopped: latched safe stop (zero torque).
        fault: why it stopped.
        ticks: number of ticks.
        E_obs: energy the passivity observer has seen flow into the controller [J]
            (`rhi.control.passivity`; negative: energy created); NaN without a passivity option.
        alpha_pc: damping rate α of the passivity controller at the last tick [1/s]; NaN without one.
        tank: the null-space energy tank (`rhi.control.tank`): its energy T and the objectives' scale λ;
            None without ``ControllerConfig.tank`` (the controller creates it).
    """

    t: float = -math.inf
    transition: TransitionState = dataclasses.field(default_factory=TransitionState)
    omega: float = 1.0
    V: float = 1.0
    alpha: float = 1.0
    beta: float = 0.0
    saturated: np.ndarray | None = None
    clipped: bool = False
    tau: np.ndarray | None = None
    stopped: bool = False
    fault: str | None = None
    ticks: int = 0
    E_obs: float = math.nan
    alpha_pc: float = math.nan
    tank: TankState | None = None


class ControllerParts(Protocol):
    """What a tick reads of its controller (`rhi.control.NullSpaceController` has all of it)."""

    device: Device
    config: ControllerConfig
    state: ControllerState
    lo: np.ndarray
    hi: np.ndarray
    aso_shape: float
    allocation: AllocationMethod
    objectives: list[tuple[float, Objective]]
    barriers: list[tuple[float, Objective]]
    schedule: tuple[float, ScheduledObjective] | None

    @property
    def passivity(self) -> PassivityState | None:
        """The passivity layer's state, or None."""
        ...


__all__ = ["ControllerConfig", "ControllerParts", "ControllerState"]
