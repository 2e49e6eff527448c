"""Bilateral position–force teleoperation over a delayed channel, kept passive by the TDPA.

The master (a haptic device in the user's hand) sends its handle position; the slave tracks it
with a Cartesian PD and sends back the contact force its F/T sensor measures; the master
renders that force (thesis §8.2's "bilateral teleoperation", beyond the thesis's unilateral
§5.3). A delayed channel is an active element: energy can appear in it. The time-domain
passivity approach (`rhi.runtime.tdpa`: the observers and the bounded passivity controllers of
both ports, with drift compensation) keeps it passive. Lost and reordered packets are harmless:
energies are cumulative and the newest packet wins.

Energy is measured twice. The TDPA's books (`BilateralLog.observed`) are what its controllers
act on; `BilateralLog.generated` is measured from the physical signals, independently of them:
the hand's work on the master ∫F_hᵀẋ_m dt (each physics step's force against the velocity
after it) and the tissue's work on the slave Σ F_env(k)ᵀ(x_s(k+1) − x_s(k)) (each physics step's
force against the displacement over it). Their negative sum is the energy the teleoperator
(both devices, their controllers and the channel) has handed to the hand and the tissue; it
never exceeds the devices' initial storage (zero at rest) while the teleoperator is passive.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput
from rhi.runtime.tdpa import DEFAULT, TDPA, PortEnergy, correct, damp, dot, smallest_mass


def _settings(passivity) -> TDPA | None:
    if passivity is not None and not isinstance(passivity, TDPA):
        raise InvalidInput(f"passivity: expected a rhi.runtime.tdpa.TDPA or None, got {type(passivity).__name__}")
    return passivity


class Master:
    """The master side: renders the slave's (delayed) contact force through `controller`, sends x_m.

    Args:
        controller: a controller whose primary law renders sensors["force"] (e.g. `ForceRendering`).
        end: the channel end (`LocalEnd` or `UDPEnd`).
        passivity: the TDPA's settings, or None (no passivity control; the port is still observed).
        dt: control period [s].
    """

    def __init__(self, controller, end, *, passivity: TDPA | None = DEFAULT, dt: float = 1e-3) -> None:
        self.inner, self.end, self.passivity, self.dt = controller, end, _settings(passivity), float(dt)
        self.device = controller.device
        self.state = getattr(controller, "state", None)
        self.port = PortEnergy()
        self.force = np.zeros(self.device.m)  # the last force sent to the renderer [N]
        self.received = np.zeros(self.device.m)  # the last force received from the slave [N]
        self._held: tuple[np.ndarray, np.ndarray] | None = None  # (x_m, force rendered) of the last tick

    def step(self, t: float, q, dq, sensors) -> np.ndarray:
        """One master tick: book the last sample, render the slave's force (TDPA-damped), send x and energy."""
        m = self.device.m
        self.end.tick()
        pkt = self.end.latest()
        F = np.zeros(m) if pkt is None else pkt[:m].copy()
        E_other = 0.0 if pkt is None else float(pkt[m])
        self.received = F.copy()
        kin = self.device.terms(q, dq, check=False)
        if self._held is not None:  # the force held over the last sample against the displacement over it
            x0, F0 = self._held
            self.port.book(dot(F0, kin.x - x0))
        if self.passivity is not None:
            F = damp(self.port, F, kin.xdot, smallest_mass(kin.Lambda), E_other, self.dt,
                     self.passivity)
        self.force = F
        self.end.send(np.concatenate([kin.x, [self.port.E_in]]))
        tau = self.inner.step(t, q, dq, {**sensors, "force": F})
        scale = getattr(self.state, "alpha", 1.0)  # the allocation's scaling of the rendered force
        self._held = (kin.x.copy(), F * (scale if np.isfinite(scale) else 1.0))
        return tau


