"""Bilateral position–force teleoperation over a delayed channel, kept passive by the TDPA.

The master (a haptic device in the user's hand) sends its handle position; the slave tracks it
with a Cartesian PD and sends back the contact force its F/T sensor measures; the master
renders that force (thesis §8.2's "bilateral teleoperation", beyond the thesis's unilateral
§5.3). A delayed channel is an active element: energy can appear in it.

Time-domain passivity approach (TDPA; Ryu, Artigas & Preusche, "A passive bilateral control
scheme for a teleoperator with time-varying communication delay", Mechatronics 20(7), 2010):
each side splits the power at its port into input and output energy,

    master: P_M = F_mᵀ v_m  (force rendered on the hand × handle velocity; > 0: energy to the user)
    slave:  P_S = −F_eᵀ v_s (slave motion against the contact force; > 0: energy to the environment)

E_in += max(−P, 0) Δt, E_out += max(P, 0) Δt, and sends its cumulative E_in with every packet.
The channel is passive while each side's output energy stays below the input energy the other
side reports (received late, so the bound is conservative): W = E_in,other(t − T) − E_out ≥ 0.
When W would go negative, a passivity controller dissipates the excess: at the master
(impedance port) a damping force F_m ← F_m − β v_m with β = −W/(Δt |v_m|²); at the slave
(admittance port) a velocity correction v_s ← v_s + α F_e with α = −W/(Δt |F_e|²), integrated
into the slave's set-point (its position drift is the price). Lost and reordered packets are
harmless: energies are cumulative and the newest packet wins.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput

_EPS_V, _EPS_F = 1e-6, 1e-6


@dataclasses.dataclass
class PortEnergy:
    """Input/output energy at one port of the channel [J] and the passivity controller's last action."""

    E_in: float = 0.0
    E_out: float = 0.0
    dissipated: float = 0.0
    gain: float = 0.0  # β [N s/m] at the master, α [m/(N s)] at the slave


def _observe(port: PortEnergy, P: float, dt: float) -> None:
    if P > 0:
        port.E_out += P * dt
    else:
        port.E_in -= P * dt


class Master:
    """The master side: renders the slave's (delayed) contact force through `controller`, sends x_m.

    Args:
        controller: a controller whose primary law renders sensors["force"] (e.g. `ForceRendering`).
        end: the channel end (`LocalEnd` or `UDPEnd`).
        passivity: run the TDPA passivity controller.
        dt: control period [s].
    """

    def __init__(self, controller, end, *, passivity: bool = True, dt: float = 1e-3) -> None:
        self.inner, self.end, self.passivity, self.dt = controller, end, bool(passivity), float(dt)
        self.device = controller.device
        self.state = getattr(controller, "state", None)
        self.port = PortEnergy()
        self.force = np.zeros(self.device.m)  # the last rendered force [N]
        self.received = np.zeros(self.device.m)  # the last force received from the slave [N]

    def step(self, t: float, q, dq, sensors) -> np.ndarray:
        """One master tick: render the force received from the slave, TDPA-damped when passivity is on; send x and energy."""
        m = self.device.m
        self.end.tick()
        pkt = self.end.latest()
        F = np.zeros(m) if pkt is None else pkt[:m].copy()
        E_other = 0.0 if pkt is None else float(pkt[m])
        self.received = F.copy()
        kin = self.device.terms(q, dq, check=False)
        v = kin.xdot
        P = float(F @ v)
        self.port.gain = 0.0
        if self.passivity:
            W = E_other - self.port.E_out - max(P, 0.0) * self.dt
            vv = float(v @ v)
            if W < 0 and vv > _EPS_V ** 2:
                beta = -W / (self.dt * vv)
                F = F - beta * v
                self.port.gain = beta
                self.port.dissipated += beta * vv * self.dt
                P = float(F @ v)
        _observe(self.port, P, self.dt)
        self.force = F
        self.end.send(np.concatenate([kin.x, [self.port.E_in]]))
        return self.inner.step(t, q, dq, {**sensors, "force": F})


