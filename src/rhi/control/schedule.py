"""Scheduled objectives: a null-space objective that the actuator saturation observer switches (thesis §6.3).

A scheduled objective is an objective term like any other (``ObjectiveTerm(FMESchedule(...), gain)`` in
``ControllerConfig.objectives``) that also provides

- ``advance(state, t, V) -> (state, Ω)``: its `TransitionState` after a tick at t [s] whose primary torque
  has the ASO volume V (eq. 6.14), and the activation Ω ∈ [0, 1] of that tick;
- ``objective(omega, torque_max) -> Objective``: the objective the controller follows at activation Ω;
- ``aso_shape``: the ASO's shape factor S (eq. 6.14) it was tuned with.

The controller keeps its `TransitionState` and Ω in `rhi.control.ControllerState` (``transition``, ``omega``),
so a controller takes at most one. Without a compiled form the controller runs every tick on the reference
route (the ASO volume V is the compiled tick's) and says so (`NullSpaceController.route`). `FMESchedule` is
chapter 6's; it computes itself in the compiled tick (``compiled(device)``, kind "fme_schedule" of
`rhi.control.compiled`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from rhi.control.compiled import CompiledObjective
from rhi.control.objectives import FMEMatching, Objective, ObjectiveTerm
from rhi.control.transition import TransitionConfig, TransitionState, transition_step
from rhi.devices.model import Device, DeviceTerms
from rhi.errors import InvalidInput
from rhi.metrics.spd import spd_matrix


class ScheduledObjective(Objective, Protocol):
    """An objective the ASO schedules (see the module); ``compiled(device)`` of kind "fme_schedule" optional."""

    @property
    def aso_shape(self) -> float:
        """The ASO's shape factor S (eq. 6.14)."""
        ...

    def advance(self, state: TransitionState, t: float, V: float) -> tuple[TransitionState, float]:
        """(state, Ω) after a tick at t [s] with ASO volume V."""
        ...

    def objective(self, omega: float, torque_max: np.ndarray) -> Objective:
        """The objective at activation Ω with torque limits (n,) [N m]."""
        ...


@dataclasses.dataclass(frozen=True, eq=False)
class FMESchedule:
    """Desired-FME matching switched by the ASO between M_Free^des and M_Stiff^des (thesis §6.3).

    A scheduled objective (see the module): each tick the controller advances it with the ASO volume V
    (`advance`, eqs. 6.15–6.19) and follows the FME-matching objective it gives for that tick's activation
    Ω (`objective`, eqs. 6.10, 6.16), with the step of its `ObjectiveTerm` (β of eq. 6.6; thesis: 20).
    As a plain objective (`value`, `gradient`) it is the matching to M_Free^des (Ω = 1, where it rests)
    with the device's torque limits.

    Attributes:
        free: (m, m) SPD M_Free^des (eq. 6.12).
        stiff: (m, m) SPD M_Stiff^des (eq. 6.13).
        transition: thresholds ε₁, ε₂, ρ and ASO shape S.
    """

    free: np.ndarray
    stiff: np.ndarray
    transition: TransitionConfig = dataclasses.field(default_factory=TransitionConfig)
    _distance: float = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        free = spd_matrix("free", self.free)
        stiff = spd_matrix("stiff", self.stiff)
        if free.shape != stiff.shape:
            raise InvalidInput(f"free/stiff: shapes differ, {free.shape} vs {stiff.shape}")
        if not isinstance(self.transition, TransitionConfig):
            raise InvalidInput(f"transition: expected a rhi.control.TransitionConfig, got {self.transition!r:.60}")
        object.__setattr__(self, "free", free)
        object.__setattr__(self, "stiff", stiff)
        object.__setattr__(self, "_distance", float(np.linalg.norm(free - stiff)))

    @property
    def distance(self) -> float:
        """‖M_Free − M_Stiff‖_F (eq. 6.19)."""
        return self._distance

    @property
    def aso_shape(self) -> float:
        """The ASO's shape factor S (eq. 6.14) of `transition`."""
        return self.transition.S

    def desired(self, omega: float) -> np.ndarray:
        """Ω M_Free + (1 − Ω) M_Stiff (eq. 6.16)."""
        if omega == 1.0:
            return self.free
        if omega == 0.0:
            return self.stiff
        return omega * self.free + (1.0 - omega) * self.stiff

    def check(self, device: Device) -> None:
        """Raise InvalidInput unless the desired FMEs are (m, m) for `device`."""
        if self.free.shape != (device.m, device.m):
            raise InvalidInput(f"fme: desired FMEs must be ({device.m}, {device.m}), got {self.free.shape}")

    def advance(self, state: TransitionState, t: float, V: float) -> tuple[TransitionState, float]:
        """The transition state and activation Ω after a tick at t [s] with ASO volume V (eqs. 6.15–6.19)."""
        return transition_step(state, t, V, self.distance, self.transition)

    def objective(self, omega: float, torque_max: np.ndarray) -> FMEMatching:
        """The FME-matching objective at activation Ω: JBLD of M̂ to `desired(omega)` (eqs. 6.10, 6.16).

        Args:
            omega: activation Ω ∈ [0, 1] (1: free, 0: stiff).
            torque_max: (n,) torque limits T_i [N m] of the weighting W = diag(1/T_i) (eq. 6.9).
        """
        return FMEMatching(self.desired(omega), torque_max)

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν(q) of the matching to M_Free^des with the device's torque limits, for q: (n,) [rad]."""
        return self.objective(1.0, device.torque_max).value(device, q)

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q: (n,) of `value`."""
        return self.objective(1.0, device.torque_max).gradient(device, q)

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self.objective(1.0, terms.device.torque_max).gradient_at(terms)

    def compiled(self, device: Device) -> CompiledObjective:
        """The schedule as the compiled tick computes it (kind "fme_schedule"; the controller's torque weights)."""
        tc = self.transition
        return CompiledObjective("fme_schedule", desired=self.free, stiff=self.stiff,
                                 schedule=(self.distance, tc.eps1, tc.eps2, tc.rho))


def scheduled_term(terms: Sequence[ObjectiveTerm]) -> ObjectiveTerm | None:
    """The term of `terms` whose objective is scheduled (has ``advance`` and ``objective``), or None.

    Raises:
        InvalidInput: more than one (the controller's state holds one transition).
    """
    found = [t for t in terms if callable(getattr(t.objective, "advance", None))
             and callable(getattr(t.objective, "objective", None))]
    if len(found) > 1:
        names = ", ".join(type(t.objective).__name__ for t in found)
        raise InvalidInput(f"objectives: at most one scheduled objective (the controller's state holds one "
                           f"transition), got {names}")
    return found[0] if found else None


def schedule_of(terms: Sequence[ObjectiveTerm]) -> ScheduledObjective | None:
    """The scheduled objective of a configuration's `terms` (e.g. for a view to draw its M_des(Ω)), or None."""
    term = scheduled_term(terms)
    return None if term is None else term.objective  # type: ignore[return-value]


__all__ = ["FMESchedule", "ScheduledObjective", "schedule_of", "scheduled_term"]