class Slave:
    """The slave side: tracks the master's (delayed) position with a Cartesian PD, sends back F_e.

    τ = Jᵀ(K_p (x_d − x) + K_d (v_d − ẋ)) + g(q), x_d = x_s0 + (x_m − x_m0) + drift, where x_m0 is
    the first master position received and the drift is the TDPA's integrated velocity correction
    (its compensation included).

    Args:
        device: the slave's model.
        end: the channel end.
        kp: K_p [N/m]; kd: K_d [N s/m].
        passivity: the TDPA's settings, or None (no passivity control; the port is still observed).
        dt: control period [s].
    """

    def __init__(self, device, end, *, kp: float = 800.0, kd: float = 20.0, passivity: TDPA | None = DEFAULT,
                 dt: float = 1e-3) -> None:
        self.device, self.end = device, end
        self.kp, self.kd = scalar("kp", kp, nonnegative=True), scalar("kd", kd, nonnegative=True)
        self.passivity, self.dt = _settings(passivity), float(dt)
        self.port = PortEnergy()
        self._rows = list(device.task_rows)
        self.x_d: np.ndarray | None = None  # commanded slave position [m]
        self._x_s0: np.ndarray | None = None
        self._x_m0: np.ndarray | None = None
        self.F_e = np.zeros(device.m)
        self.drift = np.zeros(device.m)

    def step(self, t: float, q, dq, sensors) -> np.ndarray:
        """One slave tick: PD toward the master's (delayed) position, TDPA-limited; send the contact force and energy."""
        m = self.device.m
        kin = self.device.terms(q, dq, check=False)
        if self._x_s0 is None:
            self._x_s0, self.x_d = kin.x.copy(), kin.x.copy()
        self.end.tick()
        pkt = self.end.latest()
        if pkt is not None and self._x_m0 is None:
            self._x_m0 = pkt[:m].copy()
        x_nom = self._x_s0 if pkt is None else self._x_s0 + (pkt[:m] - self._x_m0)
        v_nom = (x_nom + self.drift - self.x_d) / self.dt  # the set-point's motion over the sample
        E_other = 0.0 if pkt is None else float(pkt[m])
        F_e = np.asarray(sensors["ft"], dtype=float)[self._rows]
        self.F_e = F_e
        v = v_nom if self.passivity is None else correct(self.port, v_nom, F_e, E_other, self.drift, self.dt,
                                                         self.passivity)
        self.drift = self.drift + (v - v_nom) * self.dt
        self.port.book(-dot(F_e, v) * self.dt)
        self.x_d = x_nom + self.drift
        self.end.send(np.concatenate([F_e, [self.port.E_in]]))
        F = self.kp * (self.x_d - kin.x) + self.kd * (v - kin.xdot)
        J, g = kin.J, kin.g  # Jᵀ F + g, each sum in order (`dot`), as the compiled loop
        return np.array([dot(J[:, a], F) + g[a] for a in range(len(g))])


class _Metered:
    """A physical environment whose work on the handle is measured: Σ F(k)ᵀ(x(k+1) − x(k)) over the physics steps."""

    def __init__(self, env) -> None:
        self.env, self.work = env, 0.0
        self._last: tuple[np.ndarray, np.ndarray] | None = None

    def force(self, x, xdot) -> np.ndarray:
        self.work = self.at(x)
        F = np.asarray(self.env.force(x, xdot), dtype=float)
        self._last = (np.array(x, dtype=float), F)
        return F

    def at(self, x) -> float:
        """The work up to the handle's position x [m] (the last step's force against the displacement to x) [J]."""
        if self._last is None:
            return self.work
        x0, F = self._last
        return self.work + dot(F, np.asarray(x, dtype=float) - x0)


