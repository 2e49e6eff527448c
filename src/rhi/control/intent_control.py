"""The estimated intent as the task direction of the VME and FME objectives (thesis eqs. 3.22–3.23, 6.10–6.13).

`IntentVME` and `IntentFME` are null-space objectives whose u is read from an estimator
(`rhi.control.intent`) at every evaluation; `IntentController` wraps a
`NullSpaceController` and feeds the estimator the hand force (F/T sensor) and the
handle velocity J q̇ before each tick. With a `KnownIntent` the objectives compute exactly
what `VMEMatching(u)` and `FMEMatching(M_des(u))` compute (same arithmetic, bit for bit) and
the wrapper adds nothing to the tick.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from rhi.control.compiled import CompiledObjective
from rhi.control.intent import KnownIntent
from rhi.control.objectives import (
    FMEMatching,
    VMEMatching,
    desired_fme_free,
    desired_fme_stiff,
)
from rhi.devices.model import Device, DeviceTerms
from rhi.errors import InvalidInput


class _FollowsIntent:
    """Rebuild the wrapped fixed-u objective whenever the estimator's u changes."""

    def __init__(self, source) -> None:
        if not hasattr(source, "u") or not callable(getattr(source, "update", None)):
            raise InvalidInput(f"source: expected an intent estimator with .u and .update(), got {source!r}")
        self.source = source
        self._u: np.ndarray | None = None
        self._obj: Any = None

    def _build(self, u: np.ndarray):  # pragma: no cover - abstract
        raise NotImplementedError

    def current(self):
        """The fixed-u objective for the estimator's current u."""
        u = self.source.u
        if self._obj is None or self._u is None or not np.array_equal(u, self._u):
            u_now = np.array(u, dtype=float)
            self._u = u_now
            self._obj = self._build(u_now)
        return self._obj

    def value(self, device: Device, q: np.ndarray) -> float:
        return self.current().value(device, q)

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        return self.current().gradient(device, q)

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        return self.current().gradient_at(terms)


class IntentVME(_FollowsIntent):
    """`VMEMatching` (eq. 3.22) along the estimator's current u; β of eq. 3.23 (thesis: 0.01)."""

    def __init__(self, source, beta: float = 0.01) -> None:
        super().__init__(source)
        self.beta = beta
        self.current()  # validates β

    def _build(self, u: np.ndarray) -> VMEMatching:
        return VMEMatching(tuple(u.tolist()), self.beta)

    def compiled(self, device: Device) -> CompiledObjective:
        """VME matching to M_des of the estimator's u of each tick, computed by the whole compiled tick."""
        return CompiledObjective("vme_live", live=lambda: self.current().desired(), source=self.source,
                                 axes=(1.0, self.beta))


class IntentFME(_FollowsIntent):
    """`FMEMatching` (eq. 6.10) to M_Free^des(u) (eq. 6.12) or M_Stiff^des(u) (eq. 6.13) of the estimator's u.

    Args:
        source: intent estimator. K, zeta: 𝒦 and ζ (`fme_shape`). torque_max: (n,) limits [N m].
        mode: "free" or "stiff".
    """

    def __init__(self, source, K: float, zeta: float, torque_max, mode: str = "stiff") -> None:
        if mode not in ("free", "stiff"):
            raise InvalidInput(f"mode: expected 'free' or 'stiff', got {mode!r}")
        super().__init__(source)
        self.K, self.zeta, self.torque_max, self.mode = K, zeta, torque_max, mode
        self.current()

    def _build(self, u: np.ndarray) -> FMEMatching:
        make = desired_fme_free if self.mode == "free" else desired_fme_stiff
        return FMEMatching(make(u, self.K, self.zeta), self.torque_max)

    def compiled(self, device: Device) -> CompiledObjective | None:
        """FME matching to M_des of the estimator's u of each tick, computed by the whole compiled tick."""
        c = self.current().compiled(device)
        if c is None:
            return None
        axes = (self.K, self.zeta) if self.mode == "stiff" else (self.zeta, self.K)
        return dataclasses.replace(c, live=lambda: self.current().desired, source=self.source, axes=axes)


class IntentController:
    """A null-space controller whose objectives follow an intent estimator fed by the handle's sensors.

    Each tick: F_h = the F/T reading's force on the task axes (``sensors[sensor]``, (6,) world
    wrench or (m,)), ẋ = J q̇; `estimator.update(F_h, ẋ)`; then the wrapped controller's step.
    With a `KnownIntent` nothing is computed before the wrapped step.

    Args:
        controller: the `NullSpaceController` (its objectives: `IntentVME` / `IntentFME` on `estimator`).
        estimator: the intent estimator.
        sensor: name of the F/T reading (`rhi.sim`: "ft").
    """

    def __init__(self, controller, estimator, *, sensor: str = "ft") -> None:
        self.controller, self.estimator, self.sensor = controller, estimator, sensor
        self.device: Device = controller.device
        self._known = isinstance(estimator, KnownIntent)
        self.history: list[tuple[float, np.ndarray, float]] = []

    @property
    def state(self):
        """The wrapped controller's state."""
        return self.controller.state

    def required_sensors(self) -> dict[str, int | None]:
        """The device sensors read, name → width: the wrapped controller's and the estimator's F/T reading."""
        need = dict(self.controller.required_sensors())
        if not self._known:
            need.setdefault(self.sensor, None)
        return need

    def reset(self) -> None:
        """Reset the wrapped controller, the estimator and the history."""
        self.controller.reset()
        self.estimator.reset()
        self.history.clear()

    def step(self, t: float, q, dq, sensors: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """Update the estimate from the sensors, then one tick of the wrapped controller: τ (n,) [N m]."""
        if not self._known:
            if sensors is None or self.sensor not in sensors:
                raise InvalidInput(f"sensors: missing {self.sensor!r} needed by the intent estimator")
            dev = self.device
            v = np.asarray(sensors[self.sensor], dtype=float)
            F = v[:3][dev.task_rows] if v.shape == (6,) else v
            q_a = np.asarray(q, dtype=float)
            xdot = dev.jacobian(q_a) @ np.asarray(dq, dtype=float)
            if np.all(np.isfinite(F)) and np.all(np.isfinite(xdot)):
                at = getattr(self.estimator, "update_at", None)  # estimators that also read the time
                if at is not None:
                    at(t, F, xdot)
                else:
                    self.estimator.update(F, xdot)
        self.history.append((float(t), np.array(self.estimator.u), float(self.estimator.confidence)))
        return self.controller.step(t, q, dq, sensors)
