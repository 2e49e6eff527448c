"""`run`: a controller against a device link at a fixed rate, behind the safety layer.

Ticks start at absolute deadlines t₀ + k/rate on the monotonic clock, so the rate does not
drift; a tick that ends after its successor's deadline is a missed deadline, and the slots it
overran are skipped rather than run in a burst. Garbage collection is frozen and disabled for
the run. Each tick: read → virtual environment → safety check → controller → safety filter
(clamp) → write → log row; the steps from the reading to the torque are `rhi.runtime.step`'s (one compiled call
where it can). A fault writes zero torque with the motors disabled, latched.
"""

from __future__ import annotations

import array
import contextlib
import dataclasses
import math
import os
import signal
import threading
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from rhi._lifetime import STOP_SIGNALS
from rhi._validate import MAX_DURATION, scalar
from rhi.errors import InvalidInput, LinkError
from rhi.runtime.link import DeviceLink, Status
from rhi.runtime.realtime import check_realtime, realtime_thread, spin_rest, wait_until
from rhi.runtime.safety import Safety, SafetyConfig
from rhi.runtime.step import make_step
from rhi.sim.environment import describe
from rhi.sim.log import TIMING, Log, LogWriter, layout, nan_stats
from rhi.sim.loop import Kinematics
from rhi.sim.telemetry import TelemetrySink

nan = math.nan


@dataclasses.dataclass
class RunResult:
    """What `run` returns.

    Attributes:
        log: the per-tick log (streamed to disk when a path was given).
        summary: JSON-serialisable statistics: ticks, rate, the rate reached [Hz], missed deadlines (count and %),
            skipped device readings (a link's readings superseded before a tick took them), p50/p99/p99.9/max of
            the tick time, of the read→write latency (reading in hand to command sent) and of the readings'
            round-trip age (`Reading.age`, where the link measures it) [s], clamp count, fault, every safety event,
            the controller tick's ``route`` (`rhi.control.compiled.Route`; None for a controller without one), the
            ``step``'s route (`rhi.runtime.step`: "compiled", or "python: why").
    """

    log: Log
    summary: dict

    @property
    def fault(self) -> str | None:
        """Why the run stopped (the log's fault), or None."""
        return self.log.fault

    @property
    def exit_code(self) -> int:
        """A command's exit status for this run: 0, 128 + the signal that e-stopped it (the shell's code), else 1."""
        if self.fault is None:
            return 0
        signals = [sig for sig in ESTOP_SIGNALS if self.summary.get("fault_kind") == "estop"
                   and self.fault.endswith(sig.name)]
        return 128 + int(signals[0]) if signals else 1