@dataclasses.dataclass
class BilateralLog:
    """A bilateral run, one row per control tick (N ticks).

    Attributes:
        t: (N,) time [s].
        x_m, x_s, x_d: (N, m) master handle, slave tip and slave set-point positions [m].
        drift: (N, m) the set-point's offset from the master's position, x_d − (x_s0 + x_m − x_m0) as
            received [m] (the TDPA's velocity corrections less its drift compensation).
        F_m: (N, m) force sent to the master's renderer (after the passivity controller) [N].
        F_e: (N, m) contact force measured at the slave [N].
        F_hand: (N, m) force of the user's hand on the master [N].
        W_hand: (N,) the hand's work on the master so far, ∫F_hᵀẋ_m dt [J] (measured in the plant).
        W_env: (N,) the tissue's work on the slave so far, Σ F_envᵀΔx_s [J] (measured in the plant).
        E_M_in, E_M_out, E_S_in, E_S_out: (N,) the TDPA's cumulative port energies [J] (`rhi.runtime.tdpa`).
        beta, alpha: (N,) passivity-controller gains at the master [N s/m] and the slave [m/(N s)].
        tmi: (N,) teleoperation manipulability index of the master–slave pair (eq. 4.17), NaN between samples.
        fault: why a plant stopped, if one did.
        route: the loop that ran it: the compiled loop (`rhi.runtime._compiled.bilateral`), or the Python loop and
            why.
    """

    t: np.ndarray
    x_m: np.ndarray
    x_s: np.ndarray
    x_d: np.ndarray
    drift: np.ndarray
    F_m: np.ndarray
    F_e: np.ndarray
    F_hand: np.ndarray
    W_hand: np.ndarray
    W_env: np.ndarray
    E_M_in: np.ndarray
    E_M_out: np.ndarray
    E_S_in: np.ndarray
    E_S_out: np.ndarray
    beta: np.ndarray
    alpha: np.ndarray
    tmi: np.ndarray
    fault: str | None = None
    route: str = ""

    @property
    def generated(self) -> np.ndarray:
        """(N,) energy the teleoperator has handed the hand and the tissue so far, −(W_hand + W_env) [J].

        Measured from the physical signals at both ports (> 0: the teleoperator, devices, controllers
        and channel together, created energy; it starts at rest, so a passive one keeps it ≤ 0).
        """
        return -(self.W_hand + self.W_env)

    @property
    def observed(self) -> np.ndarray:
        """(N,) what the TDPA's own observers book: E_out − E_in over both channel ports [J] (≤ 0 by construction)."""
        return self.E_M_out + self.E_S_out - self.E_M_in - self.E_S_in


