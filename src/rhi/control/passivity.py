"""Time-domain passivity: an energy observer at the device port and a variable damping that keeps it passive.

Hannaford and Ryu (2002), "Time-domain passivity control of haptic interfaces", IEEE Trans.
Robot. Automat. 18(1):1–10 ("H&R" below). A one-port with effort f and flow v is passive
when the energy that has flowed into it never falls below minus its initial storage
(H&R eq. 1, ``∫₀ᵗ f v dτ + E(0) ≥ 0``). The *passivity observer* (PO) sums that energy
sample by sample, ``E_obs(n) = ΔT Σ_{k≤n} f(k) v(k)`` (H&R §II); the *passivity controller*
(PC) of an impedance-causality port (velocity in, force out: a rendered wall, spring or
fixture) is a damper in series, ``f(n) = f_e(n) + α(n) v(n)`` with
``α(n) = −E_obs(n) / (ΔT v(n)²)`` while ``E_obs(n) < 0`` and 0 otherwise (H&R §III, the
series PC), which dissipates in the coming sample exactly the energy the port has created.

What we observe, with which signs and which timing
--------------------------------------------------
Port. The rendered environment, the compensation terms, the allocation under saturation
(ASCM moves torque into the null space) and the null-space objectives all act on the hand
through the same motors, so the port observed by default is the *motor port*: effort the
commanded joint torque τ [N m], flow the encoder velocity q̇ [rad/s]. Its energy is the
work the motors do on the mechanism; with it the whole controller — rendering and
null-space side together — is kept passive, and the hand's work W = ∫F_hᵀẋ dt can only
fall below zero by the kinetic energy the device had at the start (energy balance of the
rigid mechanism: W + motor work = ΔT_kin + friction losses). ``port="handle"`` observes
instead the classical H&R virtual-environment port: the task force the torque produces
at the handle, ``F = J#ᵀτ`` (dynamically consistent, thesis eq. 7.5) [N], against the
handle velocity ẋ = J q̇ [m/s]; it misses energy that reaches the hand through the
self-motion (measured in `rhi.experiments.beyond.passivity`).

Sign. ``E_obs`` is the energy that has flowed *from the mechanism into the controller*:
``E_obs = −Σ (motor work)``. A passive controller has ``E_obs ≥ 0`` (a wall stores the
energy the hand pushed into it and gives back at most that); ``E_obs < 0`` is energy the
controller created and handed to the device and the hand.

Sample-and-hold. The torque computed at tick k is held constant until tick k + 1 (the
device's zero-order hold), so the energy exchanged over that interval is exactly
``τ(k)ᵀ (q(k+1) − q(k))`` — no velocity estimate and no rectangle rule. The observer
adds it when q(k+1) arrives (``E_obs(n) = −Σ_{k<n} τ(k)ᵀ (q(k+1) − q(k))``, H&R's PO with
the ZOH interval's exact work in place of ``f(k) v(k) ΔT``). At the handle port the
force ``J#ᵀτ`` is not exactly constant over the interval; ``F(k)ᵀ (x(k+1) − x(k))`` is
its work to first order in the step.

Controller. At tick n, before the torque τ₀(n) of the control law is sent, the energy the
coming interval would exchange is predicted with the current sample, as H&R's PO
includes f(n) v(n) (``E_pred = E_obs(n) − τ₀(n)ᵀ q̇(n) ΔT``); if it is negative the PC adds
the damping torque ``τ_pc = −α M q̇`` (motor port; ``Jᵀ(−α M_x ẋ)`` at the handle port)
with ``α = −E_pred / (ΔT q̇ᵀ M q̇)`` [1/s], which dissipates ``α ΔT q̇ᵀ M q̇ = −E_pred`` in the
interval. The damping is weighted by the inertia (M the joint-space inertia, M_x the
apparent inertia at the handle): it is H&R's α in every direction of motion at once, and
the sampled damper ``q̇ ← (1 − α ΔT) q̇`` stays stable and non-oscillating for every mode of
the mechanism as long as ``α ΔT < 1``; ``alpha_max`` bounds it (default ``0.5 / ΔT``). The
torque box still holds (the PC torque is clipped with the rest); whatever the clip or the
bound on α leaves undissipated stays in ``E_obs`` and is dissipated in the next intervals.

Methods (``Passivity.method``), named exactly:

- ``"damper"`` (default): H&R's series PC alone. The damper acts on the predicted deficit
  (E_obs(n) less the coming interval's work of the law's torque, step 2 of `apply`); the
  control law's torque — the rendered wall, the allocation, the objectives and the safety
  torques (null-space damping, joint-limit barrier) — is sent unchanged, with the damping
  added. What the bound on α or the torque box leaves is carried to the next samples.
- ``"bounding"``: energy bounding alone (no damper): the law's torque is scaled down so that the
  predicted work of the coming hold interval never exceeds E_obs(n) (step 4 of `apply`).
- ``"damper_bounding"``: the damper and, for what the damper and the box cannot take out,
  energy bounding. This is not H&R's series PC alone: most of its passivity comes from the
  scaling of the law's torque, the wall and the safety torques included (measured in
  `rhi.experiments.beyond.passivity`; the Z-width and the force each method keeps:
  `rhi.experiments.beyond.zwidth`).

Null-space objectives. At the motor port their torque is observed with the rest, with no
storage: the projected gradient −β N ∇ν with the tertiary scaling β of eq. 7.16 switching
as the allocation holds joints is not the gradient of any potential, and crediting Σ β_i ν_i
as storage let the §6.4 palpation hand the user tens of mJ (`rhi.experiments.beyond.passivity`).
So, with the PC on, a reconfiguration driven by the objectives runs on the energy the
hand has put in plus ``initial_energy`` (H&R's E(0)): the controller is passive as a whole.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np

from rhi.control._compiled import passivity as _kernel
from rhi.control.tank import hold_work, largest_scale
from rhi.devices.model import DeviceTerms
from rhi.errors import InvalidInput

#: The port the observer watches: the motors (τ against q̇) or the handle (J#ᵀτ against ẋ).
Port = Literal["motors", "handle"]
#: How the controller acts (see `Passivity.method`).
Method = Literal["damper_bounding", "damper", "bounding"]
_MODES = {"damper_bounding": _kernel.DAMPER_BOUNDING, "damper": _kernel.DAMPER, "bounding": _kernel.BOUNDING}


@dataclasses.dataclass(frozen=True)
class Passivity:
    """Settings of the passivity observer and controller (Hannaford and Ryu 2002).

    Attributes:
        port: "motors" (τ against q̇: the whole controller, null-space side included) or
            "handle" (J#ᵀτ against ẋ: H&R's virtual-environment port).
        alpha_max: largest damping rate α [1/s]; None: half the control rate (α ΔT ≤ 0.5).
        control: False: observe only (E_obs is computed, no damping is added).
        initial_energy: E(0) of H&R eq. 1 [J], energy the controller may give back before
            it counts as active (0: the rendered environment starts empty).
        method: "damper" (default): H&R's series damper alone (the law's torque, safety torques
            included, is never scaled; what the damper cannot take out is carried);
            "damper_bounding": the damper plus energy bounding (the law's torque scaled down by what
            the damper cannot take out; steps 2–4 of `PassivityController.apply`); "bounding":
            energy bounding only (no damper).
    """

    port: Port = "motors"
    alpha_max: float | None = None
    control: bool = True
    initial_energy: float = 0.0
    method: Method = "damper"

    def __post_init__(self) -> None:
        if self.port not in ("motors", "handle"):
            raise InvalidInput(f"port: expected 'motors' or 'handle', got {self.port!r}")
        if self.alpha_max is not None and not (math.isfinite(self.alpha_max) and self.alpha_max > 0):
            raise InvalidInput(f"alpha_max: must be finite and > 0 [1/s] or None, got {self.alpha_max!r}")
        if not (math.isfinite(self.initial_energy) and self.initial_energy >= 0):
            raise InvalidInput(f"initial_energy: must be finite and >= 0 [J], got {self.initial_energy!r}")
        if self.method not in _MODES:
            raise InvalidInput(f"method: expected one of {', '.join(_MODES)}, got {self.method!r}")

    @property
    def mode(self) -> int:
        """The compiled kernel's code of `method` (`rhi.control._compiled.passivity`; OBSERVE without control)."""
        return _MODES[self.method] if self.control else _kernel.OBSERVE