class Slave:
    """The slave side: tracks the master's (delayed) position with a Cartesian PD, sends back F_e.

    τ = Jᵀ(K_p (x_d − x) + K_d (v_d − ẋ)) + g(q), x_d = x_s0 + (x_m − x_m0) + drift, where x_m0 is
    the first master position received and the drift is the TDPA's integrated velocity correction.

    Args:
        device: the slave's model.
        end: the channel end.
        kp: K_p [N/m]; kd: K_d [N s/m].
        passivity: run the TDPA passivity controller.
        dt: control period [s].
    """

    def __init__(self, device, end, *, kp: float = 800.0, kd: float = 20.0, passivity: bool = True,
                 dt: float = 1e-3) -> None:
        self.device, self.end = device, end
        self.kp, self.kd = scalar("kp", kp, nonnegative=True), scalar("kd", kd, nonnegative=True)
        self.passivity, self.dt = bool(passivity), float(dt)
        self.port = PortEnergy()
        self._rows = list(device.task_rows)
        self.x_d: np.ndarray | None = None  # commanded slave position [m]
        self._x_s0: np.ndarray | None = None
        self._x_m0: np.ndarray | None = None
        self._x_nom: np.ndarray | None = None
        self.F_e = np.zeros(device.m)
        self.drift = np.zeros(device.m)

    def step(self, t: float, q, dq, sensors) -> np.ndarray:
        """One slave tick: PD toward the master's (delayed) position, TDPA-limited; send the contact force and energy."""
        m = self.device.m
        kin = self.device.terms(q, dq, check=False)
        if self._x_s0 is None:
            self._x_s0, self._x_nom, self.x_d = kin.x.copy(), kin.x.copy(), kin.x.copy()
        self.end.tick()
        pkt = self.end.latest()
        if pkt is not None and self._x_m0 is None:
            self._x_m0 = pkt[:m].copy()
        x_nom = self._x_s0 if pkt is None else self._x_s0 + (pkt[:m] - self._x_m0)
        v = (x_nom - self._x_nom) / self.dt
        self._x_nom = x_nom
        E_other = 0.0 if pkt is None else float(pkt[m])
        F_e = np.asarray(sensors["ft"], dtype=float)[self._rows]
        self.F_e = F_e
        P = -float(F_e @ v)
        self.port.gain = 0.0
        if self.passivity:
            W = E_other - self.port.E_out - max(P, 0.0) * self.dt
            ff = float(F_e @ F_e)
            if W < 0 and ff > _EPS_F ** 2:
                alpha = -W / (self.dt * ff)
                v = v + alpha * F_e
                self.drift = self.drift + alpha * F_e * self.dt
                self.port.gain = alpha
                self.port.dissipated += alpha * ff * self.dt
                P = -float(F_e @ v)
        _observe(self.port, P, self.dt)
        self.x_d = x_nom + self.drift
        self.end.send(np.concatenate([F_e, [self.port.E_in]]))
        F = self.kp * (self.x_d - kin.x) + self.kd * (v - kin.xdot)
        return kin.J.T @ F + kin.g


@dataclasses.dataclass
class BilateralLog:
    """A bilateral run, one row per control tick (N ticks).

    Attributes:
        t: (N,) time [s].
        x_m, x_s, x_d: (N, m) master handle, slave tip and slave set-point positions [m].
        F_m: (N, m) force rendered on the user's hand (after the passivity controller) [N].
        F_e: (N, m) contact force measured at the slave [N].
        F_hand: (N, m) force of the user's hand on the master [N].
        E_M_in, E_M_out, E_S_in, E_S_out: (N,) cumulative port energies [J] (see the module docstring).
        beta, alpha: (N,) passivity-controller gains at the master [N s/m] and the slave [m/(N s)].
        tmi: (N,) teleoperation manipulability index of the master–slave pair (eq. 4.17), NaN between samples.
        fault: why a plant stopped, if one did.
    """

    t: np.ndarray
    x_m: np.ndarray
    x_s: np.ndarray
    x_d: np.ndarray
    F_m: np.ndarray
    F_e: np.ndarray
    F_hand: np.ndarray
    E_M_in: np.ndarray
    E_M_out: np.ndarray
    E_S_in: np.ndarray
    E_S_out: np.ndarray
    beta: np.ndarray
    alpha: np.ndarray
    tmi: np.ndarray
    fault: str | None = None

    @property
    def generated(self) -> np.ndarray:
        """(N,) net energy the channel has put out so far: E_out − E_in over both ports [J] (> 0: active)."""
        return self.E_M_out + self.E_S_out - self.E_M_in - self.E_S_in