def simulate_bilateral(master_plant, master_controller, slave_plant, *, duration: float, hand=None, tissue=None,
                       forward=None, backward=None, passivity: TDPA | None = DEFAULT, kp: float = 800.0,
                       kd: float = 20.0, rate: float = 1000.0, tmi_every: int = 20, master=None,
                       slave=None) -> BilateralLog:
    """Both sides in one lock-step loop over a seeded delayed channel (deterministic).

    The two-process version runs the same `Master` and `Slave` over `UDPEnd`s with `rhi.runtime.run`. Runs whose
    parts the kernels know run on the compiled loop (`rhi.runtime._compiled.bilateral`, the channel on its
    `rhi.runtime.channel.schedule`), the others on this Python loop (the reference); `BilateralLog.route` says which.

    Args:
        master_plant: the master's MuJoCo plant (already reset).
        slave_plant: the slave's MuJoCo plant (already reset).
        master_controller: renders sensors["force"] on the master (e.g. `ForceRendering`).
        duration: simulated time [s].
        hand: the user on the master, `force(t, x, ẋ)`.
        tissue: the slave's contact environment, `force(x, ẋ)` (applied in the slave plant; its work measured).
        forward: `ChannelConfig` master→slave (default: no delay).
        backward: `ChannelConfig` slave→master (default: no delay).
        passivity: the TDPA's settings on both sides, or None (off).
        kp: the slave's Cartesian stiffness gain [N/m].
        kd: the slave's Cartesian damping gain [N s/m].
        rate: control rate of both sides [Hz].
        tmi_every: compute the TMI every this many ticks.
        master: the `Master` class (or a subclass), called as ``master(controller, end, passivity=, dt=)``.
        slave: the `Slave` class (or a subclass), called as ``slave(device, end, kp=, kd=, passivity=, dt=)``.
    """
    from rhi.metrics import tmi as tmi_fn
    from rhi.runtime._compiled.bilateral import BilateralLoop
    from rhi.runtime.channel import ChannelConfig, local_pair
    from rhi.sim.loop import Session

    metered = None if tissue is None else _Metered(tissue)
    ms = Session(master_plant, rate=rate, hand=hand)
    ss = Session(slave_plant, rate=rate, physical=metered)
    dt = ms.dt
    if scalar("duration", duration) < dt:
        raise InvalidInput(f"duration: must be at least one period ({dt} s), got {duration!r}")
    N = int(round(duration / dt))
    forward, backward = forward or ChannelConfig(), backward or ChannelConfig(seed=1)
    master, slave = master or Master, slave or Slave
    kp, kd = scalar("kp", kp, nonnegative=True), scalar("kd", kd, nonnegative=True)
    why = BilateralLoop.why_not(master is Master and slave is Slave, master_controller, ms, ss, tissue)
    fast = None if why else BilateralLoop(ms, ss, master_controller, tissue, forward, backward, _settings(passivity),
                                          (kp, kd), N)
    m_end, s_end = fast.ends if fast is not None else local_pair(forward, backward, dt)
    mst = master(master_controller, m_end, passivity=passivity, dt=dt)
    slv = slave(slave_plant.device, s_end, kp=kp, kd=kd, passivity=passivity, dt=dt)
    m = master_plant.m
    z = lambda *s: np.zeros((N, *s))  # noqa: E731
    log = BilateralLog(z(), z(m), z(m), z(m), z(m), z(m), z(m), z(m), z(), z(), z(), z(), z(), z(), z(), z(),
                       np.full(N, np.nan), route=fast.route if fast is not None else f"python loop ({why})")
    dm, ds = master_plant.device, slave_plant.device
    k = 0
    while k < N:
        if fast is not None and not master_controller.state.stopped:
            k, fault = fast.run(k, mst, slv, metered, log, tmi_every)
            if fault is not None:
                return _cut(log, fault, k)
            if k == N:
                break
        mp, sp = master_plant, slave_plant
        tau_m = mst.step(ms.t, mp.q, mp.dq, {"ft": mp.ft()})
        tau_s = slv.step(ss.t, sp.q, sp.dq, {"ft": sp.ft()})
        if k % tmi_every == 0:
            log.tmi[k] = float(tmi_fn(dm.jacobian(mp.q), ds.jacobian(sp.q)))
        log.t[k] = ms.t
        fault = ms.advance(tau_m) or ss.advance(np.clip(tau_s, ds.torque_min, ds.torque_max))
        log.x_m[k], log.x_s[k], log.x_d[k], log.drift[k] = mp.x, sp.x, slv.x_d, slv.drift
        log.F_m[k], log.F_e[k], log.F_hand[k] = mst.force, slv.F_e, ms.F_hand
        log.W_hand[k], log.W_env[k] = ms.work, 0.0 if metered is None else metered.at(sp.x)
        log.E_M_in[k], log.E_M_out[k] = mst.port.E_in, mst.port.E_out
        log.E_S_in[k], log.E_S_out[k] = slv.port.E_in, slv.port.E_out
        log.beta[k], log.alpha[k] = mst.port.gain, slv.port.gain
        k += 1
        if fault is not None:
            return _cut(log, fault, k)
    return log


def _cut(log: BilateralLog, fault: str, ticks: int) -> BilateralLog:
    """The log of a run a plant fault ended after `ticks` ticks: its arrays cut there, the fault recorded."""
    log.fault = fault
    for f in dataclasses.fields(log):
        v = getattr(log, f.name)
        if isinstance(v, np.ndarray):
            setattr(log, f.name, v[:ticks])
    return log
    return log


def run_slave(plant, end, *, tissue=None, duration: float | None = None, passivity: TDPA | None = DEFAULT,
              kp: float = 800.0, kd: float = 20.0, **run_kw):
    """The slave side as its own process, under `rhi.runtime.run`.

    The PD slave on `plant` presses on `tissue`, following what arrives on `end`. Returns
    (`RunResult`, the `Slave`). (The master side is ``run(SimLink(plant, hand=hand), Master(controller, end))``.)
    """
    from rhi.runtime.loop import run
    from rhi.runtime.simlink import SimLink

    rate = run_kw.pop("rate", 1000.0)
    slave = Slave(plant.device, end, kp=kp, kd=kd, passivity=passivity, dt=1.0 / rate)
    return run(SimLink(plant, rate=rate, physical=tissue), slave, rate=rate, duration=duration, **run_kw), slave