def run(
    link: DeviceLink,
    controller,
    *,
    rate: float = 1000.0,
    duration: float | None = None,
    safety: SafetyConfig | Safety | None = None,
    log=None,
    virtual=None,
    telemetry: TelemetrySink | None = None,
    realtime: bool = True,
    stop_on_fault: bool = True,
    cpu: int | None = None,
    priority: int | None = None,
    spin: bool = False,
    cpu_latency: float | None = None,
    progress: Callable[[dict], None] | None = None,
    until: threading.Event | None = None,
) -> RunResult:
    """Run `controller` against `link` at `rate` until `duration` has passed, a fault, or an e-stop.

    Args:
        link: the device (`SimLink`, `UDPLink`, or any `DeviceLink`), not yet opened.
        controller: `step(t, q, dq, sensors) -> tau`; its `device` is the model the safety layer and the
            virtual environment use (a controller without one needs `safety=Safety(device, ...)`); an optional
            `warmup()` runs before the link opens (e.g. loads compiled code).
        rate: control rate [Hz].
        duration: run time [s] (device time when `realtime=False`); None: until a fault or an e-stop.
        safety: limits (`SafetyConfig`) or a ready `Safety` (e.g. to call `estop`/`reset` from another thread).
        log: a ``.rhilog`` path to stream the log to (bounded memory), or None (in memory).
        virtual: environment rendered from the controller's model, `force(x, ẋ)`; its force goes to
            the controller as sensors["force"].
        telemetry: receives the newest tick for a live view (never blocks the loop).
        realtime: pace ticks on the wall clock; False: as fast as the link answers.
        stop_on_fault: end the run at the first fault (after commanding zero torque); False: keep
            ticking with zero torque until `Safety.reset` or the end.
        cpu: pin the loop to this CPU (a clear warning where the OS refuses).
        priority: SCHED_FIFO priority (1–99) (a clear warning where the OS refuses).
        spin: wait for each deadline on a busy core instead of asleep (`wait_until`): steadier, shorter ticks
            for one core at 100 % (pair with `cpu`).
        cpu_latency: ask Linux to keep every core's wake-up under this [s] for the run (PM QoS; 0: no deep idle
            state, whose wake-up flushes the caches a tick runs from; needs root, a clear warning otherwise).
        progress: called about twice a second with a status dict (rate, misses, max |τ|/limit, V, fault).
        until: an event that ends the run when set (not a fault), e.g. from the thread of a study's pages.

    Returns:
        `RunResult` with the log and a summary.

    Raises:
        InvalidInput: a bad rate or duration (named), a controller without a device and no `Safety`.
    """
    _check_run_arguments(link, controller, safety, log, virtual, telemetry, progress,
                         realtime=realtime, stop_on_fault=stop_on_fault, spin=spin)
    rate = scalar("rate", rate, positive=True)
    link_rate = getattr(link, "rate", None)
    if link_rate is not None and abs(link_rate - rate) > 1e-9 * rate:
        raise InvalidInput(f"rate: {rate!r} Hz differs from the link's {link_rate!r} Hz")
    if duration is not None and not 1.0 / rate <= scalar("duration", duration) <= MAX_DURATION:
        raise InvalidInput(f"duration: must be between one period ({1.0 / rate} s) and {MAX_DURATION:g} s, or None "
                           f"(until a fault or an e-stop), got {duration!r}")
    check_realtime(cpu, priority, cpu_latency)
    dev = getattr(controller, "device", None)
    if isinstance(safety, Safety):
        guard = safety
    elif dev is None:
        raise InvalidInput("safety: the controller has no `device`; pass safety=Safety(device, config)")
    else:
        guard = Safety(dev, safety)
    n = guard.n
    if (getattr(link, "n", 0) or n) != n:  # a device process (UDPLink) tells its motors once connected
        raise InvalidInput(f"link: the device has {link.n} motors, the controller's model {n}")
    m = dev.m if dev is not None else 0
    period = 1.0 / rate
    N = None if duration is None else int(round(duration * rate))
    ms = int(getattr(link, "slave_m", 0))  # a teleoperated slave's end effector (`rhi.runtime.teleoperated`)
    route = None if getattr(controller, "route", None) is None else str(controller.route)  # the tick's route
    w = LogWriter(layout(n, m, ms), log, meta={"device": getattr(dev, "name", "?"),
                                                "task_axes": getattr(dev, "task_axes", None), "rate": float(rate),
                                                "source": type(link).__name__, "realtime": bool(realtime),
                                                "spin": bool(spin), "cpu_latency": cpu_latency,
                                                "environment": describe(virtual), "route": route})
    c = w.cols
    at = _offsets(w, n, m)
    state = getattr(controller, "state", None)
    zero = np.zeros(n)
    zero_m = np.zeros(m)
    # the handle's x and ẋ on the controller's model and the virtual force: one compiled call where it can
    kin = None if dev is None else Kinematics(dev, virtual)
    step = make_step(guard, kin, controller)  # read → torque: one compiled call where it can (`rhi.runtime.step`)
    top = 0.0  # the largest τ_i / limit_i so far (`Safety.ratio`)
    stats = {"ticks": 0, "missed": 0, "skipped_slots": 0, "max_torque_ratio": 0.0}
    previous = _estop_on_signals(guard)
    k = slot = 0
    t_dev = 0.0  # device time of the last reading [s] (0 before the first)
    t_last = -math.inf
    last_seq = None
    ages = array.array("d")  # round-trip age of each new reading [s]
    warmup = getattr(controller, "warmup", None)
    if warmup is not None:  # compiled kernels loaded before the link opens (its watchdog runs from then on)
        warmup()
    try:
        with realtime_thread(cpu, priority, cpu_latency) as notes:
            link.open()
            if link.n != n:
                raise InvalidInput(f"link: the device has {link.n} motors, the controller's model {n}")
            _check_sensors(link, controller)
            step.attach(link)
            for msg in notes:
                w.event(0.0, "info", msg)
            rest = spin_rest(spin)
            t0 = time.monotonic()
            next_report = t0 + 0.5
            while (N is None or (slot if realtime else k) < N) and not (until is not None and until.is_set()):
                deadline = t0 + slot * period
                if realtime:
                    wait_until(deadline, spin, rest)
                ts = time.monotonic()
                tau, xdot, F_env, r = zero, None, zero_m, None
                try:
                    r = link.read()
                except LinkError as exc:
                    guard.trip(getattr(exc, "kind", "link"), _link_reason(exc))
                tr = time.monotonic()
                if r is not None:
                    if r.seq != last_seq:
                        last_seq = r.seq
                        ages.append(r.age)
                    if t_last <= r.t < math.inf:  # the log's time never runs backwards (`Safety.check` trips)
                        t_dev = t_last = r.t
                    tau, xdot, F_env = step(r, tr if realtime or r.arrival is not None else None)
                tc = time.monotonic()
                ok = guard.fault is None
                if not ok:
                    tau = zero
                try:
                    link.write(tau, enable=ok)
                except LinkError as exc:
                    guard.trip(getattr(exc, "kind", "link"), _link_reason(exc))
                te = time.monotonic()
                row = w.row()
                row[0] = t_dev
                row[at.tau:at.tau + n] = tau
                if r is not None:
                    _reading_row(row, at, r, xdot, n, m)
                row[at.F_env:at.F_env + m] = F_env
                if state is not None:
                    row[at.V:at.V + 6] = (state.V, state.omega, state.alpha, state.beta,
                                          getattr(state, "E_obs", nan), getattr(state, "alpha_pc", nan))
                row[at.seq:at.seq + 8] = (nan if r is None else r.seq, ts - t0, tr - ts, tc - tr, te - tc, te - ts,
                                          ts - deadline if realtime else 0.0, 0.0 if ok else 1.0)
                if ok and r is not None and guard.ratio > top:
                    top = stats["max_torque_ratio"] = guard.ratio
                if guard.events:
                    for kind, detail in guard.drain():
                        w.event(t_dev, kind, detail, k)
                if not ok and w.fault is None:
                    w.fault = guard.fault
                if telemetry is not None:
                    telemetry.publish(row, c, guard.fault)
                k += 1
                slot += 1
                if realtime:
                    now = time.monotonic()
                    if now > t0 + slot * period:
                        stats["missed"] += 1
                        behind = int((now - t0) / period) - slot + 1
                        stats["skipped_slots"] += behind
                        slot += behind
                    if progress is not None and now >= next_report:
                        next_report = now + 0.5
                        progress(_status(k, slot, stats, state, guard, t_dev))
                elif progress is not None and k % 500 == 0:
                    progress(_status(k, slot, stats, state, guard, t_dev))
                if not ok and stop_on_fault:
                    break
    finally:
        step.close()
        for _ in range(3):  # zero torque, motors disabled; repeated against a lost packet
            with contextlib.suppress(Exception):
                link.write(zero, enable=False)
        with contextlib.suppress(Exception):
            link.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for kind, detail in guard.drain():
            w.event(t_dev, kind, detail, k)
        if w.fault is None and guard.fault is not None:
            w.fault = guard.fault
        w.close()
    stats["ticks"] = k
    stats["skipped_readings"] = int(getattr(link, "stats", {}).get("skipped", 0))
    result_log = w.to_log()
    summary = _summary(result_log, stats, rate, guard, realtime, spin)
    summary["route"] = route
    summary["step"] = step.route
    summary["round_trip"] = nan_stats(np.frombuffer(ages, dtype=float) if len(ages) else np.zeros(0))
    return RunResult(result_log, summary)