def simulate_bilateral(master_plant, master_controller, slave_plant, *, duration: float, hand=None, tissue=None,
                       forward=None, backward=None, passivity: bool = True, kp: float = 800.0, kd: float = 20.0,
                       rate: float = 1000.0, tmi_every: int = 20) -> BilateralLog:
    """Both sides in one lock-step loop over a seeded delayed channel (deterministic).

    The two-process version runs the same `Master` and `Slave` over `UDPEnd`s with `rhi.runtime.run`.

    Args:
        master_plant: the master's MuJoCo plant (already reset).
        slave_plant: the slave's MuJoCo plant (already reset).
        master_controller: renders sensors["force"] on the master (e.g. `ForceRendering`).
        duration: simulated time [s].
        hand: the user on the master, `force(t, x, ẋ)`.
        tissue: the slave's contact environment, `force(x, ẋ)` (applied in the slave plant).
        forward: `ChannelConfig` master→slave (default: no delay).
        backward: `ChannelConfig` slave→master (default: no delay).
        passivity: run the TDPA on both sides.
        kp: the slave's Cartesian stiffness gain [N/m].
        kd: the slave's Cartesian damping gain [N s/m].
        rate: control rate of both sides [Hz].
        tmi_every: compute the TMI every this many ticks.
    """
    from rhi.metrics import tmi as tmi_fn
    from rhi.runtime.channel import ChannelConfig, local_pair
    from rhi.sim.loop import Session

    ms = Session(master_plant, rate=rate, hand=hand)
    ss = Session(slave_plant, rate=rate, physical=tissue)
    dt = ms.dt
    if scalar("duration", duration) < dt:
        raise InvalidInput(f"duration: must be at least one period ({dt} s), got {duration!r}")
    m_end, s_end = local_pair(forward or ChannelConfig(), backward or ChannelConfig(seed=1), dt)
    master = Master(master_controller, m_end, passivity=passivity, dt=dt)
    slave = Slave(slave_plant.device, s_end, kp=kp, kd=kd, passivity=passivity, dt=dt)
    N = int(round(duration / dt))
    m = master_plant.m
    z = lambda *s: np.zeros((N, *s))  # noqa: E731
    log = BilateralLog(z(), z(m), z(m), z(m), z(m), z(m), z(m), z(), z(), z(), z(), z(), z(), np.full(N, np.nan))
    dm, ds = master_plant.device, slave_plant.device
    for k in range(N):
        mp, sp = master_plant, slave_plant
        tau_m = master.step(ms.t, mp.q, mp.dq, {"ft": mp.ft()})
        tau_s = slave.step(ss.t, sp.q, sp.dq, {"ft": sp.ft()})
        if k % tmi_every == 0:
            log.tmi[k] = float(tmi_fn(dm.jacobian(mp.q), ds.jacobian(sp.q)))
        log.t[k] = ms.t
        fault = ms.advance(tau_m) or ss.advance(np.clip(tau_s, ds.torque_min, ds.torque_max))
        log.x_m[k], log.x_s[k], log.x_d[k] = mp.x, sp.x, slave.x_d
        log.F_m[k], log.F_e[k], log.F_hand[k] = master.force, slave.F_e, ms.F_hand
        log.E_M_in[k], log.E_M_out[k] = master.port.E_in, master.port.E_out
        log.E_S_in[k], log.E_S_out[k] = slave.port.E_in, slave.port.E_out
        log.beta[k], log.alpha[k] = master.port.gain, slave.port.gain
        if fault is not None:
            log.fault = fault
            for f in dataclasses.fields(log):
                v = getattr(log, f.name)
                if isinstance(v, np.ndarray):
                    setattr(log, f.name, v[:k + 1])
            break
    return log


def run_slave(plant, end, *, tissue=None, duration: float | None = None, passivity: bool = True, kp: float = 800.0,
              kd: float = 20.0, **run_kw):
    """The slave side as its own process, under `rhi.runtime.run`.

    The PD slave on `plant` presses on `tissue`, following what arrives on `end`. Returns
    (`RunResult`, the `Slave`). (The master side is ``run(SimLink(plant, hand=hand), Master(controller, end))``.)
    """
    from rhi.runtime.loop import run
    from rhi.runtime.simlink import SimLink

    rate = run_kw.pop("rate", 1000.0)
    slave = Slave(plant.device, end, kp=kp, kd=kd, passivity=passivity, dt=1.0 / rate)
    return run(SimLink(plant, rate=rate, physical=tissue), slave, rate=rate, duration=duration, **run_kw), slave
