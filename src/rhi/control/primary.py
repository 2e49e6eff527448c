"""Primary (task-space) control laws: the force the device renders to the user's hand.

A primary law returns two task-space forces ``(F_render, F_extra)`` [N]: ``F_render`` is
the rendered environment force, which saturation handling may scale by α (eq. 7.9);
``F_extra`` (damping, compensation terms, the μ of eq. 7.9) is never scaled. The joint
torque is ``τ_m = Jᵀ(α F_render + F_extra)`` (eqs. 6.5, 7.4).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Protocol

import numpy as np

from rhi._validate import as_array
from rhi.errors import InvalidInput


class PrimaryLaw(Protocol):
    """A task-space control law F_m (thesis eqs. 6.5, 7.2)."""

    def forces(
        self, t: float, x: np.ndarray, xdot: np.ndarray, sensors: Mapping[str, np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray]:
        """(F_render, F_extra), each (m,) [N], from the end-effector position x (m,) [m],
        its velocity ẋ (m,) [m/s] and the sensor readings."""
        ...

    def required_sensors(self) -> tuple[str, ...]:
        """Names of the sensor entries `forces` reads."""
        ...


def _damping(name: str, B, m: int | None = None) -> np.ndarray:
    B = as_array(name, B)
    if B.ndim == 0:
        if B < 0:
            raise InvalidInput(f"{name}: must be >= 0, got {float(B)}")
        return B
    if B.ndim != 2 or B.shape[0] != B.shape[1]:
        raise InvalidInput(f"{name}: expected a scalar or an (m, m) matrix, got shape {B.shape}")
    if np.any(np.linalg.eigvalsh(0.5 * (B + B.T)) < -1e-12):
        raise InvalidInput(f"{name}: must be positive semi-definite")
    return B


@dataclasses.dataclass(frozen=True)
class ForceRendering:
    """Render a measured/virtual environment force: F_m = F_e − B_d ẋ (thesis eq. 7.2 without C_x, G_x, F_x).

    ``sensors["force"]`` is the force the device should apply to the user's hand [N]
    (the thesis's desired force feedback; eq. 7.2 writes it as −F_e with F_e the wrench
    the device applies to the environment). Coriolis, gravity and friction compensation
    of eq. 7.2 are left to the controller's joint-space gravity term or omitted.

    Attributes:
        damping: B_d, scalar or (m, m) PSD [N s/m] (thesis §7.5: 0.01).
        gain: scale of the rendered force.
    """

    damping: float | np.ndarray = 0.0
    gain: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "damping", _damping("damping", self.damping))
        if not np.isfinite(self.gain):
            raise InvalidInput(f"gain: must be finite, got {self.gain!r}")

    def required_sensors(self) -> tuple[str, ...]:
        return ("force",)

    def forces(self, t, x, xdot, sensors):
        F = self.gain * np.asarray(sensors["force"], dtype=float)
        return F, -(self.damping @ xdot if np.ndim(self.damping) else self.damping * xdot)


@dataclasses.dataclass(frozen=True)
class SpringPalpation:
    """A virtual spring wall: F_m = K_e δX − B_d ẋ with δX = x0 − x (thesis eqs. 6.21, 7.20).

    The spring pushes the hand back towards the start point x0 once it has moved along
    ``normal`` (the contact direction); with ``normal=None`` it acts in every direction.

    Attributes:
        stiffness: K_e [N/m] (thesis: 1000).
        x0: (m,) start point X₀ [m].
        normal: (m,) direction into the environment, or None.
        damping: B_d scalar or (m, m) [N s/m].
    """

    stiffness: float
    x0: tuple[float, ...]
    normal: tuple[float, ...] | None = None
    damping: float | np.ndarray = 0.0

    def __post_init__(self) -> None:
        if not np.isfinite(self.stiffness) or self.stiffness < 0:
            raise InvalidInput(f"stiffness: must be finite and >= 0, got {self.stiffness!r}")
        object.__setattr__(self, "x0", as_array("x0", self.x0, ndim_min=1))
        if self.normal is not None:
            nrm = as_array("normal", self.normal, ndim_min=1)
            if np.linalg.norm(nrm) < 1e-12:
                raise InvalidInput("normal: zero-length direction vector")
            object.__setattr__(self, "normal", nrm / np.linalg.norm(nrm))
        object.__setattr__(self, "damping", _damping("damping", self.damping))

    def required_sensors(self) -> tuple[str, ...]:
        return ()

    def forces(self, t, x, xdot, sensors):
        dx = x - self.x0
        if self.normal is None:
            F = -self.stiffness * dx
        else:
            depth = float(self.normal @ dx)
            F = -self.stiffness * max(depth, 0.0) * self.normal
        return F, -(self.damping @ xdot if np.ndim(self.damping) else self.damping * xdot)
