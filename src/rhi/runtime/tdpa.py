"""The TDPA of a delayed channel: the observers and bounded controllers of its two ports, with drift compensation.

The time-domain passivity approach (TDPA): Ryu, Artigas & Preusche, "A passive bilateral control
scheme for a teleoperator with time-varying communication delay", Mechatronics 20(7), 2010; the
drift compensation of Artigas, Ryu & Preusche, "Position drift compensation in time domain
passivity based teleoperation", IROS 2010.

The channel of a position–force teleoperator is a two-port: at the master it puts out the force
F_m rendered on the hand against the handle velocity (power F_mᵀẋ_m, > 0: energy to the user); at
the slave the set-point motion v_d against the measured contact force F_e (power −F_eᵀv_d, > 0:
energy to the environment). Each side splits the power at its port into input and output energy
(E_in, E_out, cumulative) and sends its E_in with every packet; the channel is passive while each
side's output stays below the input the other side reported (received late: a conservative
bound), W = E_in,other − E_out ≥ 0.

Master (impedance port, `damp`). The force rendered at tick k is held until tick k + 1 (the
device's zero-order hold), so the observer books F_r(k)ᵀ(x_m(k+1) − x_m(k)) — the force paired
with the displacement over the sample (H&R's alignment), where F_r is the force the device
rendered (the allocation's scaling α included). The coming sample's output is predicted as
F_mᵀẋ_m ΔT; while it would leave W < 0 the passivity controller adds a damping force −β ẋ_m with
β = −W / (ΔT |ẋ_m|²), bounded three times: β ≤ ``max_damping``, β ≤ ½ m_min / ΔT (m_min the
smallest apparent mass of the handle, the smallest eigenvalue of Λ: a sampled damper with
β ΔT / m ≥ 1 reverses the motion within a sample and puts energy in instead of taking it out)
and |β ẋ_m| ≤ ``max_force``. Near zero
velocity the unbounded β asks for unbounded force (1 mJ at 2 µm/s: 5·10⁵ N); bounded, the
energy it could not take out stays in the books (E_out − E_in,other) and is taken out in the
next samples, as the hand moves.

Slave (admittance port, `correct`). The set-point follows the master's (delayed) position; its
velocity over the sample v_d = (x_d(k) − x_d(k−1))/ΔT is the flow. While the coming output
−F_eᵀv_d ΔT would leave W < 0 the controller corrects the velocity, v_d ← v_d + α F_e with
α = −W / (ΔT |F_e|²), bounded by |α F_e| ≤ ``max_correction_speed`` (the set-point backs off along
the contact force; what the bound leaves stays in the books): the price is a drift
of the set-point from the master's position. Drift compensation (Artigas et al. 2010): while
W > 0 the set-point moves back towards the master's position at ``drift_rate`` (at most
``max_drift_speed``), spending at most the energy W has in hand in the sample (moving against
F_e costs −F_eᵀv ΔT, moving with it costs nothing), so the port stays passive.

Why the slave side is passive: the observer books −∫F_eᵀv_d dt; the slave's PD coupling (a
spring K_p and a damper K_d between the set-point and the tip) and its gravity-compensated
mechanism store ½K_p|x_d − x_s|² + ½ẋ_sᵀM_xẋ_s and dissipate, so the energy reaching the
environment, −∫F_eᵀẋ_s dt, exceeds what the set-point port delivered only by the inertial force
of the tip along the set-point motion, ∫(M_x ẍ_s)ᵀv_d dt (exact for a quasi-static contact). The
physically measured energy at both ports (`rhi.runtime.bilateral.BilateralLog.generated`) is the
check that this approximation holds in a run.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rhi.errors import InvalidInput

_EPS_V, _EPS_F = 1e-6, 1e-6


def dot(a, b) -> float:
    """The dot product a · b of two small vectors, summed in order from 0.0 (the compiled twins' arithmetic).

    Not NumPy's ``a @ b``: BLAS may fuse a multiply and an add (an FMA, depending on the CPU), and the TDPA's
    decisions (W ≥ 0) at a tie would then depend on the machine, and differ from the compiled loop's.
    """
    s = 0.0
    for x, y in zip(np.asarray(a, dtype=float).tolist(), np.asarray(b, dtype=float).tolist()):
        s += x * y
    return s


def smallest_mass(Lambda: np.ndarray) -> float:
    """The smallest eigenvalue of the symmetric apparent mass Λ (m, m) [kg]: closed form for m ≤ 2 (its lower triangle)."""
    L = np.asarray(Lambda, dtype=float)
    if L.shape == (1, 1):
        return float(L[0, 0])
    if L.shape == (2, 2):
        a, c, d = float(L[0, 0]), float(L[1, 0]), float(L[1, 1])
        h = 0.5 * (a - d)
        return 0.5 * (a + d) - math.sqrt(h * h + c * c)
    return float(np.linalg.eigvalsh(L)[0])


@dataclasses.dataclass(frozen=True)
class TDPA:
    """Settings of the TDPA on both sides of the channel.

    Attributes:
        max_force: bound on the master's damping force |β ẋ_m| [N].
        max_damping: bound on the master's damping β [N s/m].
        drift_rate: rate γ at which the slave's set-point returns to the master's position [1/s] (0: no
            drift compensation).
        max_drift_speed: bound on the set-point speed of the drift compensation [m/s].
        max_correction_speed: bound on the slave's velocity correction |α F_e| [m/s] (a small contact force
            would otherwise ask for a jump of the set-point).
    """

    max_force: float = 5.0
    max_damping: float = 100.0
    drift_rate: float = 2.0
    max_drift_speed: float = 0.02
    max_correction_speed: float = 0.5

    def __post_init__(self) -> None:
        for name in ("max_force", "max_damping", "max_drift_speed", "max_correction_speed"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
        if not (isinstance(self.drift_rate, (int, float)) and math.isfinite(self.drift_rate) and self.drift_rate >= 0):
            raise InvalidInput(f"drift_rate: must be finite and >= 0 [1/s], got {self.drift_rate!r}")


#: The default settings.
DEFAULT = TDPA()


@dataclasses.dataclass
class PortEnergy:
    """Input/output energy at one port of the channel [J] and the passivity controller's last action.

    Attributes:
        E_in, E_out: cumulative input and output energy of the port [J].
        dissipated: energy the controller was predicted to take out, summed [J].
        gain: β [N s/m] at the master, α [m/(N s)] at the slave, of the last tick (0: idle).
        deficit: the energy the bounded controller could not take out at the last tick [J].
    """

    E_in: float = 0.0
    E_out: float = 0.0
    dissipated: float = 0.0
    gain: float = 0.0
    deficit: float = 0.0

    def book(self, energy: float) -> None:
        """Add the energy the port put out over a sample [J] (< 0: energy taken in)."""
        if energy > 0:
            self.E_out += energy
        else:
            self.E_in -= energy


def damp(port: PortEnergy, F: np.ndarray, v: np.ndarray, mass: float, E_other: float, dt: float,
         cfg: TDPA) -> np.ndarray:
    """The master's bounded passivity controller: the force to render (m,) [N] for the coming sample.

    Args:
        port: the master's energies (E_out booked up to now); gain, dissipated and deficit updated.
        F: (m,) the force the channel delivers [N].
        v: (m,) the handle velocity [m/s].
        mass: the handle's smallest apparent mass m_min [kg].
        E_other: the slave's reported input energy [J].
        dt: the sample [s].
        cfg: the bounds.
    """
    port.gain, port.deficit = 0.0, 0.0
    W = E_other - port.E_out - max(dot(F, v), 0.0) * dt
    vv = dot(v, v)
    if W >= 0:
        return F
    if vv <= _EPS_V**2:
        port.deficit = -W
        return F
    beta = min(-W / (dt * vv), cfg.max_damping, 0.5 * mass / dt, cfg.max_force / math.sqrt(vv))
    port.gain = beta
    port.dissipated += beta * vv * dt
    port.deficit = -W - beta * vv * dt
    return F - beta * v


def correct(port: PortEnergy, v: np.ndarray, F_e: np.ndarray, E_other: float, drift: np.ndarray, dt: float,
            cfg: TDPA) -> np.ndarray:
    """The slave's passivity controller and drift compensation: the set-point velocity (m,) [m/s] of the sample.

    Args:
        port: the slave's energies (E_out booked up to now); gain and dissipated updated.
        v: (m,) the set-point velocity the master's motion asks for [m/s].
        F_e: (m,) the measured contact force on the slave [N].
        E_other: the master's reported input energy [J].
        drift: (m,) the set-point's offset from the master's position so far [m].
        dt: the sample [s].
        cfg: the drift compensation's rate and bound.
    """
    port.gain, port.deficit = 0.0, 0.0
    P = -dot(F_e, v)
    A = E_other - port.E_out
    W = A - max(P, 0.0) * dt
    ff = dot(F_e, F_e)
    if W < 0 and ff > _EPS_F**2:
        alpha = min(-W / (dt * ff), cfg.max_correction_speed / math.sqrt(ff))
        port.gain = alpha
        port.dissipated += alpha * ff * dt
        port.deficit = -W - alpha * ff * dt
        return v + alpha * F_e
    if W < 0:
        port.deficit = -W
        return v
    dn = math.sqrt(dot(drift, drift))
    if cfg.drift_rate == 0.0 or dn == 0.0:
        return v
    vc = -min(cfg.drift_rate, cfg.max_drift_speed / dn) * drift
    cost = -dot(F_e, vc)  # the power the correction adds at the port [W]
    s = 1.0 if cost <= 0 else min(1.0, max(0.0, (A / dt - P) / cost))
    return v + s * vc


__all__ = ["DEFAULT", "TDPA", "PortEnergy", "correct", "damp", "dot", "smallest_mass"]
