"""The actuator saturation observer and the desired-FME transition it drives (thesis §6.3.2, eqs. 6.14–6.19).

The ASO volume V measures the unused torque capacity of τ_m; a hysteresis on V selects the
desired FME (M_Free or M_Stiff), and the activation Ω moves between them along a cosine.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rhi._validate import as_array, scalar
from rhi.control import _compiled as kernels
from rhi.control.saturation import check_torque_limits
from rhi.errors import InvalidInput


def aso_volume(tau, *, torque_min, torque_max, S: float = 50.0) -> float:
    """Actuator saturation observer V ∈ [0, 1]: the tank of unused torque capacity (thesis eq. 6.14).

    V = (1 − exp(−S (−1)ⁿ Πᵢ (τᵢ − T_max,i)(τᵢ − T_min,i)/(T_max,i − T_min,i)²)) / (1 − exp(−S/4ⁿ)).
    V = 1 with every torque at the middle of its range, V = 0 when any torque is at or
    beyond a limit (the formula's sign flips outside the box; we return 0 there).

    Args:
        tau: (n,) joint torques τ_m [N m].
        torque_min: (n,) lower limits [N m].
        torque_max: (n,) upper limits [N m], > torque_min.
        S: shape factor S > 0 (Fig. 6.6 uses 50).
    """
    lo, hi = check_torque_limits(torque_min=torque_min, torque_max=torque_max)
    t = as_array("tau", tau, shape_tail=(lo.shape[-1],))
    if t.ndim != 1:
        raise InvalidInput(f"tau: expected shape ({lo.shape[-1]},), got {t.shape}")
    return kernels.aso_volume(np.ascontiguousarray(t), lo, hi, scalar("S", S, positive=True))


def hysteresis(stiff: bool, V: float, eps1: float, eps2: float) -> bool:
    """Which desired FME is selected, with two thresholds against chattering (thesis eq. 6.15, §6.3.2).

    Switches to stiff when V < ε₁, back to free when V ≥ ε₂ (ε₁ <= ε₂); with ε₁ = ε₂ = ε
    this is the single-threshold switch of eq. 6.15.

    Returns:
        True for M_Stiff^des, False for M_Free^des.
    """
    if eps1 > eps2:
        raise InvalidInput(f"eps1: must be <= eps2, got eps1={eps1}, eps2={eps2}")
    if stiff:
        return not V >= eps2
    return V < eps1


@dataclasses.dataclass(frozen=True)
class TransitionConfig:
    """Parameters of the FME transition (thesis eqs. 6.15–6.19).

    Attributes:
        eps1: ASO threshold below which the transition free → stiff starts (thesis: 0.7).
        eps2: ASO threshold above which the transition stiff → free starts (thesis: 0.95).
        rho: duration per Frobenius distance ρ [s] (eq. 6.19; thesis: 0.003).
        S: ASO shape factor.
    """

    eps1: float = 0.7
    eps2: float = 0.95
    rho: float = 0.003
    S: float = 50.0

    def __post_init__(self) -> None:
        for name in ("eps1", "eps2", "rho", "S"):
            v = getattr(self, name)
            if not np.isfinite(v):
                raise InvalidInput(f"{name}: must be finite, got {v!r}")
        if not 0.0 <= self.eps1 <= self.eps2 <= 1.0:
            raise InvalidInput(f"eps1/eps2: need 0 <= eps1 <= eps2 <= 1, got {self.eps1}, {self.eps2}")
        if self.rho < 0 or self.S <= 0:
            raise InvalidInput(f"rho/S: need rho >= 0 and S > 0, got {self.rho}, {self.S}")


@dataclasses.dataclass(frozen=True)
class TransitionState:
    """State of the activation parameter Ω (1: M_Free^des, 0: M_Stiff^des), eqs. 6.16–6.18.

    Attributes:
        stiff: the target selected by the hysteresis.
        omega_start: Ω when the current transition began.
        t0, tf: start and end of the current transition [s] (tf <= t0: none running).
    """

    stiff: bool = False
    omega_start: float = 1.0
    t0: float = 0.0
    tf: float = 0.0

    def omega(self, t: float) -> float:
        """Ω(t) = Ω_target + (Ω_start − Ω_target) · ½(1 + cos(π (t − t0)/(tf − t0))) (eqs. 6.17, 6.18)."""
        target = 0.0 if self.stiff else 1.0
        if t >= self.tf or self.tf <= self.t0:
            return target
        s = max(0.0, (t - self.t0) / (self.tf - self.t0))
        return target + (self.omega_start - target) * 0.5 * (1.0 + math.cos(math.pi * s))


def transition_step(
    state: TransitionState, t: float, V: float, distance: float, config: TransitionConfig
) -> tuple[TransitionState, float]:
    """Advance the FME transition by one tick: hysteresis on V, then the cosine blend.

    A transition starts when the hysteresis target changes; it runs from the current Ω
    to the new target over ``t_f − t_0 = ρ ‖M_Free − M_Stiff‖_F |Ω_target − Ω|`` (eq. 6.19
    for a full transition). A transition reversed midway starts from the current Ω, so
    Ω is continuous in t and ``|dΩ/dt| <= π/(2 ρ ‖M_Free − M_Stiff‖_F)``.

    Args:
        state: current state.
        t: time [s].
        V: ASO volume in [0, 1].
        distance: ‖M_Free^des − M_Stiff^des‖_F.
        config: thresholds and ρ.

    Returns:
        (new state, Ω(t)); the desired FME is Ω M_Free + (1 − Ω) M_Stiff (eq. 6.16).
    """
    stiff = hysteresis(state.stiff, V, config.eps1, config.eps2)
    if stiff != state.stiff:
        om = state.omega(t)
        target = 0.0 if stiff else 1.0
        duration = config.rho * distance * abs(target - om)
        state = TransitionState(stiff, om, t, t + duration)
    return state, state.omega(t)


__all__ = ["TransitionConfig", "TransitionState", "aso_volume", "hysteresis", "transition_step"]