def _link_reason(exc: LinkError) -> str:
    """The fault reason of a link's error: its message, which names the link once."""
    msg = str(exc)
    return msg if msg.startswith("link:") else f"link: {msg}"

def _check_sensors(link: DeviceLink, controller) -> None:
    """At connect: the device reports every sensor the controller needs (`required_sensors`), at its width.

    Raises:
        LinkError: a missing sensor or a wrong width, naming both (the link is closed by `run`).
    """
    have = getattr(link, "sensors", None)
    need = getattr(controller, "required_sensors", None)
    if have is None or need is None:  # a local link (its readings are checked by the controller) or no needs
        return
    have = dict(have)
    for name, width in need().items():
        if name not in have:
            raise LinkError(f"sensors: the configuration's controller needs {name!r} ({width} floats) but the device "
                            f"reports only {sorted(have) or 'none'} (docs/protocol.md, INFO)")
        if width is not None and have[name] != width:
            raise LinkError(f"sensors: the device's {name!r} has {have[name]} floats, the controller needs {width}")


def _check_run_arguments(link, controller, safety, log, virtual, telemetry, progress, **flags: bool) -> None:
    """The objects `run` is given must be what it uses (InvalidInput naming the argument)."""
    for name, obj, methods in (("link", link, ("open", "read", "write", "close")), ("controller", controller, ("step",)),
                               ("virtual", virtual, ("force",)), ("telemetry", telemetry, ("publish",))):
        if (obj is not None or name in ("link", "controller")) and not all(
                callable(getattr(obj, mth, None)) for mth in methods):
            raise InvalidInput(f"{name}: expected an object with {', '.join(f'`{mth}`' for mth in methods)}, "
                               f"got {obj!r:.60}")
    if safety is not None and not isinstance(safety, (SafetyConfig, Safety)):
        raise InvalidInput(f"safety: expected a SafetyConfig, a Safety or None, got {safety!r:.60}")
    if log is not None and not isinstance(log, (str, os.PathLike)):
        raise InvalidInput(f"log: expected a .rhilog path or None, got {log!r:.60}")
    if progress is not None and not callable(progress):
        raise InvalidInput(f"progress: expected a callable or None, got {progress!r:.60}")
    for name, v in flags.items():
        if not isinstance(v, bool):
            raise InvalidInput(f"{name}: expected True or False, got {v!r:.60}")


