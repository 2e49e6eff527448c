"""The null-space haptic controller: primary law + prioritised null-space objectives + saturation handling.

One tick (`NullSpaceController.step`) computes, from the joint sensors and the sensor dict:

1. the device terms at (q, q̇) (`Device.terms`: x, J, ∂J/∂q, M, g and, on demand, the
   task-space dynamics M_x, J#, C_x, G_x of eq. 5.2);
2. the primary task-space force (F_render, F_extra) and τ_m = Jᵀ(F_render + F_extra)
   (eqs. 5.4–5.7, 6.5, 7.2–7.4), plus the null-space part (I − JᵀJ#ᵀ) g of the gravity
   torque (the task-space part G_x is the primary law's);
3. the actuator saturation observer V of τ_m (eq. 6.14) and, with a scheduled objective
   (`rhi.control.schedule`, e.g. `FMESchedule`), its transition Ω (eqs. 6.15–6.19) and the objective
   it gives for Ω (M_des = Ω M_Free + (1 − Ω) M_Stiff for FME matching, eqs. 6.10, 6.16);
4. the allocation of τ_m within the torque box by the configured strategy (`rhi.control.allocation`:
   none / simple scaling / ASCM (Algorithm 1) / LP optimum / active set), with force scaling α (eq. 7.9);
5. the safety torque τ_s = −k_D q̇ − Σ w ∂ν_lim/∂q (null-space damping and every
   `JointLimitBarrier` term) acts whatever the allocation holds or clips (a strategy that is not
   ``safe``, simple scaling, keeps
   Algorithm 2 as it is, the balance chapter 6's FME term and barrier rely on): the part of
   N τ_s that the joints held at a limit would block (all of it when they leave no redundancy, where
   Algorithm 2 gives β = 0) is added in full, and when it does not fit in the box the
   allocated torque α a + Z y (not b) is scaled by the largest γ <= 1 that makes room
   (α ← γ α; `safety_room`);
6. the objective torque τ_to = −Σ β_i ∂ν_i/∂q − τ_s (eqs. 3.20–3.21, 5.9–5.10, 6.6, 7.17),
   projected into the null space of the task and of the held joints and scaled by the β
   of Algorithm 2 (eq. 7.16). The safety torque's share within the held joints' null space
   is scaled with the objectives so their balance (the static optimum of ν + ν_lim) holds;
   the share β = 0 would switch off is not.

Torques never leave the torque box. Non-finite readings stop the controller (zero
torque, latched) and record why in the state; on the very first tick after
construction or `reset` they are bad input instead and raise InvalidInput.

Two implementations compute the same tick: ``implementation="fast"`` (the default: for a
device whose chain the compiled kinematics handle, a built-in primary law and the objectives
the kernel knows, the whole tick, passivity layer included, in one compiled call,
`rhi.control._compiled.whole`; otherwise `Device.terms`, the law's `forces`, then steps 2–6 in
one compiled kernel; `rhi.control.tick` and `rhi.control._compiled`) and ``"reference"`` (`rhi.control.reference`:
per-call Device methods, `null_basis` SVD, `ascm`/`tertiary` on the orthonormal basis,
`rhi.metrics` projectors) — the readable composition of the equations, kept as the oracle
the kernel is tested against. A strategy without a compiled branch (``kernel=None``, e.g. one registered
without one) runs every tick in the reference.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from rhi._validate import as_array, scalar
from rhi.control.allocation import Allocation, allocation_method
from rhi.control.compiled import Route, warn_route
from rhi.control.objectives import Objective
from rhi.control.passivity import PassivityController, PassivityState
from rhi.control.reference import reference_terms, reference_tick
from rhi.control.saturation import check_torque_limits
from rhi.control.schedule import ScheduledObjective, scheduled_term
from rhi.control.settings import ControllerConfig, ControllerState
from rhi.control.tank import NullSpaceTank, TankState
from rhi.control.tick import Fallback, KernelTick, compiled_form
from rhi.devices.model import Device
from rhi.errors import InvalidInput, RhiError, Singular
from rhi.metrics import dynamic_pinv, weighted_pinv


def _reading(name: str, v) -> np.ndarray:
    """A sensor reading as a float array (NaN allowed: a running loop stops safely on it)."""
    if v is None or isinstance(v, (str, bytes)) or np.iscomplexobj(v):
        raise InvalidInput(f"{name}: expected a real vector, got {v!r:.60}")
    try:
        return np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput(f"{name}: expected a real vector, got {v!r:.60}") from None


def _finite(v: np.ndarray) -> bool:
    """Whether every entry of the float vector v is finite (one sum over Python floats; exact check on overflow)."""
    return math.isfinite(sum(v.tolist())) or bool(np.isfinite(v).all())


DEVICE_SENSOR_WIDTHS = {"ft": 6}
"""Widths of the device sensors a primary law may read (docs/protocol.md, INFO)."""


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
        allocation = allocation_method(config.saturation)
        if config.projector not in ("dynamic", "pseudoinverse"):
            raise InvalidInput(f"projector: expected 'dynamic' or 'pseudoinverse', got {config.projector!r}")
        if config.null_space not in ("scaled", "clipped"):
            raise InvalidInput(f"null_space: expected 'scaled' or 'clipped', got {config.null_space!r}")
        if config.implementation not in ("fast", "reference"):
            raise InvalidInput(f"implementation: expected 'fast' or 'reference', got {config.implementation!r}")
        scalar("damping", config.damping, nonnegative=True)
        if config.tank is not None and not isinstance(config.tank, NullSpaceTank):
            raise InvalidInput(f"tank: expected a rhi.control.NullSpaceTank or None, got {config.tank!r:.60}")
        if config.tank is not None and (config.null_space != "scaled" or config.projector != "dynamic"):
            raise InvalidInput("tank: the null-space energy tank needs null_space='scaled' (Algorithm 2) and "
                               "projector='dynamic' (its null-space torques put no force at the handle)")
        scalar("aso_shape", config.aso_shape, positive=True)
        primary = config.primary
        if not all(callable(getattr(primary, name, None)) for name in ("forces", "required_sensors", "check")):
            raise InvalidInput(f"primary: expected a primary law (forces, required_sensors, check: ForceRendering, "
                               f"ImpedanceControl, ...), got {primary!r:.80}")
        lo = device.torque_min if config.torque_min is None else config.torque_min
        hi = device.torque_max if config.torque_max is None else config.torque_max
        self.lo, self.hi = check_torque_limits(torque_min=lo, torque_max=hi, n=device.n)
        term = scheduled_term(config.objectives)
        for t in config.objectives:
            check = getattr(t.objective, "check", None)
            if callable(check):
                check(device)
        primary.check(device)
        self.device = device
        self.config = config
        #: The allocation strategy ``config.saturation`` names.
        self.allocation = allocation
        self.state = state or ControllerState()
        self._fresh_tank()
        #: (gain, scheduled objective) of the objective the ASO schedules (`rhi.control.schedule`), or None.
        self.schedule: tuple[float, ScheduledObjective] | None = (
            None if term is None else (float(term.gain), term.objective))  # type: ignore[assignment]
        #: S of eq. 6.14 for the ASO.
        self.aso_shape = config.aso_shape if term is None else float(getattr(term.objective, "aso_shape",
                                                                             config.aso_shape))
        #: (gain, objective) of the tertiary objectives and of the joint-limit barriers (part of the safety torque).
        self.objectives: list[tuple[float, Objective]] = []
        self.barriers: list[tuple[float, Objective]] = []
        for t in config.objectives:
            if t.gain > 0 and t is not term:
                (self.barriers if getattr(t.objective, "safety", False) else self.objectives).append(
                    (float(t.gain), t.objective))
        self._sensors = tuple(config.primary.required_sensors())
        pas = getattr(config.primary, "passivity", None)
        self._pc = None if pas is None else PassivityController(pas, reference=config.implementation == "reference")
        self._n = device.n
        self._kernel = (None if config.implementation == "reference" or allocation.kernel is None
                        or self._uncompiled_schedule() else KernelTick(self))
        #: A dict to fill with each reference tick's torque by source (`rhi.control.reference.reference_tick`'s
        #: parts: every tick with ``implementation="reference"``, a fast controller's fallback ticks), or None.
        self.sources: dict[str, np.ndarray] | None = None
        if config.implementation == "fast":
            warn_route(self.route)

    @property
    def route(self) -> Route:
        """Which implementation runs this controller's tick, and why not the whole compiled tick (`rhi.control.compiled`)."""
        cfg, kt = self.config, self._kernel
        if kt is not None:
            return Route("whole") if kt.whole_ok else Route("composed", kt.reason or "the whole tick is switched off")
        if cfg.implementation == "reference":
            return Route("reference", "implementation='reference' asked for")
        if self.allocation.kernel is None:
            return Route("reference", f"the allocation {self.allocation.name!r} has no compiled branch")
        return Route("reference", f"the scheduled objective {self._uncompiled_schedule()} has no compiled form")

    def _uncompiled_schedule(self) -> str:
        """The name of the scheduled objective when it has no compiled form ("" without one or where it has)."""
        if self.schedule is None:
            return ""
        c = compiled_form(self.schedule[1], self.device)
        return "" if c is not None and c.kind == "fme_schedule" else type(self.schedule[1]).__name__

    @property
    def passivity(self) -> PassivityState | None:
        """State of the passivity observer/controller (`rhi.control.passivity`), None without one."""
        return None if self._pc is None else self._pc.state

    def required_sensors(self) -> dict[str, int | None]:
        """The device sensors the primary law reads, name → width (None: any); `rhi.runtime.run` checks them.

        "force" is not among them: the host renders it from the virtual environment.
        """
        return {name: DEVICE_SENSOR_WIDTHS.get(name) for name in self._sensors if name != "force"}

    def warmup(self) -> None:
        """Load the compiled kernels now (Numba's disk cache, or a compile), not at a real-time loop's first tick.

        Steps a fresh twin at rest, at the middle of the joint range (or seeded random
        configurations if that one is singular); this controller's state is untouched.
        `rhi.runtime.run` calls it before it opens the link.
        """
        dev, rng = self.device, np.random.default_rng(0)
        lo, hi = (np.where(np.isfinite(b), b, s * np.pi) for b, s in ((dev.q_min, -1.0), (dev.q_max, 1.0)))
        sensors = {name: np.zeros(dev.m) for name in self._sensors}
        for k in range(5):
            twin = NullSpaceController(dev, self.config)
            q = 0.5 * (lo + hi) if k == 0 else rng.uniform(lo, hi)
            try:
                twin.step(0.0, q, np.zeros(self._n), sensors)
                twin.step(1e-3, q, np.full(self._n, 1e-3), sensors)
            except (RhiError, np.linalg.LinAlgError):  # this configuration does not suit the law: try another
                continue
            if twin.state.ticks == 2:
                return

    def reset(self) -> None:
        """Fresh state (clears a safe stop, empties the passivity observer)."""
        self.state = ControllerState()
        self._fresh_tank()
        if self._pc is not None:
            self._pc.reset()

    def _fresh_tank(self) -> None:
        """Give the state a full-of-`initial` tank when the configuration has one and the state has none."""
        tank = self.config.tank
        if tank is not None and self.state.tank is None:
            self.state.tank = TankState(energy=float(tank.initial), allocation=float(tank.initial))

    def _stop(self, why: str) -> np.ndarray:
        s = self.state
        s.stopped, s.fault = True, why
        s.tau = np.zeros(self._n)
        return s.tau

    def _bad_reading(self, why: str) -> np.ndarray:
        """Bad input before the loop started (raise); a fault while running (safe stop)."""
        if self.state.ticks == 0:
            raise InvalidInput(why + " (first tick: check the sensor pipeline)")
        return self._stop(why)

    def step(self, t: float, q, dq, sensors: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """One control tick.

        Args:
            t: time [s].
            q: (n,) joint positions [rad].
            dq: (n,) joint velocities [rad/s].
            sensors: named readings the primary law needs (e.g. "force": (m,) [N], "ft": (6,) [N, N m]);
                others are ignored.

        Returns:
            τ: (n,) joint torques [N m], within [torque_min, torque_max]; zeros after a safe stop.

        Raises:
            InvalidInput: wrong shapes, a missing sensor, or non-finite readings on the first tick.
                (Non-finite readings later, and singular configurations, stop the controller instead.)
        """
        s = self.state
        n = self._n
        if s.stopped:
            return np.zeros(n)
        if not (type(t) is float or isinstance(t, (int, np.floating, np.integer))) or isinstance(t, bool):
            raise InvalidInput(f"t: expected a real time [s], got {t!r:.60}")
        if not (type(q) is np.ndarray and q.dtype == np.float64):
            q = _reading("q", q)
        if not (type(dq) is np.ndarray and dq.dtype == np.float64):
            dq = _reading("dq", dq)
        if q.shape != (n,) or dq.shape != (n,):
            raise InvalidInput(f"q/dq: expected shape ({n},), got {q.shape} and {dq.shape}")
        if not math.isfinite(sum(q.tolist()) + sum(dq.tolist())):  # one check for both (exactly on overflow)
            if not _finite(q):
                return self._bad_reading(f"q: non-finite joint position at t={t}: {q.tolist()}")
            if not _finite(dq):
                return self._bad_reading(f"dq: non-finite joint velocity at t={t}: {dq.tolist()}")
        if not math.isfinite(t):
            return self._bad_reading(f"t: non-finite time {t}")
        if self._sensors:
            if sensors is None:
                sensors = {}
            for name in self._sensors:
                if name not in sensors:
                    raise InvalidInput(f"sensors: missing {name!r} required by the primary law")
                v = sensors[name]
                if not (type(v) is np.ndarray and v.dtype == np.float64):
                    v = _reading(f"sensors[{name!r}]", v)
                if v.ndim != 1:
                    raise InvalidInput(f"sensors[{name!r}]: expected a vector, got shape {v.shape}")
                if not _finite(v):
                    return self._bad_reading(f"sensors[{name!r}]: non-finite reading at t={t}: {v.tolist()}")
        try:
            return self._tick(float(t), q, dq, sensors or {})
        except (np.linalg.LinAlgError, Singular) as exc:
            return self._stop(f"numerical failure at t={t} (singular configuration?): {exc}")

    def _tick(self, t: float, q: np.ndarray, dq: np.ndarray, sensors: Mapping[str, np.ndarray]) -> np.ndarray:
        s = self.state
        kernel = self._kernel
        pc = self._pc
        if kernel is None:
            kin = reference_terms(self, q, dq) if self.config.implementation == "reference" else self.device.terms(
                q, dq, check=False)
            tau, alpha, beta, sat, clipped = reference_tick(self, t, kin, sensors, parts=self.sources)
            tau = np.minimum(np.maximum(tau, self.lo), self.hi)
        else:
            if kernel.whole_ok:  # one compiled call, the passivity layer included
                out = kernel.whole(t, q, dq, sensors)
            else:
                kin = self.device.terms(q, dq, check=False)
                out = kernel(t, kin, sensors)
            if type(out) is Fallback:  # the kernel cannot decide this held set accurately: the basis form
                kin = out.kin
                tau, alpha, beta, sat, clipped = reference_tick(self, t, kin, sensors, (out.F_render, out.F_extra),
                                                               parts=self.sources)
                tau = np.minimum(np.maximum(tau, self.lo), self.hi)
            else:
                tau, alpha, beta, sat, clipped = out
                if kernel.whole_ok:
                    pc = None  # the whole tick ran the passivity layer
        if pc is not None and _finite(tau):  # time-domain passivity around the whole torque (rhi.control.passivity)
            tau = pc.apply(t, kin, tau, self.lo, self.hi)
            s.E_obs, s.alpha_pc = pc.state.energy, pc.state.alpha
        if not _finite(tau):  # e.g. a non-finite objective gradient at a singular configuration
            return self._stop(f"non-finite torque at t={t} (singular configuration?): {tau.tolist()}")
        return self._record(t, tau, alpha, beta, sat, clipped)

    def _record(self, t: float, tau: np.ndarray, alpha: float, beta: float, sat: np.ndarray, clipped: bool) -> np.ndarray:
        """The state after a tick at t [s] that commanded the finite τ (n,) [N m]; returns τ."""
        s = self.state
        s.t, s.alpha, s.beta, s.saturated, s.clipped, s.tau = t, alpha, beta, sat, clipped, tau
        s.ticks += 1
        return tau


class ZeroTorque:
    """The motors off: τ = 0 every tick, the device's own dynamics (`rhi.sim.simulate` runs it compiled).

    Args:
        n: number of motors.

    Raises:
        InvalidInput: n is not a positive integer.
    """

    def __init__(self, n: int) -> None:
        if type(n) is bool or not isinstance(n, int | np.integer) or n < 1:
            raise InvalidInput(f"n: expected a positive integer (the number of motors), got {n!r}")
        self.n = int(n)

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, sensors: dict) -> np.ndarray:
        """τ: (n,) zeros [N m]."""
        return np.zeros(self.n)


def output_force(J: np.ndarray, tau: np.ndarray, M: np.ndarray | None = None) -> np.ndarray:
    """Task-space force produced by joint torques, J#ᵀ τ (dynamic) or J⁺ᵀ τ (pseudoinverse) [N]: (m,).

    Raises:
        InvalidInput: a non-finite or misshapen J, τ or M (named).
    """
    J = as_array("J", J, shape_tail=(None, None))
    tau = as_array("tau", tau, shape_tail=(J.shape[-1],))
    return (weighted_pinv(J) if M is None else dynamic_pinv(J, M)).T @ tau


__all__ = [
    "Allocation",
    "ControllerConfig",
    "ControllerState",
    "NullSpaceController",
    "ZeroTorque",
    "output_force",
]
