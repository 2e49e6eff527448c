"""The null-space haptic controller: primary law + prioritised null-space objectives + saturation handling.

One tick (`NullSpaceController.step`) computes, from the joint sensors and the sensor dict:

1. the device terms at (q, q̇) (`Device.terms`: x, J, ∂J/∂q, M, g and, on demand, the
   task-space dynamics M_x, J#, C_x, G_x of eq. 5.2);
2. the primary task-space force (F_render, F_extra) and τ_m = Jᵀ(F_render + F_extra)
   (eqs. 5.4–5.7, 6.5, 7.2–7.4), plus the null-space part (I − JᵀJ#ᵀ) g of the gravity
   torque (the task-space part G_x is the primary law's);
3. the actuator saturation observer V of τ_m (eq. 6.14) and, when a desired-FME schedule
   is configured, the hysteresis and cosine transition Ω (eqs. 6.15–6.19) giving
   M_des = Ω M_Free + (1 − Ω) M_Stiff for the FME-matching objective (eq. 6.10);
4. the allocation of τ_m within the torque box: none / simple scaling / ASCM (Algorithm 1) /
   LP optimum, with force scaling α (eq. 7.9);
5. the safety torque τ_s = −k_D q̇ − Σ w ∂ν_lim/∂q (null-space damping and every
   `JointLimitBarrier` term) acts whatever the allocation holds or clips (simple scaling keeps
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

Two implementations compute the same tick: ``implementation="fast"`` (the default: one
Pinocchio pass, projector-form ASCM, no SVD, no per-call validation) and
``"reference"`` (per-call Device methods, `null_basis` SVD, `ascm`/`tertiary` on the
orthonormal basis, `rhi.metrics` projectors) — the readable composition of the
equations, kept as the oracle the fast path is tested against.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Literal

import numpy as np

from rhi._validate import scalar
from rhi.control.active_set import allocate_active_set
from rhi.control.objectives import FMEMatching, JointLimitBarrier, Objective, _spd, gradient_function
from rhi.control.passivity import PassivityController, PassivityState
from rhi.control.primary import PrimaryLaw
from rhi.control.saturation import (
    Allocation,
    TransitionConfig,
    TransitionState,
    allocate_lp,
    allocate_none,
    allocate_scaling,
    _as_list,
    _ascm_fast,
    _aso_volume,
    _null_projector_rows,
    _tertiary_fast,
    ascm,
    check_torque_limits,
    null_basis,
    null_projector,
    tertiary,
    transition_step,
)
from rhi.control.safety import _held_part_fast, held_part, safety_room
from rhi.device import Device, DeviceTerms
from rhi.errors import InvalidInput, Singular
from rhi.metrics import dynamic_pinv, nullspace_projector, weighted_pinv

#: Allocations that hold joints at a limit with null-space torque.
_HOLDING = ("ascm", "lp", "active_set")
#: Allocations after which the safety torque acts whatever the held (or clipped) joints: all but simple
#: scaling, which keeps chapter 6's Algorithm 2 (its FME term and limit barrier balance each other there).
_SAFE = _HOLDING + ("none",)

Saturation = Literal["none", "scaling", "ascm", "lp", "active_set"]


def _reading(name: str, v) -> np.ndarray:
    """A sensor reading as a float array (NaN allowed: a running loop stops safely on it)."""
    if v is None or isinstance(v, (str, bytes)) or np.iscomplexobj(v):
        raise InvalidInput(f"{name}: expected a real vector, got {v!r:.60}")
    try:
        return np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInput(f"{name}: expected a real vector, got {v!r:.60}") from None


def _finite(v: np.ndarray) -> bool:
    """Whether every entry of the float array v is finite (one dot product; exact check on overflow)."""
    return math.isfinite(v.dot(v)) or bool(np.isfinite(v).all())


@dataclasses.dataclass(frozen=True)
class ObjectiveTerm:
    """A null-space objective with its gradient step size (β of eq. 6.6, Λ of eq. 7.17)."""

    objective: Objective
    gain: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "gain", scalar("gain", self.gain, nonnegative=True))


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
        object.__setattr__(self, "gain", scalar("gain", self.gain, nonnegative=True))
        object.__setattr__(self, "free", free)
        object.__setattr__(self, "stiff", stiff)
        object.__setattr__(self, "_distance", float(np.linalg.norm(free - stiff)))

    @property
    def distance(self) -> float:
        """‖M_Free − M_Stiff‖_F (eq. 6.19)."""
        return self._distance

    def desired(self, omega: float) -> np.ndarray:
        """Ω M_Free + (1 − Ω) M_Stiff (eq. 6.16)."""
        if omega == 1.0:
            return self.free
        if omega == 0.0:
            return self.stiff
        return omega * self.free + (1.0 - omega) * self.stiff


@dataclasses.dataclass(frozen=True)
class ControllerConfig:
    """Everything the controller needs besides the device.

    Attributes:
        primary: the task-space law (e.g. `ImpedanceControl`, `ForceRendering`, `SpringPalpation`).
        objectives: null-space objectives with step sizes (τ_to = −Σ gain ∂ν/∂q).
        fme: optional ASO-switched FME matching (adds FMEMatching(M_des(t)) to the objectives).
        damping: null-space joint damping k_D [N m s/rad] (eqs. 3.20, 6.6).
        saturation: "none" | "scaling" | "ascm" | "lp" | "active_set" (the LP optimum by an active-set
            method warm-started at ASCM, `rhi.control.active_set`; "lp" solves the same LP with HiGHS).
        projector: "dynamic" (J# = M⁻¹Jᵀ(JM⁻¹Jᵀ)⁻¹) or "pseudoinverse" (J⁺).
        torque_min, torque_max: (n,) limits [N m]; None: the device's.
        gravity_compensation: add the null-space part (I − JᵀJ#ᵀ) g(q) of the gravity torque;
            with a primary law that compensates G_x (eqs. 5.4, 7.2) the whole g(q) is compensated.
        aso_shape: S of eq. 6.14 when no FME schedule is given.
        implementation: "fast" (default) or "reference" (the slow oracle; same torques).
    """

    primary: PrimaryLaw
    objectives: Sequence[ObjectiveTerm] = ()
    fme: FMESchedule | None = None
    damping: float = 0.1
    saturation: Saturation = "ascm"
    projector: Literal["dynamic", "pseudoinverse"] = "dynamic"
    torque_min: np.ndarray | None = None
    torque_max: np.ndarray | None = None
    gravity_compensation: bool = True
    aso_shape: float = 50.0
    implementation: Literal["fast", "reference"] = "fast"


@dataclasses.dataclass
class ControllerState:
    """Explicit controller state, updated by every tick (inspect it; replace it to reset).

    Attributes:
        t: time of the last tick [s].
        transition: FME transition state.
        omega: activation Ω of the desired FME (1: free, 0: stiff).
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
        if config.saturation not in ("none", "scaling", "ascm", "lp", "active_set"):
            raise InvalidInput(
                f"saturation: expected 'none', 'scaling', 'ascm', 'lp' or 'active_set', got {config.saturation!r}")
        if config.projector not in ("dynamic", "pseudoinverse"):
            raise InvalidInput(f"projector: expected 'dynamic' or 'pseudoinverse', got {config.projector!r}")
        if config.implementation not in ("fast", "reference"):
            raise InvalidInput(f"implementation: expected 'fast' or 'reference', got {config.implementation!r}")
        scalar("damping", config.damping, nonnegative=True)
        scalar("aso_shape", config.aso_shape, positive=True)
        if not (callable(getattr(config.primary, "forces", None)) and callable(getattr(config.primary, "required_sensors", None))):
            raise InvalidInput(f"primary: expected a primary law (ForceRendering, ImpedanceControl, ...), got {config.primary!r:.80}")
        lo = device.torque_min if config.torque_min is None else config.torque_min
        hi = device.torque_max if config.torque_max is None else config.torque_max
        self.lo, self.hi = check_torque_limits(lo, hi, device.n)
        if config.fme is not None and config.fme.free.shape != (device.m, device.m):
            raise InvalidInput(f"fme: desired FMEs must be ({device.m}, {device.m}), got {config.fme.free.shape}")
        check = getattr(config.primary, "check", None)
        if callable(check):
            check(device)
        self.device = device
        self.config = config
        self._fme = None if config.fme is None else FMEMatching(config.fme.free, self.hi)
        self.state = state or ControllerState()
        self._sensors = tuple(config.primary.required_sensors())
        pas = getattr(config.primary, "passivity", None)
        self._pc = None if pas is None else PassivityController(pas)
        self._n, self._m = device.n, device.m
        self._lo_l, self._hi_l = self.lo.tolist(), self.hi.tolist()
        self._aso_S = config.fme.transition.S if config.fme is not None else config.aso_shape
        self._fast = config.implementation == "fast"
        self._dynamic = config.projector == "dynamic"
        self._grads, self._safe_grads = [], []  # tertiary objectives; joint-limit barriers (safety)
        for term in config.objectives:
            if term.gain > 0:
                obj = term.objective
                fn = gradient_function(obj, device) if self._fast else (
                    lambda kin, obj=obj: np.asarray(obj.gradient(device, kin.q), dtype=float)
                )
                (self._safe_grads if isinstance(obj, JointLimitBarrier) else self._grads).append((float(term.gain), fn))

    @property
    def passivity(self) -> PassivityState | None:
        """State of the passivity observer/controller (`rhi.control.passivity`), None without one."""
        return None if self._pc is None else self._pc.state

    def reset(self) -> None:
        """Fresh state (clears a safe stop, empties the passivity observer)."""
        self.state = ControllerState()
        if self._pc is not None:
            self._pc.reset()

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
            return self._tick(t, q, dq, sensors or {})
        except (np.linalg.LinAlgError, Singular) as exc:
            return self._stop(f"numerical failure at t={t} (singular configuration?): {exc}")

    def terms(self, q: np.ndarray, dq: np.ndarray) -> DeviceTerms:
        """The device terms the tick uses: one Pinocchio pass (fast) or per-call Device methods (reference)."""
        dev = self.device
        if self._fast:
            return dev.terms(q, dq, check=False)
        return DeviceTerms(
            dev, q, dq,
            x=dev.fk(q), J=dev.jacobian(q), dJ=dev.jacobian_derivative(q), M=dev.mass_matrix(q), g=dev.gravity(q),
        )

    def _tick(self, t: float, q: np.ndarray, dq: np.ndarray, sensors: Mapping[str, np.ndarray]) -> np.ndarray:
        s, cfg = self.state, self.config
        lo, hi = self.lo, self.hi
        kin = self.terms(q, dq)
        F_r, F_x = cfg.primary.forces(t, kin, sensors)
        Jt = kin.J.T
        a = Jt.dot(F_r)
        b = Jt.dot(F_x)
        g = kin.g
        if cfg.gravity_compensation and g.dot(g) != 0.0:
            b = b + (g - Jt.dot(kin.Gx))  # (I − JᵀJ#ᵀ) g: the part G_x leaves out
        tau_m = a + b

        # ASO and desired-FME transition
        s.V = _aso_volume(_as_list(tau_m), self._lo_l, self._hi_l, self._aso_S)
        fme = cfg.fme
        if fme is not None:
            s.transition, s.omega = transition_step(s.transition, t, s.V, fme.distance, fme.transition)

        # allocation within the torque box, the safety torque, then the null-space objectives (tertiary)
        tau_s = -cfg.damping * dq
        for gain, fn in self._safe_grads:
            tau_s = tau_s - gain * fn(kin)
        tau_to = tau_s
        if fme is not None and fme.gain > 0:
            tau_to = tau_to - fme.gain * self._fme.gradient_from(kin.J, kin.dJ, fme.desired(s.omega))
        for gain, fn in self._grads:
            tau_to = tau_to - gain * fn(kin)
        if self._fast:
            al, alpha, delta, beta = self._allocate_fast(a, b, tau_m, s.V, tau_s, tau_to, kin)
        else:
            al, alpha, delta, beta = self._allocate_reference(a, b, tau_s, tau_to, kin)
        tau = np.minimum(np.maximum(al.tau + delta if beta else al.tau, lo), hi)
        pc = self._pc
        if pc is not None and _finite(tau):  # time-domain passivity around the whole torque (rhi.control.passivity)
            tau = pc.apply(t, kin, tau, lo, hi)
            s.E_obs, s.alpha_pc = pc.state.energy, pc.state.alpha
        if not _finite(tau):  # e.g. a non-finite objective gradient at a singular configuration
            return self._stop(f"non-finite torque at t={t} (singular configuration?): {tau.tolist()}")

        s.t, s.alpha, s.beta, s.saturated, s.clipped, s.tau = t, alpha, beta, al.saturated, al.clipped, tau
        s.ticks += 1
        return tau

    def _allocate_reference(self, a, b, tau_s, tau_to, kin: DeviceTerms):
        cfg, lo, hi = self.config, self.lo, self.hi
        M = kin.M if self._dynamic else None
        Z = null_basis(kin.J, M)
        if cfg.saturation == "ascm":
            al = ascm(a, b, Z, lo, hi)
        elif cfg.saturation == "lp":
            al = allocate_lp(a, b, Z, lo, hi)
        elif cfg.saturation == "active_set":
            al = allocate_active_set(a, b, Z, lo, hi)
        elif cfg.saturation == "scaling":
            al = allocate_scaling(a, b, lo, hi)
        else:
            al = allocate_none(a, b, lo, hi)
        N = nullspace_projector(kin.J, M)
        gamma = 1.0
        if al.saturated.any() and al.method in _SAFE:  # safety the held joints would block
            tau1, gamma = safety_room(al.tau, b, held_part(Z, al.saturated, N @ tau_s), lo, hi, skip=al.clipped)
            al = dataclasses.replace(al, tau=tau1)
        delta, beta = tertiary(al.tau, al.saturated, Z, tau_to, lo, hi, N)
        return al, gamma * al.alpha, delta, beta

    def _allocate_fast(self, a, b, tau_m, V, tau_s, tau_to, kin: DeviceTerms):
        cfg, lo, hi, n = self.config, self.lo, self.hi, self._n
        r = n - self._m
        P = Z = None
        if self._dynamic:
            Jt = kin.J.T
            Ntau = tau_to - Jt.dot(kin.Jsharp.T.dot(tau_to))  # (I − JᵀJ#ᵀ) τ_to
        else:
            P = null_projector(kin.J)  # = I − JᵀJ⁺ᵀ, the pseudoinverse N
            Ntau = P.dot(tau_to)
        sat = cfg.saturation
        if V > 0.0 and sat in _HOLDING:  # τ_m strictly inside the box: kept as it is (Algorithm 1, line 6)
            al = Allocation(tau_m, 1.0, np.zeros(n, bool), np.zeros(n), sat)
        elif sat == "ascm":
            if P is None:
                P = _null_projector_rows(kin.JMinv)
            al = _ascm_fast(a, b, P, self._lo_l, self._hi_l, r)
            if al is None:  # ill-conditioned held set: the basis form, as the reference
                Z = self._null_basis(kin)
                al = ascm(a, b, Z, lo, hi)
        elif sat == "lp":
            Z = self._null_basis(kin)
            al = allocate_lp(a, b, Z, lo, hi)
        elif sat == "active_set":
            if P is None:
                P = _null_projector_rows(kin.JMinv)
            Z = self._null_basis(kin)
            start = _ascm_fast(a, b, P, self._lo_l, self._hi_l, r)
            al = allocate_active_set(a, b, Z, lo, hi, start=start)
        elif sat == "scaling":
            al = allocate_scaling(a, b, lo, hi)
        else:
            al = allocate_none(a, b, lo, hi)
        gamma = 1.0
        if al.saturated.any() and al.method in _SAFE:  # safety the held joints would block
            Nsafe = tau_s - Jt.dot(kin.Jsharp.T.dot(tau_s)) if self._dynamic else P.dot(tau_s)
            if P is None:
                P = _null_projector_rows(kin.JMinv)
            held = _held_part_fast(P, al.saturated, Nsafe)
            if held is None:
                held = held_part(self._null_basis(kin) if Z is None else Z, al.saturated, Nsafe)
            tau1, gamma = safety_room(al.tau, b, held, lo, hi, skip=al.clipped)
            al = dataclasses.replace(al, tau=tau1)
        if P is None and al.saturated.any():
            P = _null_projector_rows(kin.JMinv)
        res = _tertiary_fast(al.tau, al.saturated, P, tau_to, Ntau, self._lo_l, self._hi_l, r)
        if res is None:
            N = kin.N if self._dynamic else null_projector(kin.J)
            res = tertiary(al.tau, al.saturated, self._null_basis(kin) if Z is None else Z, tau_to, lo, hi, N)
        return al, gamma * al.alpha, res[0], res[1]

    def _null_basis(self, kin: DeviceTerms) -> np.ndarray:
        return null_basis(kin.J, kin.M if self._dynamic else None)

    def last_allocation(self) -> tuple[float, float]:
        """(α, β) of the last tick."""
        return self.state.alpha, self.state.beta


def output_force(J: np.ndarray, tau: np.ndarray, M: np.ndarray | None = None) -> np.ndarray:
    """Task-space force produced by joint torques, J#ᵀ τ (dynamic) or J⁺ᵀ τ (pseudoinverse) [N]: (m,)."""
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