#: The signals that stop a run as an e-stop (Ctrl-C; `kill`, systemd and Docker; a closed terminal).
ESTOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


def _estop_on_signals(guard: Safety) -> dict:
    """Make `ESTOP_SIGNALS` an e-stop of `guard` (from the main thread only); {signal: previous handler}.

    A stop signal the command received before (`rhi._lifetime.STOP_SIGNALS`) is an e-stop at once, in any thread.
    """
    if STOP_SIGNALS:
        guard.estop(STOP_SIGNALS[0])
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.signal(sig, lambda num, _frame: guard.estop(signal.Signals(num).name)) for sig in ESTOP_SIGNALS}


class _Offsets(NamedTuple):
    """Where a log row's columns start (`rhi.sim.log.layout`): the loop writes contiguous blocks at once."""

    q: int
    tau: int
    x: int
    F_hand: int
    F_env: int
    ft: int
    work: int
    V: int
    slave_x: int
    seq: int


def _offsets(w: LogWriter, n: int, m: int) -> _Offsets:
    names = [name for name, _ in w.columns]
    start = dict(zip(names, np.cumsum([0] + [width for _, width in w.columns]).tolist()))
    at = _Offsets(*(start.get(f, -1) for f in _Offsets._fields))
    # the blocks written at once: q|q̇, x|ẋ, V..α_pc, seq..safety
    if (at.tau - at.q, at.F_hand - at.x, start["alpha_pc"] - at.V, start["safety"] - at.seq) != (2 * n, 2 * m, 5, 7):
        raise AssertionError(f"log layout changed: {w.columns}")  # pragma: no cover - a bug, not an input
    return at


def _reading_row(row: np.ndarray, at: _Offsets, r, xdot: np.ndarray | None, n: int, m: int) -> None:
    """Write what the reading carries into the log row: q, q̇, F/T, the simulation's ground truth, the slave."""
    row[at.q:at.q + n] = r.q
    row[at.q + n:at.q + 2 * n] = r.dq
    s = r.sensors
    if "ft" in s:
        row[at.ft:at.ft + 6] = s["ft"]
    if "x" in s:  # ground truth (docs/protocol.md: a simulated device), else ẋ from the encoders
        row[at.x:at.x + m] = s["x"]
    if "xdot" in s:
        row[at.x + m:at.x + 2 * m] = s["xdot"]
    elif "x" not in s and xdot is not None:
        row[at.x + m:at.x + 2 * m] = xdot
    if "F_hand" in s:
        row[at.F_hand:at.F_hand + m] = s["F_hand"]
    if "work" in s:
        row[at.work] = s["work"][0]
    if at.slave_x >= 0 and "slave_x" in s:
        row[at.slave_x:at.slave_x + len(s["slave_x"])] = s["slave_x"]


def _status(k: int, slot: int, stats: dict, state, guard: Safety, t: float) -> dict:
    return {"t": t, "ticks": k, "missed": stats["missed"], "max_torque_ratio": stats["max_torque_ratio"],
            "V": getattr(state, "V", math.nan), "fault": guard.fault}


def _summary(log: Log, stats: dict, rate: float, guard: Safety, realtime: bool, spin: bool) -> dict:
    k = max(stats["ticks"], 1)

    def timing(name: str) -> np.ndarray:
        v = getattr(log, name)
        return v if v is not None and len(log) else np.zeros(0)

    lat = timing("t_step") + timing("t_write")  # reading in hand → command sent
    out = {
        "rate": rate, "realtime": realtime, "spin": spin, "ticks": stats["ticks"],
        "duration": float(timing("wall")[-1]) if len(log) else 0.0,
        "missed": stats["missed"], "missed_pct": 100.0 * stats["missed"] / k,
        "skipped_slots": stats["skipped_slots"], "skipped_readings": stats["skipped_readings"],
        "skipped_readings_pct": 100.0 * stats["skipped_readings"] / (stats["skipped_readings"] + k),
        "tick": nan_stats(timing("t_tick")), "read_to_write": nan_stats(lat),
        "late": nan_stats(timing("late")),
        "clamped": guard.clamped, "max_torque_ratio": stats["max_torque_ratio"],
        "fault": log.fault, "fault_kind": guard.fault_kind,
        "events": [dataclasses.asdict(e) for e in log.events],
    }
    for name in TIMING[1:5]:
        out[name] = nan_stats(getattr(log, name) if len(log) else [])
    out["rate_reached"] = stats["ticks"] / out["duration"] if out["duration"] > 0 else math.nan
    return out


__all__ = ["RunResult", "Status", "run"]
