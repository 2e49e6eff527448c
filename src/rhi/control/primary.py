"""Primary (task-space) control laws: the force the device renders to the user's hand.

A primary law reads the per-tick `DeviceTerms` snapshot (x, ẋ, J, M_x, C_x, G_x, J#, …
of the device at (q, q̇), see `rhi.devices.model.Device.terms`) and the sensor readings, and
returns two task-space forces ``(F_render, F_extra)`` [N]: ``F_render`` is the rendered
environment force, which saturation handling may scale by α (eq. 7.9); ``F_extra`` (the
μ of eq. 7.9: damping and the Coriolis, gravity and friction compensation
``C_x ẋ + G_x + F_x`` of eqs. 5.4, 7.2) is never scaled. The joint torque is
``τ_m = Jᵀ(α F_render + F_extra)`` (eqs. 5.7, 6.5, 7.4).

Sign convention: every force here is the force the device applies to the user's hand,
in the world task axes of the device (``Device.task_axes``).

The laws that render an environment (`ForceRendering`, `SpringPalpation`) carry a
``passivity`` option, on by default: the controller then runs the time-domain passivity
observer and controller of `rhi.control.passivity` (Hannaford and Ryu 2002) around the
whole torque it sends. ``passivity=None`` renders exactly the thesis's law.

A law may also give its ``compiled(device)`` form (`rhi.control.compiled.CompiledLaw`), which the
whole compiled tick computes instead of calling ``forces``; the bundled laws do.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Protocol

import numpy as np

from rhi._validate import as_array, scalar
from rhi.control.compiled import CompiledLaw
from rhi.control.passivity import Passivity
from rhi.devices.model import Device, DeviceTerms
from rhi.errors import InvalidInput
from rhi.metrics.spd import spd_matrix


class PrimaryLaw(Protocol):
    """A task-space control law F_m (thesis eqs. 5.4, 6.5, 7.2)."""

    def forces(
        self, t: float, kin: DeviceTerms, sensors: Mapping[str, np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray]:
        """(F_render, F_extra), each (m,) [N], at time t [s] from the device terms and the sensors.

        The controller has checked that every sensor of `required_sensors` is present and finite.
        """
        ...

    def required_sensors(self) -> tuple[str, ...]:
        """Names of the sensor entries `forces` reads."""
        ...

    def check(self, device: Device) -> None:
        """Raise InvalidInput unless the law's parameters fit `device` (its m task rows and n joints).

        The controller calls it once, at construction.
        """
        ...

    # Optional: ``compiled(device) -> CompiledLaw | None``, the law as the whole compiled tick computes it
    # (`rhi.control.compiled`); without it, or where it gives None, the tick calls `forces` in Python.


def _damping(name: str, B) -> np.ndarray:
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


def _check_passivity(p) -> None:
    if p is not None and not isinstance(p, Passivity):
        raise InvalidInput(f"passivity: expected a rhi.control.Passivity or None, got {type(p).__name__}")


def _check_task_matrix(name: str, A: np.ndarray, m: int) -> None:
    if A.ndim == 2 and A.shape != (m, m):
        raise InvalidInput(f"{name}: expected a scalar or a ({m}, {m}) matrix for this device, got shape {A.shape}")


@dataclasses.dataclass(frozen=True, eq=False)
class JointFriction:
    """Model of the joint friction torques F_q(q̇) the controller compensates (thesis eq. 5.1's F_q).

    F_q = b ⊙ q̇ + f_c ⊙ tanh(q̇ / v_s): viscous plus Coulomb friction, the sign function
    smoothed over |q̇| ≲ v_s so the compensation stays continuous through zero velocity.
    Its end-effector reflection is F_x = J#ᵀ F_q (eq. 5.2).

    Attributes:
        viscous: b, scalar or (n,) [N m s/rad], >= 0.
        coulomb: f_c, scalar or (n,) [N m], >= 0.
        velocity_scale: v_s [rad/s], > 0.
    """

    viscous: float | np.ndarray = 0.0
    coulomb: float | np.ndarray = 0.0
    velocity_scale: float = 0.01

    def __post_init__(self) -> None:
        for name in ("viscous", "coulomb"):
            v = as_array(name, getattr(self, name))
            if v.ndim > 1 or v.size == 0 or np.any(v < 0):
                raise InvalidInput(f"{name}: expected a scalar or an (n,) vector, each >= 0, got {v.tolist()}")
            object.__setattr__(self, name, v)
        object.__setattr__(self, "velocity_scale", scalar("velocity_scale", self.velocity_scale, positive=True))

    def check(self, n: int) -> None:
        """Raise InvalidInput unless the parameters fit a device with n joints."""
        for name in ("viscous", "coulomb"):
            v = getattr(self, name)
            if v.ndim == 1 and v.shape != (n,):
                raise InvalidInput(f"{name}: expected a scalar or ({n},) values for this device, got shape {v.shape}")

    def torque(self, dq: np.ndarray) -> np.ndarray:
        """F_q(q̇): (n,) [N m] for dq: (n,) [rad/s]."""
        return self.viscous * dq + self.coulomb * np.tanh(dq / self.velocity_scale)


def task_compensation(
    kin: DeviceTerms, *, coriolis: bool = True, gravity: bool = True, friction: JointFriction | None = None
) -> np.ndarray | None:
    """Model-based compensation C_x ẋ + G_x + F_x of the end-effector dynamics (thesis eqs. 5.2, 5.4, 7.2).

    C_x = M_x (J M_q⁻¹ C_q − J̇) J#, G_x = J#ᵀ G_q and F_x = J#ᵀ F_q(q̇) (eq. 5.2).

    Args:
        kin: the device terms at (q, q̇).
        coriolis: include C_x ẋ.
        gravity: include G_x.
        friction: joint friction model for F_x, or None.

    Returns:
        (m,) force [N], or None when every term is off.
    """
    out = None
    if coriolis:
        out = kin.Cx.dot(kin.xdot)
    if gravity and kin.g.dot(kin.g) != 0.0:
        out = kin.Gx if out is None else out + kin.Gx
    if friction is not None:
        f = kin.Jsharp.T.dot(friction.torque(kin.dq))  # type: ignore[arg-type]  # a controller's tick has q̇
        out = f if out is None else out + f
    return out


def _minus_damping(B: np.ndarray, xdot: np.ndarray) -> np.ndarray:
    return -(B.dot(xdot) if B.ndim else B * xdot)


class _Compensated:
    """Behaviour shared by the laws with damping B^d and the compensation terms of eqs. 5.4 / 7.2.

    A mixin of the frozen dataclasses below, which declare these fields (``damping`` is stored as an
    array by their ``__post_init__``).
    """

    damping: float | np.ndarray
    coriolis: bool
    gravity: bool
    friction: JointFriction | None

    def _extra(self, kin: DeviceTerms) -> np.ndarray:
        """−B^d ẋ + C_x ẋ + G_x + F_x: (m,) [N]."""
        c = task_compensation(kin, coriolis=self.coriolis, gravity=self.gravity, friction=self.friction)
        B, xdot = self.damping, kin.xdot
        Bx = B.dot(xdot) if B.ndim else B * xdot  # type: ignore[union-attr]  # an array after __post_init__
        return -Bx if c is None else c - Bx

    def _check_common(self, device: Device) -> None:
        _check_task_matrix("damping", self.damping, device.m)  # type: ignore[arg-type]  # an array after __post_init__
        if self.friction is not None:
            self.friction.check(device.n)

    def _compiled(self, device: Device, kind, **kw) -> CompiledLaw:
        """This law's `CompiledLaw` of `kind` with the shared damping and compensation settings."""
        B = np.asarray(self.damping, dtype=float)
        f, n = self.friction, device.n
        return CompiledLaw(kind, B * np.eye(device.m) if B.ndim == 0 else B, coriolis=bool(self.coriolis),
                           gravity=bool(self.gravity),
                           viscous=None if f is None else np.broadcast_to(np.asarray(f.viscous, dtype=float), (n,)),
                           coulomb=None if f is None else np.broadcast_to(np.asarray(f.coulomb, dtype=float), (n,)),
                           velocity_scale=0.0 if f is None else float(f.velocity_scale), **kw)


@dataclasses.dataclass(frozen=True, eq=False)
class ImpedanceControl(_Compensated):
    """Impedance control with null stiffness: the master renders M_x^d ẍ + B^d ẋ = F_h (thesis eqs. 5.4–5.7).

    With ``inertia=None`` the desired inertia is the device's own apparent inertia
    (M_x^d = M_x, the thesis's choice) and eq. 5.4 reduces to eq. 5.6,
    ``F_m = −B^d ẋ + C_x ẋ + G_x + F_x``: free motion with damping, no force sensor needed.
    With a desired inertia M_x^d, eq. 5.4 reads the user's hand force F_h from the
    handle sensor: ``F_m = M_x (M_x^d)⁻¹ (F_h − B^d ẋ) − F_h + C_x ẋ + G_x + F_x``.
    The joint torque is τ_m = Jᵀ F_m (eq. 5.7). Nothing is rendered (F_render = 0).

    Attributes:
        damping: B^d, scalar or (m, m) PSD [N s/m].
        inertia: M_x^d, (m, m) SPD [kg], or None for M_x^d = M_x (eq. 5.6).
        coriolis: compensate C_x ẋ.
        gravity: compensate G_x.
        friction: joint friction model for F_x, or None (not compensated, thesis §7.5).
        sensor: name of the hand-force reading F_h (only with `inertia`): the handle's F/T
            sensor, (6,) force [N] and torque [N m] the hand applies, in world axes (`rhi.sim`'s
            "ft"), or an (m,) force on the task axes [N].
    """

    damping: float | np.ndarray = 0.0
    inertia: np.ndarray | None = None
    coriolis: bool = True
    gravity: bool = True
    friction: JointFriction | None = None
    sensor: str = "ft"

    def __post_init__(self) -> None:
        object.__setattr__(self, "damping", _damping("damping", self.damping))
        if self.sensor not in ("ft", "force"):
            raise InvalidInput(f"sensor: expected 'ft' (6-axis wrench) or 'force' (task force), got {self.sensor!r}")
        if self.inertia is not None:
            Md = spd_matrix("inertia", self.inertia)
            object.__setattr__(self, "inertia", Md)
            object.__setattr__(self, "_inertia_inv", np.linalg.inv(Md))

    def check(self, device: Device) -> None:
        """Raise InvalidInput unless the parameters fit `device`."""
        self._check_common(device)
        if self.inertia is not None:
            _check_task_matrix("inertia", self.inertia, device.m)

    def required_sensors(self) -> tuple[str, ...]:
        """The hand's F/T sensor when inertia is shaped (eq. 5.4), none otherwise (eq. 5.6)."""
        return () if self.inertia is None else (self.sensor,)

    def compiled(self, device: Device) -> CompiledLaw | None:
        """The compiled form of free motion (eq. 5.6); None with a desired inertia (eq. 5.4 runs in Python)."""
        return self._compiled(device, "free") if self.inertia is None else None

    def hand_force(self, kin: DeviceTerms, sensors: Mapping[str, np.ndarray]) -> np.ndarray:
        """F_h: (m,) [N] from the sensor reading, a (6,) world-axes wrench [N, N m] or an (m,) task force."""
        v = np.asarray(sensors[self.sensor], dtype=float)
        m = kin.J.shape[0]
        if v.shape == (6,):
            return v[:3][kin.device.task_rows]
        if v.shape != (m,):
            raise InvalidInput(f"sensors[{self.sensor!r}]: expected a (6,) wrench or an ({m},) force, got shape {v.shape}")
        return v

    def forces(self, t, kin, sensors):
        """(F_render, F_extra) of eqs. 5.4–5.7 at time t [s], each (m,) [N]."""
        if self.inertia is None:
            return self._zeros(kin), self._extra(kin)  # eq. 5.6
        # eq. 5.4: M_x (M_x^d)⁻¹ (F_h − B^d ẋ) − F_h + C_x ẋ + G_x + F_x
        Fh = self.hand_force(kin, sensors)
        # _inertia_inv and the damping array are set by __post_init__
        F = kin.Lambda.dot(self._inertia_inv.dot(Fh + _minus_damping(self.damping, kin.xdot))) - Fh  # type: ignore[attr-defined,arg-type]
        c = task_compensation(kin, coriolis=self.coriolis, gravity=self.gravity, friction=self.friction)
        return self._zeros(kin), (F if c is None else F + c)

    @staticmethod
    def _zeros(kin: DeviceTerms) -> np.ndarray:
        return np.zeros(kin.J.shape[0])


@dataclasses.dataclass(frozen=True, eq=False)
class ForceRendering(_Compensated):
    """Render a measured/virtual environment force (thesis eq. 7.2): F_m = −F_e − B^d ẋ + C_x ẋ + G_x + F_x.

    ``sensors["force"]`` is −F_e, the force the device should apply to the user's hand
    [N] (eq. 7.2's F_e is the wrench the environment applies). With the compensation
    terms on, the device's end-effector dynamics become M_x ẍ + B^d ẋ = F_h − F_e
    (eq. 7.3). Only the rendered force is scaled by ASCM's α (eq. 7.9).

    Attributes:
        damping: B^d, scalar or (m, m) PSD [N s/m] (thesis §7.5: 0.01).
        gain: scale of the rendered force.
        coriolis: compensate C_x ẋ.
        gravity: compensate G_x.
        friction: joint friction model for F_x, or None (not compensated, thesis §7.5).
        passivity: time-domain passivity observer/controller (`rhi.control.passivity`), or None (off).
    """

    damping: float | np.ndarray = 0.0
    gain: float = 1.0
    coriolis: bool = True
    gravity: bool = True
    friction: JointFriction | None = None
    passivity: Passivity | None = dataclasses.field(default_factory=Passivity)

    def __post_init__(self) -> None:
        object.__setattr__(self, "damping", _damping("damping", self.damping))
        object.__setattr__(self, "gain", scalar("gain", self.gain))
        _check_passivity(self.passivity)

    def check(self, device: Device) -> None:
        """Raise InvalidInput unless the parameters fit `device`."""
        self._check_common(device)

    def required_sensors(self) -> tuple[str, ...]:
        """The force to render, ``sensors["force"]`` (m,) [N]."""
        return ("force",)

    def compiled(self, device: Device) -> CompiledLaw:
        """The compiled form of eq. 7.2."""
        return self._compiled(device, "force", gain=float(self.gain))

    def forces(self, t, kin, sensors):
        """(gain · sensors["force"], compensation C_x ẋ + G_x + F_x − B^d ẋ) of eq. 7.2, each (m,) [N]."""
        F = np.asarray(sensors["force"], dtype=float)
        if F.shape != kin.x.shape:
            raise InvalidInput(f"sensors['force']: expected shape {kin.x.shape}, got {F.shape}")
        return (F if self.gain == 1.0 else self.gain * F), self._extra(kin)


@dataclasses.dataclass(frozen=True, eq=False)
class SpringPalpation(_Compensated):
    """A virtual spring wall: F_m = K_e δX − B^d ẋ + C_x ẋ + G_x (+ F_x), δX = X₀ − x (thesis eqs. 6.21, 7.20).

    The spring pushes the hand back towards the start point X₀ once it has moved along
    ``normal`` (the contact direction); with ``normal=None`` it acts in every direction.
    The spring force is the rendered (α-scaled) part. Eq. 6.21 is the spring alone
    (``damping=0, coriolis=False, gravity=False``); eq. 7.20 adds −B^d ẋ + C_x ẋ.

    Attributes:
        stiffness: K_e [N/m] (thesis: 1000).
        x0: (m,) start point X₀ [m].
        normal: (m,) direction into the environment, or None.
        damping: B^d scalar or (m, m) [N s/m].
        coriolis, gravity, friction: compensation terms as in `ForceRendering`.
        passivity: time-domain passivity observer/controller (`rhi.control.passivity`), or None (off).
    """

    stiffness: float
    x0: tuple[float, ...]
    normal: tuple[float, ...] | None = None
    damping: float | np.ndarray = 0.0
    coriolis: bool = True
    gravity: bool = True
    friction: JointFriction | None = None
    passivity: Passivity | None = dataclasses.field(default_factory=Passivity)

    def __post_init__(self) -> None:
        object.__setattr__(self, "stiffness", scalar("stiffness", self.stiffness, nonnegative=True))
        object.__setattr__(self, "x0", as_array("x0", self.x0, ndim_min=1))
        if self.normal is not None:
            nrm = as_array("normal", self.normal, ndim_min=1)
            if nrm.shape != self.x0.shape:  # type: ignore[attr-defined]  # x0: an array from here on
                raise InvalidInput(f"normal: expected shape {self.x0.shape} like x0, got {nrm.shape}")  # type: ignore[attr-defined]
            if np.linalg.norm(nrm) < 1e-12:
                raise InvalidInput("normal: zero-length direction vector")
            object.__setattr__(self, "normal", nrm / np.linalg.norm(nrm))
        object.__setattr__(self, "damping", _damping("damping", self.damping))
        _check_passivity(self.passivity)

    def check(self, device: Device) -> None:
        """Raise InvalidInput unless the parameters fit `device`."""
        if self.x0.shape != (device.m,):  # type: ignore[attr-defined]  # x0: an array after __post_init__
            raise InvalidInput(f"x0: expected shape ({device.m},) for this device, got {self.x0.shape}")  # type: ignore[attr-defined]
        self._check_common(device)

    def required_sensors(self) -> tuple[str, ...]:
        """None: the spring is a function of the position alone."""
        return ()

    def compiled(self, device: Device) -> CompiledLaw:
        """The compiled form of eqs. 6.21 / 7.20."""
        return self._compiled(device, "spring", stiffness=float(self.stiffness), x0=np.asarray(self.x0, dtype=float),
                              normal=None if self.normal is None else np.asarray(self.normal, dtype=float))

    def spring(self, x: np.ndarray) -> np.ndarray:
        """K_e δX: (m,) [N] at the end-effector position x: (m,) [m]."""
        dx = x - self.x0
        if self.normal is None:
            return -self.stiffness * dx
        depth = float(self.normal.dot(dx))  # type: ignore[attr-defined]  # normal: an array after __post_init__
        return -self.stiffness * max(depth, 0.0) * self.normal  # type: ignore[operator]

    def forces(self, t, kin, sensors):
        """(K_e δX, compensation terms) of eqs. 6.21 / 7.20, each (m,) [N]."""
        return self.spring(kin.x), self._extra(kin)
