"""Set-ups the thesis experiments share: hands, one simulated run, progress.

The chapters' own set-ups (their constants, controllers and start configurations) are the
``setup`` module of each chapter package (`rhi.experiments.ch3.nullspace` for ch. 3,
`rhi.experiments.ch5.setup`, `rhi.experiments.ch6.setup`); what every chapter builds the
same way is here.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TypeGuard, get_args

import numpy as np

from rhi.control.allocation import Saturation, ascm_projector, ramp_peak
from rhi.control.objectives import EllipsoidMatching, VMEMatching
from rhi.control.saturation import null_basis
from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.metrics import jbld, max_force, max_force_scaling
from rhi.metrics.force import ProjectorKind
from rhi.sim import Hand, HandPath, Log, Plant, simulate

#: A progress callback: progress(done, total), in ticks or items.
Progress = Callable[[int, int], None]


def vme_values(dev: Device, objective: VMEMatching | EllipsoidMatching, q: np.ndarray) -> np.ndarray:
    """ν = JBLD(M_des, H J Jᵀ Hᵀ) (thesis eqs. 3.22, 5.11) of a VME-matching objective at many configurations.

    The values of ``objective.value(dev, q_i)``, from one batched Jacobian.

    Args:
        dev: the device.
        objective: `VMEMatching` (H = I) or `EllipsoidMatching`.
        q: (N, n) configurations [rad].

    Returns:
        (N,) ν.

    Raises:
        InvalidInput: another objective.
    """
    J = dev.jacobian(q)
    if isinstance(objective, VMEMatching):
        desired = objective.desired()
    elif isinstance(objective, EllipsoidMatching):
        desired = objective.desired
        J = J if objective.H is None else objective.H @ J
    else:
        raise InvalidInput(f"objective: expected VMEMatching or EllipsoidMatching, got {type(objective).__name__}")
    return jbld(desired, J @ np.swapaxes(J, -1, -2))


def path_hand(points, speed: float, start: float, stiffness: float, damping: float,
              max_force: float | None = 60.0) -> Hand:
    """A hand following the polyline `points` (k, m) [m] at `speed` [m/s] after `start` [s].

    Args:
        points: (k, m) polyline of the `rhi.sim.HandPath` [m].
        speed: its speed [m/s].
        start: when it starts [s].
        stiffness: the grip stiffness [N/m].
        damping: the grip damping [N s/m].
        max_force: saturation of the hand's force [N] (None: none).
    """
    return Hand(HandPath(np.asarray(points, dtype=float), speed=speed, start=start), stiffness=stiffness,
                damping=damping, max_force=max_force)


def run(dev: Device, controller, hand, q_start: np.ndarray, duration: float, progress: Progress | None = None,
        offset: int = 0, total: int | None = None, **kw) -> Log:
    """Simulate `controller` on a fresh plant of `dev` reset at rest to q_start: (n,) [rad].

    Args:
        dev: the device (its plant is built here).
        controller: as `rhi.sim.simulate`.
        hand: as `rhi.sim.simulate`.
        duration: simulated time [s].
        q_start: (n,) start configuration [rad].
        progress: callback(done, total) in ticks, shifted by `offset` out of `total` (several runs in a row).
        offset: this run's first tick among all runs.
        total: the ticks of all runs (None: this run's).
        **kw: further `rhi.sim.simulate` arguments (virtual, physical, record, ...).
    """
    plant = Plant(dev)
    plant.reset(q_start)
    cb = None if progress is None else (lambda k, n: progress(offset + k, n if total is None else total))
    return simulate(plant, controller, duration=duration, hand=hand, progress=cb, **kw)


class ProgressChain:
    """Progress over several runs: run i reports (offset + done, total)."""

    def __init__(self, progress: Progress | None, total: int) -> None:
        self.progress, self.total, self.offset = progress, total, 0

    def run(self, n: int):
        """The callback of the next run of n ticks (None without a progress callback)."""
        off = self.offset
        self.offset += n
        if self.progress is None:
            return None
        return lambda k, _n: self.progress(off + k, self.total)


def ticks(duration: float, rate: float = 1000.0) -> int:
    """Control ticks in `duration` [s] at `rate` [Hz]."""
    return int(round(duration * rate))


def positive(name: str, v: float, *, allow_zero: bool = False) -> float:
    """V as a float; InvalidInput naming `name` unless finite and > 0 (>= 0 with allow_zero)."""
    v = float(v)
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise InvalidInput(f"{name}: must be finite and {'>=' if allow_zero else '>'} 0, got {v!r}")
    return v


def is_projector(value: object) -> TypeGuard[ProjectorKind]:
    """Whether `value` names a null-space projector: "dynamic" (J#) or "pseudoinverse" (J⁺)."""
    return value in get_args(ProjectorKind)


def is_saturation(value: object) -> TypeGuard[Saturation]:
    """Whether `value` names an allocation under the torque limits (`rhi.control.ControllerConfig.saturation`)."""
    return value in get_args(Saturation)


def projector_names(projectors: Iterable[object]) -> tuple[ProjectorKind, ...]:
    """The null-space projectors an experiment runs in turn, checked: distinct "dynamic"/"pseudoinverse" entries.

    Raises:
        InvalidInput: no entry, a repeated one or one that names no projector.
    """
    given = tuple(projectors)
    kinds = tuple(p for p in given if is_projector(p))
    if not kinds or len(kinds) != len(given) or len(set(kinds)) != len(kinds):
        raise InvalidInput(f"projectors: expected distinct 'dynamic'/'pseudoinverse' entries, got {given!r}")
    return kinds


def check_motion(**kw: float) -> None:
    """Raise InvalidInput naming the first hand-motion parameter that is not finite and >= 0 (> 0 for depth, speed)."""
    for name, v in kw.items():
        strict = name in ("depth", "speed")
        if not np.isfinite(v) or v < 0 or (strict and v == 0):
            raise InvalidInput(f"{name}: must be finite and {'> 0' if strict else '>= 0'}, got {v!r}")


def smooth(a: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average over `window` samples along axis 0 (edges: shorter windows)."""
    if window <= 1:
        return a
    k = np.ones(window) / window
    num = np.apply_along_axis(lambda v: np.convolve(v, k, mode="same"), 0, a)
    den = np.convolve(np.ones(len(a)), k, mode="same")
    return num / (den[:, None] if a.ndim > 1 else den)


def capabilities(J: np.ndarray, u: np.ndarray, *, torque_min: np.ndarray, torque_max: np.ndarray,
                 projector: ProjectorKind = "dynamic", M: np.ndarray | None = None,
                 samples: int = 41) -> tuple[float, float, float]:
    """F_max along u by simple scaling, ASCM (Algorithm 1) and the LP optimum [N].

    The numbers of `rhi.control.allocation.force_capability` with method "scaling", "ascm" and "lp",
    computed together for the sweeps of chapter 7 and beyond: the LP once, and ASCM's ramp of requests
    (simple-scaling capability to 1.5× the LP optimum, then the optimum itself) through the compiled
    projector form `rhi.control.allocation.ascm_projector` (the same allocation as the reference).

    Args:
        J: (m, n) Jacobian [m/rad].
        u: (m,) direction (normalised here).
        torque_min: (n,) lower torque limits [N m].
        torque_max: (n,) upper torque limits [N m].
        projector: "dynamic" (J#, needs M) or "pseudoinverse" (J⁺, no M).
        M: (n, n) inertia [kg m²] for the dynamic projector.
        samples: requests in ASCM's ramp.
    """
    J = np.asarray(J, dtype=float)
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    lo, hi = torque_min, torque_max
    f_s = float(max_force_scaling(J, u, torque_min=lo, torque_max=hi))
    f_lp = float(max_force(J, u, torque_min=lo, torque_max=hi, projector=projector, M=M))
    Z = null_basis(J, M if projector == "dynamic" else None)
    P, t = Z @ Z.T, J.T @ u
    b = np.zeros_like(t)
    return f_s, ramp_peak(lambda f: ascm_projector(f * t, b, P, torque_min=lo, torque_max=hi, rank=Z.shape[1]).alpha,
                          f_s, f_lp, samples), f_lp
