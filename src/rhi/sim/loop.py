"""The simulation loop: controller at a fixed rate (1 kHz), plant substeps, hand, environments, logs.

`Session` is a plant with its user (hand), its physical world and an optional teleoperated
slave, advanced one control period at a time; `simulate` runs a controller against it as
fast as the machine allows, and `rhi.runtime.SimLink` puts the same session behind the
device-link protocol for the real-time loop. Both write the same `Log`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, Protocol

import mujoco
import numpy as np
import pinocchio as pin

from rhi._validate import scalar
from rhi.control.controller import ZeroTorque
from rhi.devices import batch
from rhi.errors import InvalidInput
from rhi.sim.environment import describe
from rhi.sim.log import Log, LogWriter, layout
from rhi.sim.plant import Plant, unstable
from rhi.sim.probe import Probe, Recorded
from rhi.sim.telemetry import Telemetry


class Controller(Protocol):
    """Anything with `step(t, q, dq, sensors) -> tau` (e.g. `rhi.control.NullSpaceController`)."""

    def step(self, t: float, q: np.ndarray, dq: np.ndarray, sensors: dict) -> np.ndarray:
        """Torques τ: (n,) [N m] at time t [s] from encoders q: (n,) [rad], dq: (n,) [rad/s] and the sensors."""


class ForceField(Protocol):
    """An environment or hand: the force on the handle."""

    def force(self, *args) -> np.ndarray:
        """The force on the handle: (m,) [N]."""


#: the log row's columns that `rhi.sim._compiled.io.log_row` writes, in its order, then the first scalar
_ROW_ARRAYS = ["q", "dq", "tau", "x", "xdot", "F_hand", "F_env", "ft", "work"]


def substeps(rate: float, timestep: float) -> int:
    """Physics steps per control period; the rate must be exact.

    Raises:
        InvalidInput: a non-finite or non-positive rate, or one the plant's timestep does not divide.
    """
    rate = scalar("rate", rate, positive=True)
    sub = round(1.0 / (rate * timestep))
    if sub < 1 or abs(sub * timestep * rate - 1.0) > 1e-9:
        ok = [round(1.0 / (k * timestep), 6) for k in (1, 2, 4, 5, 10)]
        raise InvalidInput(f"rate: {rate!r} Hz is not a whole number of plant timesteps ({timestep} s); "
                           f"use e.g. {', '.join(f'{r:g}' for r in ok)} Hz or change the plant's timestep")
    return sub


class Session:
    """A plant with its hand, physical environment and teleoperated slave, one control period at a time.

    Args:
        plant: the simulated device (already `reset` to its start).
        rate: control rate [Hz]; the plant's timestep must divide its period.
        hand: the user, `force(t, x, ẋ)`; None: no hand.
        physical: environment acting on the handle in the plant, `force(x, ẋ)`.
        teleop: a `Teleoperation` whose slave follows the master every period.

    Attributes:
        t: simulated time [s] (kept here: MuJoCo resets its own clock when the physics diverges).
        work: W = ∫ F_hᵀ ẋ dt so far [J] (eq. 5.15).
        F_hand: (m,) the hand's force during the last period [N].
        slave_x: (m_s,) the slave's position after the last period [m] (teleoperation).
        fault: why the session stopped (non-finite force, unstable physics), else None.
    """

    def __init__(self, plant: Plant, *, rate: float = 1000.0, hand=None, physical=None, teleop=None) -> None:
        if not isinstance(plant, Plant):
            raise InvalidInput(f"plant: expected an rhi.sim.Plant, got {type(plant).__name__}")
        for name, v, method in (("hand", hand, "force"), ("physical", physical, "force"), ("teleop", teleop, "follow")):
            if v is not None and not callable(getattr(v, method, None)):
                raise InvalidInput(f"{name}: expected None or an object with a `{method}` method, got {v!r:.60}")
        self.plant, self.hand, self.physical, self.teleop = plant, hand, physical, teleop
        self.sub = substeps(rate, plant.timestep)
        self.dt = self.sub * plant.timestep
        self.t = plant.time
        self.work = 0.0
        self.F_hand = np.zeros(plant.m)
        self.slave_x = np.zeros((0,)) if teleop is None else teleop.slave.x.copy()
        self.fault: str | None = None
        self._zero = np.zeros(plant.m)
        # the plant's persistent MjData views and indices (see `Plant.step`), fetched once
        p = plant
        self._mj = (p.model, p.data, p._sd, p._pos, p._vel, p._xfrc, p._task, p._wnum, *p._bad)
        # the compiled hand's buffers (`_steps_compiled`): its force, (work, timestep, add flag), sensor indices
        self._F = np.zeros(plant.m)
        self._acc = np.array([0.0, plant.timestep, 0.0])
        self._idx = np.concatenate([p._pos, p._vel, p._task]).astype(np.int64)
        self._fused: tuple[Any, np.ndarray] | None = None  # (rhi.sim._compiled.handle.hand_period, its constants)
        self._addr = (p.model._address, p.data._address)  # the C structs, for MuJoCo's step in compiled code
        self._badv = np.array(p._bad, dtype=np.int64)
        self._at = np.zeros(1, dtype=np.int64)
        self._fused_for: tuple = (None, None)
        fused = self._compiled(hand, physical)
        if fused is not None:
            # load (or compile) the kernel now, not in the first period of a real-time run: zero physics steps
            kernel, c = fused
            kernel(*self._addr, 0, self.t, p._sd, self._idx, c, self._F.copy(), p._xfrc.copy(), self._acc.copy(),
                   p._wnum, self._badv, self._at)

    def advance(self, tau: np.ndarray, x_master: np.ndarray | None = None) -> str | None:
        """Apply τ: (n,) [N m] for one control period; returns the fault that stopped it, if any.

        x_master: (m,) [m] the master position the teleoperated slave follows (the controller's FK).
        """
        if self.fault is not None:
            return self.fault
        # The torque is set once for the period, the handle force on the task axes at every physics step
        # (or zero), then mj_step2 + mj_step1 with the divergence check.
        self.plant.apply(tau)
        hand, phys = self.hand, self.physical
        fused = self._compiled(hand, phys)
        if fused is not None:
            fault = self._steps_compiled(*fused)
        else:
            fault = self._steps(hand, phys)
        if fault is not None:
            return self._stop(fault)
        self.t += self.dt
        if self.teleop is not None and x_master is not None:
            self.slave_x = self.teleop.follow(x_master, self.dt)
        return None

    def _steps(self, hand, phys) -> str | None:
        """The period's physics steps with any hand and physical environment (their `force` methods)."""
        h = self.plant.timestep
        model, data, sd, pos, vel, xfrc, task, wn, i, j, k = self._mj
        step1, step2 = mujoco.mj_step1, mujoco.mj_step2
        forces = hand is not None or phys is not None
        F_h = self._zero
        t0 = self.t
        work = self.work
        xdot = sd[vel] if forces else None  # index arrays: each read is a fresh array
        for s in range(self.sub):
            if forces:
                x = sd[pos]
                if hand is not None:
                    F_h = hand.force(t0 + s * h, x, xdot)
                    F = F_h + phys.force(x, xdot) if phys is not None else F_h
                else:
                    F = phys.force(x, xdot)
                if not math.isfinite(F.dot(F)):
                    self.work = work
                    return (f"hand/environment: non-finite force {np.asarray(F).tolist()} on the "
                            f"handle at t={t0 + s * h:.4f} s")
                xfrc[task] = F
            step2(model, data)
            step1(model, data)
            if wn[i] or wn[j] or wn[k]:
                self.work = work
                return str(unstable(t0 + s * h))
            if forces:
                xdot = sd[vel]  # the velocity after the step: the user's work, the next step's hand
                if hand is not None:
                    work += float(F_h.dot(xdot)) * h
        self.work = work
        self.F_hand = F_h
        return None

    def _compiled(self, hand, phys) -> tuple[Any, np.ndarray] | None:
        """The kernel of `_steps_compiled` and its constants where the kernels know the hand and the physical wall.

        A `Hand`, a `MinimumJerkPalpation` or a `HandSequence` of them and a `Wall` or none
        (`rhi.sim._compiled.handle.hand_supported`).
        None for other hands and environments, or a hand or wall of another dimension than the plant's
        (`_steps` raises their error).
        """
        if self._fused_for[0] is hand and self._fused_for[1] is phys:
            return self._fused
        from rhi.sim._compiled.handle import hand_constants, hand_period, hand_supported

        if not hand_supported(hand, phys, self.plant.m):
            return None
        self._fused = (hand_period, hand_constants(hand, phys, self.plant.m))
        self._fused_for = (hand, phys)
        return self._fused

    def _steps_compiled(self, kernel, c: np.ndarray) -> str | None:
        """`_steps` for a hand `_compiled` knows and a physical `Wall` (or none): one compiled call.

        The same arithmetic as the hand's `force` and `Wall.force` (`rhi.sim._compiled.handle.hand_period`), with the
        handle's state read from MuJoCo's sensors, the force written to its applied force and MuJoCo's step
        called from there.
        """
        p, F, acc = self.plant, self._F, self._acc
        acc[0], acc[2] = self.work, 0.0
        t0 = self.t
        status = kernel(*self._addr, self.sub, t0, p._sd, self._idx, c, F, p._xfrc, acc, p._wnum, self._badv, self._at)
        self.work = float(acc[0])
        if status != 0:  # not PERIOD_OK
            return self._fault(status, t0)
        self.F_hand = F.copy()
        return None

    def _fault(self, status: int, t0: float) -> str:
        """Why `rhi.sim._compiled.handle.hand_period` stopped a period that started at t0 [s] (its failed step in `_at`)."""
        from rhi.sim._compiled.handle import PERIOD_NONFINITE

        t = t0 + int(self._at[0]) * self.plant.timestep
        if status == PERIOD_NONFINITE:
            force = self.plant._xfrc[self.plant._task].tolist()
            return f"hand/environment: non-finite force {force} on the handle at t={t:.4f} s"
        return str(unstable(t))

    def _stop(self, why: str) -> str:
        self.fault = why
        return why


def simulate(
    plant: Plant,
    controller: Controller,
    *,
    duration: float,
    hand=None,
    virtual=None,
    physical=None,
    teleop=None,
    rate: float = 1000.0,
    progress: Callable[[int, int], None] | None = None,
    log=None,
    telemetry: Telemetry | None = None,
    record: Callable[[], dict] | Probe | None = None,
) -> Log:
    """Run the controller against the plant for `duration` seconds, as fast as the machine allows.

    Each tick the controller receives the encoders q, dq and the sensors
    {"ft": (6,) F/T reading, "force": (m,) virtual-environment force}; the virtual force is
    computed from the *controller's* model (FK of the measured q), as a haptic rendering loop
    does. Between ticks the plant advances `1/(rate·timestep)` physics steps with the
    hand and the physical environment re-evaluated at every step.

    A fault (the controller's safe stop, a non-finite force, unstable physics) ends the run with
    zero torque; the log keeps every tick up to it and `Log.fault` says why and when.

    Args:
        plant: the simulated device (already `reset` to its start).
        controller: `step(t, q, dq, sensors) -> tau` (n,) [N m].
        duration: simulated time [s] (at least one control period).
        hand: the user, `force(t, x, ẋ)` (e.g. `Hand`, `PushForce`); None: no hand.
        virtual: environment rendered by the controller, `force(x, ẋ)`; None: free space.
        physical: environment acting on the handle in the plant, `force(x, ẋ)` (e.g. a stop).
        teleop: a `Teleoperation` whose slave follows the master each tick.
        rate: control rate [Hz]; must be a whole number of plant timesteps per period.
        progress: callback(done, total) every 1 % of the ticks.
        log: a ``.rhilog`` path to stream the log to (bounded memory), or None (in memory).
        telemetry: a `Telemetry` that receives the newest tick (for a live view).
        record: called once per tick after the plant has advanced, returning ``{name: value}``
            of what else to log (e.g. a controller state the log has no column for); each name
            becomes ``Log.extra[name]`` of shape (N, *value.shape). Names must not change
            between ticks. A `rhi.sim.Probe` records the loop's own state and keeps the run on the
            compiled loop (`rhi.sim.probe`).

    Raises:
        InvalidInput: a bad duration or rate (named), a record name that is a log column or
            changes between ticks, or the controller's bad-input errors.
    """
    from rhi.sim._compiled.io import log_row

    sess = Session(plant, rate=rate, hand=hand, physical=physical, teleop=teleop)
    if scalar("duration", duration) < sess.dt * (1 - 1e-9):
        raise InvalidInput(f"duration: must be at least one control period ({sess.dt} s), got {duration!r}")
    N = int(round(duration / sess.dt))
    n, m = plant.n, plant.m
    dev = getattr(controller, "device", plant.device)
    ms = teleop.slave.m if teleop is not None else 0
    from rhi.sim._compiled import fast_loop, motors_off

    # the handle's kinematics: the virtual force, the slave's target, the compiled loop's intent estimator's ẋ
    handle = virtual is not None or teleop is not None or type(controller) is fast_loop.IntentController
    kin = Kinematics(dev, virtual) if handle else None
    columns = layout(n, m, ms)
    compiled = motors_off.MotorsOffLoop if type(controller) is ZeroTorque else fast_loop.FastLoop
    fast = compiled.build(sess, controller, kin, virtual=virtual, teleop=teleop, record=record, columns=columns)
    why = "" if fast is not None else (compiled.why_not(sess, controller, kin, virtual=virtual, teleop=teleop,
                                                        record=record) or "switched off")
    w = LogWriter(columns, log, meta={"device": dev.name, "task_axes": dev.task_axes, "rate": float(rate),
                                      "source": "simulate", "environment": describe(virtual),
                                      "route": fast.route if fast is not None else _route(why, controller)},
                  chunk=N if log is None else 200)
    c = w.cols
    # Row blocks (see `layout`): the arrays from q to ft (one compiled call, `_compiled.io.log_row`), the scalars
    # from work to alpha_pc, then seq, the timing columns and safety: one write each.
    names = [name for name, _ in w.columns]
    at = dict(zip(names, np.cumsum([0] + [width for _, width in w.columns]).tolist()))
    i_q, i_sc, i_seq = at["q"], at["work"], at["seq"]
    if (names[1:10], at["alpha_pc"] - i_sc, at["safety"] - i_seq) != (_ROW_ARRAYS, 6, 7):
        raise AssertionError(f"log layout changed: {w.columns}")  # pragma: no cover - a bug, not an input
    scalars, tail = slice(i_sc, i_sc + 7), slice(i_seq, i_seq + 8)
    slave = c.get("slave_x")
    zero_m = np.zeros(m)
    nan = math.nan
    every = max(1, N // 100)
    state = getattr(controller, "state", None)
    recorded = Recorded(c)
    hook = record.hook(controller, sess) if isinstance(record, Probe) else record
    if fast is not None:
        fast.recorded = recorded
    step = controller.step
    sd, xv = plant._sd, np.concatenate([plant._pos, plant._vel]).astype(np.int64)
    perf = time.perf_counter
    t_start = perf()

    def tick(k: int) -> bool:
        """Tick k in Python; whether the run ends there (a plant fault)."""
        t0 = perf()
        t = sess.t
        read = plant.sensors()
        q, dq, ft = read[:n], read[n:2 * n], read[2 * n:]
        x_m = None
        if kin is not None:
            x_m, xdot_m, F_env = kin.render(q, dq)
        else:
            F_env = zero_m
        t1 = perf()
        tau = np.asarray(step(t, q, dq, {"ft": ft, "force": F_env}), dtype=float)
        t2 = perf()
        if tau.shape != (n,):
            raise InvalidInput(f"controller: step returned torques of shape {tau.shape}, expected ({n},)")
        fault = sess.advance(tau, x_m)
        row = w.row()
        row[0] = t
        log_row(row, i_q, read, tau, sd, xv, sess.F_hand, F_env)
        if ms:
            row[slave] = sess.slave_x
        if state is not None:
            row[scalars] = (sess.work, state.V, state.omega, state.alpha, state.beta,
                            getattr(state, "E_obs", nan), getattr(state, "alpha_pc", nan))
            if state.stopped and w.fault is None:
                w.fault = state.fault
                w.event(t, "controller", state.fault or "controller stopped", k)
        else:
            row[i_sc] = sess.work
        t3 = perf()
        row[tail] = (k, t0 - t_start, t1 - t0, t2 - t1, t3 - t2, t3 - t0, 0.0, 0.0 if fault is None else 1.0)
        if hook is not None:
            recorded.tick(hook())
        if telemetry is not None:
            telemetry.publish(row, c, fault or w.fault)
        if fault is not None:
            w.fault = fault
            w.event(t, "plant", fault, k)
            return True
        if progress is not None and (k % every == 0 or k == N - 1):
            progress(k + 1, N)
        return False

    fast_loop.last = fast if isinstance(fast, fast_loop.FastLoop) else None
    motors_off.last = fast if isinstance(fast, motors_off.MotorsOffLoop) else None
    try:
        k = 0
        while k < N:
            if fast is not None and not (fast.stopped and w.fault is None):
                k, ended = _fast_block(fast, w, k, N, t_start, telemetry, progress, every)
                if ended or k == N:
                    break
            if tick(k):
                break
            k += 1
    finally:
        w.close()
    out = w.to_log()
    out.extra = recorded.arrays()
    return out


def _route(why: str, controller) -> str:
    """The log's ``route`` of a run on the Python loop: why, and the controller's route."""
    route = getattr(controller, "route", None)
    return f"python loop ({why})" + ("" if route is None or why.endswith(str(route)) else f"; controller: {route}")


def _fast_block(fast, w: LogWriter, k: int, N: int, t_start: float, telemetry, progress, every: int) -> tuple[int, bool]:
    """Ticks from k in compiled calls (`rhi.sim._compiled.fast_loop`) until the end, a fault or a tick for Python.

    Returns (the next tick, whether the run ended at a fault). Timing columns: each call's average per tick.
    """
    c, perf = w.cols, time.perf_counter
    i_wall, i_read, i_tick = int(c["wall"]), int(c["t_read"]), int(c["t_tick"])  # type: ignore[arg-type]
    from rhi.sim._compiled.fast_loop import FAULT, PYTHON

    while k < N:
        rows = w.block(min(N - k, 1000))
        t0 = perf()
        done, out = fast.run(k, rows)
        dt = (perf() - t0) / max(done, 1)
        w.commit(done)
        block = rows[:done]
        block[:, i_wall] = (t0 - t_start) + dt * np.arange(done)
        block[:, i_read:i_read + 3] = math.nan
        block[:, i_tick] = dt
        fault, prior = fast.sess.fault, w.fault
        if out == FAULT:
            w.fault = fault
            w.event(block[-1, 0], "plant", fault, k + done - 1)
        if telemetry is not None:  # as the Python loop: the plant's fault on its tick, else the run's (controller)
            for r in range(done):
                telemetry.publish(block[r], c, fault if out == FAULT and r == done - 1 else prior)
        if progress is not None:
            for kk in range(k, k + done):
                if kk % every == 0 or kk == N - 1:
                    progress(kk + 1, N)
        k += done
        if out == FAULT:
            return k, True
        if out == PYTHON:
            return k, False
    return k, False


class Kinematics:
    """The handle position and velocity on the controller's model, from the encoders, and the virtual force.

    What a haptic rendering loop computes before its controller runs, leaving the device's
    `terms` snapshot untouched: for trees of one-DoF revolute/prismatic joints one compiled call
    (`rhi.sim._compiled.handle`, on the constants of `rhi.devices.batch.pack`), which also evaluates a
    virtual `Wall`, `Fixture` or a `compose` of them; otherwise one Pinocchio forward-kinematics pass
    with velocities on a `pin.Data` of its own. Equal to `Device.fk(q)`, `Device.terms(q, dq).xdot` and
    `virtual.force` (to rounding).

    Args:
        device: the controller's device.
        virtual: the virtual environment `render` evaluates, `force(x, ẋ)`; None: free space.
    """

    def __init__(self, device, virtual=None) -> None:
        self.model = device.model
        self.frame = device.model.getFrameId(device.ee_frame)
        self.rows = np.array(device.task_rows)
        self.A = np.ascontiguousarray(device.A, dtype=float)
        self.b = np.ascontiguousarray(device.b, dtype=float)
        self.m = len(self.rows)
        self.virtual = virtual
        self._compiled = None
        self._fused = False  # the compiled call evaluates the virtual wall too
        if batch.supported(self.model):
            from rhi.sim._compiled.handle import env_constants, handle_state

            ints, joints, consts = batch.pack(self.model, self.frame)
            fc = [consts[:12], self.b, self.A.ravel()]
            env = None if virtual is None else env_constants(virtual, self.m)
            self._fused = env is not None
            if env is not None:
                fc.append(np.array(env))
            self._compiled = (handle_state, np.concatenate([ints, self.rows]).astype(np.int64), joints,
                              np.concatenate(fc))
            # load (or compile) the kernel now, not in a real-time loop's first tick: one call at q = 0
            zero = np.zeros(device.n)
            handle_state(*self._compiled[1:], zero, zero, np.empty((3 if self._fused else 2, self.m)))
        else:
            self.data = device.model.createData()

    def __call__(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x: (m,) [m] and ẋ: (m,) [m/s] at motor angles q: (n,) [rad] and velocities dq: (n,) [rad/s]."""
        if self._compiled is not None:
            kernel, ints, joints, fc = self._compiled
            out = np.empty((2, self.m))
            kernel(ints, joints, fc, q, dq, out)
            return out[0], out[1]
        model, data, f, A, rows = self.model, self.data, self.frame, self.A, self.rows
        pin.forwardKinematics(model, data, A.dot(q) + self.b, A.dot(dq))
        x = pin.updateFramePlacement(model, data, f).translation[rows]
        return x, pin.getFrameVelocity(model, data, f, pin.LOCAL_WORLD_ALIGNED).linear[rows]

    def render(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """x: (m,) [m], ẋ: (m,) [m/s] and the virtual environment's force on the handle: (m,) [N] (zero without one)."""
        if self._fused and self._compiled is not None:
            kernel, ints, joints, fc = self._compiled
            out = np.empty((3, self.m))
            kernel(ints, joints, fc, q, dq, out)
            return out[0], out[1], out[2]
        x, xdot = self(q, dq)
        return x, xdot, np.zeros(self.m) if self.virtual is None else self.virtual.force(x, xdot)