@dataclasses.dataclass
class PassivityState:
    """State of the observer and controller after a tick.

    Attributes:
        energy: E_obs, energy that has flowed from the device into the controller [J]
            (≥ −initial_energy when passive; negative: energy the controller created).
        alpha: damping rate α of the last tick [1/s] (0: the PC was idle).
        scale: λ of the last tick, the factor on the law's torque (1: untouched).
        dissipated: energy the PC's damping was predicted to take out, −Σ w(e_d) [J].
        t, position, effort: time [s], port position (q [rad] or x [m]) and port effort
            (τ [N m] or J#ᵀτ [N]) of the last tick, held until the next one.
    """

    energy: float = 0.0
    alpha: float = 0.0
    scale: float = 1.0
    dissipated: float = 0.0
    t: float = -math.inf
    position: np.ndarray | None = None
    effort: np.ndarray | None = None


class PassivityController:
    """The PO/PC pair for one controller (see the module docstring for the equations).

    Use per tick: ``tau = apply(t, kin, tau0, lo, hi)``, which runs the observer, adds the
    damping and records the torque sent; an observer alone is ``Passivity(control=False)``.

    Args:
        config: the settings.
        reference: run the readable composition (`reference_passivity`)
            instead of the compiled kernel (`rhi.control._compiled.passivity`); equal to rounding.
    """

    def __init__(self, config: Passivity, *, reference: bool = False) -> None:
        self.config = config
        self.reference = bool(reference)
        self.state = PassivityState(energy=config.initial_energy)
        self._alpha_max = -1.0 if config.alpha_max is None else float(config.alpha_max)

    def reset(self) -> None:
        """Empty the observer (E_obs = E(0))."""
        self.state = PassivityState(energy=self.config.initial_energy)

    def apply(self, t: float, kin: DeviceTerms, tau0: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """PO then PC for one tick: the torque to send (n,) [N m], within [lo, hi]; records it for the observer.

        1. PO: ``E_obs(n) = E_obs(n−1) − e(n−1)ᵀ(p(n) − p(n−1))`` (effort e, port position p).
        2. Prediction of the coming hold interval (H&R's PO includes the current sample
           f(n) v(n)): the work a held effort e does on the free mechanism in ΔT,
           ``w(e) = ΔT eᵀv + ½ ΔT² eᵀ M⁻¹ e`` (M⁻¹ = M_q⁻¹ at the motor port, M_x⁻¹ at the
           handle); the second term is the energy the held torque gives by accelerating the
           port within the interval — the sample-and-hold energy a stiff or switching law
           injects into light links, which the first term alone misses.
           ``E_pred = E_obs(n) − w(e₀)``.
        3. PC (H&R's series damper): while ``E_pred < 0``, the damping torque
           ``τ_d = −α M q̇`` (``Jᵀ(−α M_x ẋ)`` at the handle port), ``α = −E_pred / (ΔT q̇ᵀMq̇)``
           bounded by ``alpha_max``, clipped to the torque box.
        4. Energy bounding (methods "damper_bounding" and "bounding"; "damper" stops at step 3 and
           carries what is left): what the box and the bound on α leave, the law's torque is scaled
           down, so the law never delivers energy the port has not received. At the motor port its null-space
           part N τ₀ (N = I − JᵀJ#ᵀ: allocation and objectives, no force at the handle) yields
           first, by the largest λ_N ∈ [0, 1] with ``w(Jᵀ J#ᵀτ₀ + λ_N N τ₀ + τ_d) ≤ E_obs(n)``,
           then the task part, by λ (``scale``) with ``w(λ JᵀJ#ᵀτ₀ + τ_d) ≤ E_obs(n)``; at the
           handle port the whole law's torque by λ. Each bound is the larger root of a
           quadratic in λ. λ < 1 only while the law's torque would push energy out.

        Args:
            t: time of this tick [s].
            kin: the device terms at the measured (q, q̇).
            tau0: (n,) the torque the control law would send [N m].
            lo: (n,) lower bound of the torque box [N m] (<= 0).
            hi: (n,) upper bound of the torque box [N m] (>= 0).
        """
        if self.reference:
            return reference_passivity(self, t, kin, tau0, lo, hi)
        s, motors = self.state, self.config.port == "motors"
        if motors:
            pos, v, Mp, Mi = kin.q, kin.dq, kin.M, kin.Minv
        else:
            pos, v, Mp, Mi = kin.x, kin.xdot, kin.Lambda, kin.JMinv.dot(kin.J.T)
        prev = s.position is not None
        tau, effort = np.empty(tau0.shape[0]), np.empty(len(pos))
        s.energy, s.alpha, s.scale, dissipated = _kernel.apply(
            s.energy, prev, s.position if prev else pos, s.effort if prev else pos, t - s.t, pos, v, Mp, Mi, kin.J,
            kin.Jsharp, tau0, lo, hi, motors, self.config.mode, self._alpha_max, tau, effort)
        s.effort = effort
        s.dissipated += dissipated
        s.t, s.position = t, np.array(pos, dtype=float)
        return tau


def reference_passivity(pc: PassivityController, t: float, kin: DeviceTerms, tau0: np.ndarray, lo: np.ndarray,
                        hi: np.ndarray) -> np.ndarray:
    """`PassivityController.apply` (steps 1–4 of its docstring), one equation per line.

    The oracle of `rhi.control._compiled.passivity.apply` (``PassivityController(reference=True)`` runs it).
    Returns the torque to send (n,) [N m]; advances ``pc.state``.
    """
    s, cfg = pc.state, pc.config
    motors = cfg.port == "motors"
    pos, v = (kin.q, kin.dq) if motors else (kin.x, kin.xdot)
    if v is None:
        raise InvalidInput("dq: the passivity controller needs the joint velocity; call Device.terms(q, dq)")
    if s.position is not None and s.effort is not None:  # 1. PO: the held effort's exact work over the interval
        s.energy -= float(s.effort.dot(pos - s.position))
    E, dt = s.energy, t - s.t
    s.alpha, s.scale = 0.0, 1.0
    tau = tau0

    def effort(tau: np.ndarray) -> np.ndarray:  # τ at the motor port, J#ᵀτ (eq. 7.5) at the handle
        return tau if motors else kin.Jsharp.T.dot(tau)

    if cfg.control and dt > 0.0 and math.isfinite(dt):
        Minv = kin.Minv if motors else kin.JMinv.dot(kin.J.T)
        e0 = effort(tau0)
        w0 = hold_work(e0, v, Minv, dt)
        if w0 > E:  # 2. the coming interval would leave E_obs < 0
            Mv = kin.M.dot(v) if motors else kin.Lambda.dot(v)
            ke2 = float(v.dot(Mv))  # 2 × the kinetic energy of the port's motion [J]
            tau_d = np.zeros_like(tau0)
            if ke2 > 0.0 and cfg.method != "bounding":  # 3. the series damper
                a_max = 0.5 / dt if cfg.alpha_max is None else cfg.alpha_max
                s.alpha = min((w0 - E) / (dt * ke2), a_max)
                tau_d = -s.alpha * Mv if motors else kin.J.T.dot(-s.alpha * Mv)
                tau_d = np.minimum(np.maximum(tau_d, lo), hi)
                s.dissipated -= hold_work(effort(tau_d), v, Minv, dt)
            if cfg.method == "damper":  # the law untouched
                tau = tau0 + tau_d
            elif motors:  # 4. the null-space part of the law's torque yields first, then the task part
                tau_t = kin.J.T.dot(kin.Jsharp.T.dot(tau0))
                lam_n = largest_scale(E, tau_t + tau_d, tau0 - tau_t, v, Minv, dt)
                lam_t = 1.0 if lam_n > 0.0 else largest_scale(E, tau_d, tau_t, v, Minv, dt)
                tau = lam_t * tau_t + lam_n * (tau0 - tau_t) + tau_d
                s.scale = lam_t
            else:
                s.scale = largest_scale(E, effort(tau_d), e0, v, Minv, dt)
                tau = s.scale * tau0 + tau_d
            tau = np.minimum(np.maximum(tau, lo), hi)
    s.t, s.position, s.effort = t, np.array(pos, dtype=float), effort(tau)
    return tau


__all__ = ["Method", "Passivity", "PassivityController", "PassivityState", "Port", "reference_passivity"]
