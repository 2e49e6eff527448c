"""rhi.runtime: the fixed-rate loop over SimLink, the safety layer under fault injection, the streamed log."""

from __future__ import annotations

import os
import signal
import threading
import time
import warnings

import numpy as np
import pytest

import rhi
from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
from rhi.errors import InvalidInput
from rhi.runtime import Reading, Safety, SafetyConfig, SimLink, Telemetry, run
from rhi.runtime.inject import Inject
from rhi.sim import Hand, HandPath, Log, Plant, PushForce, Wall, simulate, stop

Q0 = np.array([-0.63, 0.25, 0.28, 0.09])


@pytest.fixture(scope="module")
def dev():
    return rhi.device("rhi4")


def _scenario(dev):
    """The README's palpation: a hand pushing into a rendered 1000 N/m wall, a rigid stop behind it."""
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    ctrl = NullSpaceController(dev, ControllerConfig(primary=ForceRendering(), saturation="ascm"))
    hand = Hand(HandPath([x0, x0 + [0, 0.05]], speed=0.05))
    wall = Wall(x0 + [0, 0.01], normal=[0, 1], stiffness=1000.0)
    return plant, ctrl, hand, wall, stop(x0 + [0, 0.03], [0, 1])


def _sim_run(dev, duration=0.6, link_wrap=None, **kw):
    plant, ctrl, hand, wall, phys = _scenario(dev)
    link = SimLink(plant, hand=hand, physical=phys)
    if link_wrap is not None:
        link = link_wrap(link)
    return run(link, kw.pop("controller", ctrl), duration=duration, virtual=wall, realtime=False, **kw)


def test_simlink_equals_simulate(dev):
    plant, ctrl, hand, wall, phys = _scenario(dev)
    ref = simulate(plant, ctrl, duration=0.6, hand=hand, virtual=wall, physical=phys)
    res = _sim_run(dev)
    assert res.fault is None and ref.fault is None
    assert len(res.log) == len(ref) == 600
    np.testing.assert_allclose(res.log.tau, ref.tau, atol=1e-9, rtol=0)
    np.testing.assert_allclose(res.log.q, ref.q, atol=1e-12, rtol=0)
    assert np.abs(ref.tau).max() > 0.05  # the scenario renders a real force
    s = res.summary
    assert s["ticks"] == 600 and s["clamped"] == 0 and s["fault"] is None
    assert 0 < s["tick"]["p50"] <= s["tick"]["p99"] <= s["tick"]["max"]


@pytest.mark.realtime
def test_realtime_log_streams_and_is_readable_while_running(dev, tmp_path):
    path = tmp_path / "run.rhilog"
    tel = Telemetry(every=5)
    out = {}
    th = threading.Thread(target=lambda: out.setdefault("res", _realtime(dev, path, tel)))
    th.start()
    mid, running = None, False
    while th.is_alive():  # read the file while the run goes on, once its first chunk is on disk
        if path.exists():
            mid, running = Log.load(path), th.is_alive()
            if len(mid):
                break
        time.sleep(0.02)
    snap = tel.latest()
    th.join()
    res = out["res"]
    assert running and 0 < len(mid) < len(res.log)
    assert snap is not None and snap.q.shape == (4,) and snap.safety == "ok"
    assert res.summary["ticks"] >= 0.5 * 800  # 0.8 s at 1 kHz (a loaded machine skips slots)
    assert res.summary["late"]["p50"] < 1e-3
    full = Log.load(path)
    np.testing.assert_array_equal(full.tau, res.log.tau)
    assert np.all(np.diff(full.wall) > 0)


def _realtime(dev, path, tel):
    plant, ctrl, hand, wall, phys = _scenario(dev)
    return run(SimLink(plant, hand=hand, physical=phys), ctrl, duration=0.8, virtual=wall, log=path, telemetry=tel)


def _assert_safe_stop(res, kind, t_min, t_max):
    log = res.log
    assert res.summary["fault_kind"] == kind, res.summary["fault"]
    assert res.fault and log.safety[-1] == 1
    np.testing.assert_array_equal(log.tau[-1], 0.0)
    t_fault = log.t[np.argmax(log.safety == 1)]
    assert t_min <= t_fault <= t_max, (t_fault, res.fault)
    assert any(e.kind == kind for e in log.events)


@pytest.mark.parametrize("window", [(0.3, 0.4), (0.3, 0.8)])
def test_frozen_sensors_fault(dev, window, tmp_path):
    res = _sim_run(dev, link_wrap=lambda k: Inject(k, freeze=window), log=tmp_path / "f.rhilog")
    _assert_safe_stop(res, "stale", 0.3, 0.305)
    again = Log.load(tmp_path / "f.rhilog")  # the log survives the fault, complete
    assert len(again) == len(res.log) and again.fault == res.fault


def test_frozen_values_with_advancing_sequence_numbers_fault(dev, tmp_path):
    """Issue 24's fault 2: the values stop while the sequence numbers advance (the frozen-sensor rule)."""
    res = _sim_run(dev, link_wrap=lambda k: Inject(k, frozen=(0.3, 0.6)), log=tmp_path / "f.rhilog")
    ticks = SafetyConfig().frozen_ticks
    _assert_safe_stop(res, "frozen", 0.3 + ticks * 1e-3, 0.3 + (ticks + 1) * 1e-3)
    assert Log.load(tmp_path / "f.rhilog").fault == res.fault
    # configurable: a longer window of identical readings before the rule applies
    res = _sim_run(dev, link_wrap=lambda k: Inject(k, frozen=(0.3, 0.6)), safety=SafetyConfig(frozen_ticks=200))
    _assert_safe_stop(res, "frozen", 0.5, 0.502)


def test_frozen_sensor_rule_cannot_fire_at_rest(dev):
    """A device at rest (zero velocity, a noisy or a constant F/T) never trips the rule; frozen values in motion do."""
    rng = np.random.default_rng(0)
    safety = Safety(dev, SafetyConfig(frozen_ticks=5))
    for k in range(200):  # at rest: positions and velocities unchanged, a real F/T sensor's noise
        r = Reading(seq=k, t=k * 1e-3, q=Q0, dq=np.zeros(4), sensors={"ft": 1e-3 * rng.standard_normal(6)})
        assert safety.check(r, None), safety.fault
    for k in range(200, 400):  # a simulated sensor without contact reads exact zeros
        assert safety.check(Reading(seq=k, t=k * 1e-3, q=Q0, dq=np.zeros(4), sensors={"ft": np.zeros(6)}), None)
    ft = np.array([0.1, 0.2, 0.0, 0.0, 0.0, 0.01])
    for k in range(400, 406):  # the same non-zero wrench bit for bit at rest: not a fault (a simulated sensor)
        assert safety.check(Reading(seq=k, t=k * 1e-3, q=Q0, dq=np.zeros(4), sensors={"ft": ft}), None)
    for k in range(406, 412):  # ... while the joints move: frozen
        safety.check(Reading(seq=k, t=k * 1e-3, q=Q0 + 1e-4 * k, dq=np.full(4, 0.1), sensors={"ft": ft}), None)
    assert safety.fault_kind == "frozen" and "force/torque" in safety.fault
    safety = Safety(dev, SafetyConfig(frozen_ticks=5, frozen_motion=1e-3))
    for k in range(6):  # 0.5 rad/s for 5 ms: 2.5 mrad implied, positions unchanged
        safety.check(Reading(seq=k, t=k * 1e-3, q=Q0, dq=np.array([0.5, 0, 0, 0]), sensors={}), None)
    assert safety.fault_kind == "frozen" and "encoders" in safety.fault
    with pytest.raises(InvalidInput, match="frozen_ticks"):
        SafetyConfig(frozen_ticks=0)
    with pytest.raises(InvalidInput, match="frozen_motion"):
        SafetyConfig(frozen_motion=float("nan"))


def test_nan_reading_fault(dev):
    _assert_safe_stop(_sim_run(dev, link_wrap=lambda k: Inject(k, nan=(0.2, 0.3))), "nan", 0.2, 0.201)


def test_out_of_order_reading_fault(dev):
    _assert_safe_stop(_sim_run(dev, link_wrap=lambda k: Inject(k, reorder_at=0.25)), "order", 0.247, 0.251)


def test_link_lost_fault(dev):
    _assert_safe_stop(_sim_run(dev, link_wrap=lambda k: Inject(k, silence=(0.1, 0.5))), "link", 0.0, 0.1)



def test_safety_check_finite_readings_exactly(dev):
    """Sums over the readings decide fast; an overflowing sum of finite values is no fault, ±inf that cancel are."""
    q = np.clip(Q0, dev.q_min, dev.q_max)

    def check(dq=None, **sensors):
        guard = Safety(dev, SafetyConfig(max_joint_speed=1e300, max_handle_speed=1e300))
        dq = np.zeros(4) if dq is None else dq
        ok = guard.check(Reading(0.1, 1, q, dq, {"ft": np.zeros(6), **sensors}), None, np.zeros(2))
        return ok, guard.fault_kind

    assert check() == (True, None)
    assert check(big=np.array([1e308, 1e308]), grid=np.full((2, 2), 1e308)) == (True, None)  # finite: no fault
    assert check(x=np.array([np.inf, -np.inf])) == (False, "nan")  # the sum is NaN
    assert check(grid=np.array([[0.0, np.nan], [1.0, 2.0]])) == (False, "nan")
    assert check(dq=np.array([np.inf, -np.inf, 0.0, 0.0])) == (False, "nan")
    assert check(dq=np.array([1e300, 1e300, 0.0, 0.0])) == (True, None)

class _NaNHand:
    def __init__(self, at):
        self.at = at

    def force(self, t, x, xdot):
        return np.full(2, np.nan) if t >= self.at else np.zeros(2)


class _Kick:
    """A hand that hits the handle with an absurd force: the physics diverges."""

    def force(self, t, x, xdot):
        return np.array([0.0, 1e25]) if t >= 0.35 else np.zeros(2)


@pytest.mark.parametrize("hand", [_NaNHand(0.5), _Kick()])
def test_plant_fault_keeps_log_and_time(dev, hand):
    plant, ctrl, *_ = _scenario(dev)
    log = simulate(plant, ctrl, duration=1.0, hand=hand)
    assert log.fault is not None and len(log) > 300
    assert log.t[-1] >= 0.34, log.fault  # MuJoCo's reset must not rewind the reported time
    plant, ctrl, *_ = _scenario(dev)
    res = run(SimLink(plant, hand=hand), ctrl, duration=1.0, realtime=False)
    assert res.summary["fault_kind"] == "device" and res.log.t[-1] >= 0.34
    np.testing.assert_array_equal(res.log.tau[-1], 0.0)


def test_controller_raising_is_a_fault(dev):
    class Boom:
        device = dev

        def step(self, t, q, dq, sensors):
            if t > 0.05:
                raise RuntimeError("division by zero in a user objective")
            return np.zeros(4)

    _assert_safe_stop(_sim_run(dev, controller=Boom()), "controller", 0.05, 0.052)


@pytest.mark.realtime
def test_estop_method_and_sigint(dev):
    guard = Safety(dev)

    class Stopper:
        device = dev

        def step(self, t, q, dq, sensors):
            if t >= 0.1:
                guard.estop("operator pressed the button")
            return np.zeros(4)

    _assert_safe_stop(_sim_run(dev, controller=Stopper(), safety=guard), "estop", 0.1, 0.102)
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # Ctrl-C, `kill` (systemd, Docker), a closed terminal
        plant, ctrl, hand, wall, phys = _scenario(dev)
        before = signal.getsignal(sig)
        threading.Timer(0.2, lambda sig=sig: os.kill(os.getpid(), sig)).start()
        res = run(SimLink(plant, hand=hand), ctrl, duration=2.0)
        assert res.summary["fault_kind"] == "estop" and res.fault.endswith(sig.name)
        assert res.log.wall[-1] < 1.0 and signal.getsignal(sig) is before
        np.testing.assert_array_equal(res.log.tau[-1], 0.0)


def test_a_stop_signal_whose_interrupt_was_lost_stops_the_next_run(dev):
    """A SIGTERM lost as a KeyboardInterrupt still stops the command: the next run e-stops at its first tick.

    Outside a run's loop `rhi.cli` turns it into a KeyboardInterrupt, which Python ignores inside a weakref
    callback (Numba runs those while it compiles); the command records the signal, and a run that starts after it
    e-stops at once with zero torque and the reason in the log (`rhi view --compare` went on running before).
    """
    import weakref

    from rhi import _lifetime
    from rhi.cli import _interrupt_on_signals

    previous = _interrupt_on_signals()
    try:
        class Thing:
            pass

        thing = Thing()
        weakref.finalize(thing, lambda: signal.raise_signal(signal.SIGTERM))  # the handler runs in the callback
        del thing
        assert _lifetime.STOP_SIGNALS == ["SIGTERM"]  # the KeyboardInterrupt was lost; the signal is not
        plant, ctrl, hand, wall, phys = _scenario(dev)
        res = run(SimLink(plant, hand=hand), ctrl, duration=1.0, realtime=False)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        _lifetime.STOP_SIGNALS.clear()
    assert res.summary["fault_kind"] == "estop" and res.fault.endswith("SIGTERM") and res.exit_code == 143
    assert len(res.log) <= 1 and np.all(res.log.tau == 0)


def test_latched_until_reset(dev):
    plant, ctrl, hand, wall, phys = _scenario(dev)
    guard = Safety(dev)
    guard.estop("test")
    res = run(SimLink(plant, hand=hand), ctrl, duration=0.05, safety=guard, realtime=False, stop_on_fault=False)
    assert len(res.log) == 50 and np.all(res.log.safety == 1) and np.all(res.log.tau == 0)
    guard.reset()
    assert guard.fault is None


class _RecordingLink:
    """A device that reports random in-range states and records every torque it receives."""

    def __init__(self, dev, rng, N):
        lo, hi = np.maximum(dev.q_min, -3), np.minimum(dev.q_max, 3)
        self.n, self.seq = dev.n, 0
        self.Q, self.dQ = rng.uniform(lo, hi, (N + 10, dev.n)), rng.normal(0, 2.0, (N + 10, dev.n))
        self.sent = []
        self.ft = np.zeros(6)

    def open(self):
        pass

    def read(self):
        k = self.seq = self.seq + 1
        return Reading(k * 1e-3, k, self.Q[k], self.dQ[k], {"ft": self.ft}, 1)

    def write(self, tau, *, enable):
        self.sent.append(tau if enable else np.zeros(self.n))

    def close(self):
        pass


def test_no_torque_above_limit_over_1e5_ticks(dev):
    """Every safety option on, a controller returning wild torques, the operator resetting every fault at once."""
    N = 100_000
    rng = np.random.default_rng(7)
    scale = np.array([0.1, 1.0, 10.0, 1e6])[rng.integers(4, size=N + 10)]
    T = rng.normal(0, 1, (N + 10, 4)) * scale[:, None]
    bad = rng.random(N + 10) < 1e-3
    T[bad, rng.integers(4, size=bad.sum())] = rng.choice([np.nan, np.inf, -np.inf], bad.sum())
    guard = Safety(dev, SafetyConfig(max_joint_speed=5.0, max_handle_speed=3.0, range_margin=0.01))
    kinds = set()

    class Wild:
        device = dev
        k = 0

        def step(self, t, q, dq, sensors):
            self.k += 1
            return T[self.k]

    link = _RecordingLink(dev, rng, N)
    ctrl = Wild()

    orig = guard.filter

    def filter_and_reset(tau, t):
        out = orig(tau, t)
        if guard.fault is not None:
            kinds.add(guard.fault_kind)
            guard.reset()
        return out

    guard.filter = filter_and_reset
    res = run(link, ctrl, duration=N / 1000, realtime=False, safety=guard, stop_on_fault=False)
    sent = np.array(link.sent)
    assert len(sent) >= N
    assert np.all(sent >= dev.torque_min - 1e-12) and np.all(sent <= dev.torque_max + 1e-12)
    assert res.summary["clamped"] > 0.4 * N
    assert {"torque", "speed"} <= kinds
    # the summary's peak load is that of the torques sent (each on its own side's limit), and a clamp reaches 1
    ratio = np.where(sent > 0, sent / dev.torque_max, sent / dev.torque_min).max()
    assert res.summary["max_torque_ratio"] == pytest.approx(ratio, rel=1e-12) and ratio == pytest.approx(1.0)


def test_torque_ratio_is_against_the_limit_on_its_side(dev):
    """Asymmetric limits: τ / τ_max for a positive torque, τ / τ_min for a negative one; 0 after a fault."""
    lopsided = dev.lock(name="rhi4_lopsided")
    lopsided.torque_min, lopsided.torque_max = np.full(4, -1.0), np.full(4, 2.0)
    guard = Safety(lopsided)
    np.testing.assert_array_equal(guard.filter([1.5, -0.9, 0.0, 0.2], 0.0), [1.5, -0.9, 0.0, 0.2])
    assert guard.ratio == pytest.approx(0.9) and guard.clamped == 0
    np.testing.assert_array_equal(guard.filter([3.0, -0.5, 0.0, 0.0], 0.0), [2.0, -0.5, 0.0, 0.0])
    assert guard.ratio == 1.0 and guard.clamped == 1
    np.testing.assert_array_equal(guard.filter([np.nan, 0.0, 0.0, 0.0], 0.0), np.zeros(4))
    assert guard.ratio == 0.0 and guard.fault_kind == "torque"


@pytest.mark.parametrize("bad", [
    lambda dev, p: SimLink(p, rate=1500.0),
    lambda dev, p: SimLink(p, rate=1e6),
    lambda dev, p: SimLink(p, rate=-5.0),
    lambda dev, p: Plant(dev, timestep=0.5),
    lambda dev, p: Plant(dev, timestep=0.0),
    lambda dev, p: simulate(p, object(), duration=0.1, rate=1500.0),
    lambda dev, p: simulate(p, object(), duration=1e-5),
    lambda dev, p: simulate(p, object(), duration=-1.0),
    lambda dev, p: run(SimLink(p), NullSpaceController(dev, ControllerConfig(primary=ForceRendering())),
                       duration=-1.0),
    lambda dev, p: run(SimLink(p, rate=500.0), NullSpaceController(dev, ControllerConfig(primary=ForceRendering()))),
    lambda dev, p: SafetyConfig(stale_ticks=0),
    lambda dev, p: SafetyConfig(silence=float("nan")),
    lambda dev, p: SafetyConfig.from_dict({"stale_tick": 3}),
    lambda dev, p: SafetyConfig.from_dict({"stale_ticks": "3"}),
    lambda dev, p: Inject(SimLink(p), freeze=(0.5, 0.1)),
    lambda dev, p: Telemetry(every=0),
], ids=range(16))
def test_bad_input_is_a_clear_error(dev, bad):
    plant = Plant(dev)
    plant.reset(Q0)
    with pytest.raises(InvalidInput) as e:
        bad(dev, plant)
    assert ":" in str(e.value)


def test_infinite_torque_limits_refused(dev):
    free = dev.lock(name="rhi4_unlimited")
    free.torque_max = np.full(4, np.inf)
    with pytest.raises(InvalidInput, match="torque limits"):
        Safety(free)


def test_push_force_and_csv_roundtrip(dev, tmp_path):
    plant = Plant(dev)
    plant.reset(Q0)
    ctrl = NullSpaceController(dev, ControllerConfig(primary=ForceRendering()))
    log = simulate(plant, ctrl, duration=0.05, hand=PushForce([0, 1], 1.0))
    log.to_csv(tmp_path / "a.csv")
    back = Log.load(tmp_path / "a.csv")
    np.testing.assert_allclose(back.tau, log.tau, rtol=1e-15)
    np.testing.assert_allclose(back.work, log.work, rtol=1e-15)
    log.to_npz(tmp_path / "a.npz")
    assert np.load(tmp_path / "a.npz")["q"].shape == (50, 4)


@pytest.mark.realtime
def test_affinity_refused_is_a_clear_warning(dev):
    plant, ctrl, hand, wall, phys = _scenario(dev)
    with pytest.warns(RuntimeWarning, match="CPU affinity 4096 not applied"):
        res = run(SimLink(plant, hand=hand), ctrl, duration=0.02, cpu=4096)
    assert res.fault is None and any("affinity" in e.detail for e in res.log.events)
    with pytest.raises(InvalidInput, match="priority"):
        run(SimLink(plant, hand=hand), ctrl, duration=0.02, priority=120)


@pytest.mark.realtime
def test_spin_waits_on_a_busy_core(dev):
    """`wait_until(spin=True)` keeps its core busy to the deadline; the default sleeps; `run(spin=True)` is on time."""
    from rhi.runtime.realtime import wait_until

    used = {}
    for spin in (False, True):
        c0, w0 = time.thread_time(), time.monotonic()
        wait_until(w0 + 0.1, spin)
        used[spin], wall = time.thread_time() - c0, time.monotonic() - w0
        assert wall >= 0.1
    # a loaded machine gives the spinning thread only its share of a core (a fifth at a load of 10 on 2 cores)
    assert used[False] < 0.1 * wall and used[True] > max(5 * used[False], 0.05 * wall), (used, wall)
    plant, ctrl, hand, wall_, phys = _scenario(dev)
    res = run(SimLink(plant, hand=hand), ctrl, duration=0.2, virtual=wall_, spin=True)
    assert res.fault is None and res.summary["spin"] is True
    assert res.summary["ticks"] <= 200 <= res.summary["ticks"] + res.summary["skipped_slots"]
    assert res.log.wall[-1] >= 0.19  # paced on the clock, not run as fast as it can


def test_a_spinning_sched_fifo_loop_sleeps_whole_waits_where_the_kernel_throttles_it():
    """Spinning under a throttled SCHED_FIFO priority, whole waits are slept, 8 % of the time (`spin_rest`)."""
    from rhi.runtime.realtime import realtime_thread, rt_throttled, spin_rest

    assert spin_rest(True).share == spin_rest(False).share == 0.0  # not real-time
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with realtime_thread(None, 1):
            granted = not any("not applied" in str(w.message) for w in caught)
            rest, asleep = spin_rest(True), spin_rest(False)
    if not granted or not rt_throttled():
        pytest.skip("SCHED_FIFO not granted here, or the kernel does not throttle real-time tasks")
    assert rest.share == 0.08 and asleep.share == 0.0


@pytest.mark.parametrize("busy", [0.2e-3, 0.9e-3])
def test_spin_rest_sleeps_few_whole_waits_and_enough_of_the_time(busy):
    """On a clock of 1 ms ticks busy `busy` [s]: the waits slept are whole, spread out, 8 % of each half second."""
    from rhi.runtime.realtime import SpinRest

    rest, never = SpinRest(0.08), SpinRest(0.0)
    now, slept, asleep = 0.0, 0.0, []
    for _ in range(3000):
        now += busy
        assert not never.due(now)
        due = rest.due(now)
        asleep.append(due)
        if due:
            rest.slept(1e-3 - busy)
            slept += 1e-3 - busy
        now += 1e-3 - busy
    wait = 1e-3 - busy  # (a window may end one wait short of its share, or over it)
    assert 0.05 < 0.08 - wait / SpinRest.WINDOW <= slept / now <= 0.08 + wait / SpinRest.WINDOW
    if wait >= 0.5e-3:  # one slept wait pays for the next five or more
        assert not any(a and b for a, b in zip(asleep, asleep[1:]))  # never two slept waits in a row
    assert sum(asleep) <= 0.08 * now / wait + 3 * now / SpinRest.WINDOW


def test_a_cpu_latency_request_is_held_for_the_loop_and_released_after():
    """`cpu_latency` writes Linux's PM QoS request while the loop runs; the kernel's aggregate reads it back."""
    import struct

    from rhi.runtime.realtime import CPU_LATENCY_FILE, realtime_thread

    if not os.access(CPU_LATENCY_FILE, os.R_OK | os.W_OK):
        with pytest.warns(RuntimeWarning, match="CPU latency request of 0 µs not applied"):
            with realtime_thread(None, None, 0.0):
                pass
        pytest.skip(f"{CPU_LATENCY_FILE} not writable here: the refusal is a warning (checked)")

    def current() -> int:
        with open(CPU_LATENCY_FILE, "rb") as f:
            return struct.unpack("i", f.read(4))[0]

    before = current()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # granted: no warning
        with realtime_thread(None, None, 0.0):
            assert current() == 0
        with realtime_thread(None, None, 25e-6):
            assert current() == min(25, before)
    assert current() == before


def test_warmup_leaves_the_controller_untouched_and_bad_realtime_options(dev):
    """`run` warms the controller's kernels on a twin: the controller's own state stays fresh."""
    from rhi.runtime.server import DeviceServer

    plant, ctrl, hand, wall, phys = _scenario(dev)
    ctrl.warmup()
    assert ctrl.state.ticks == 0 and not ctrl.state.stopped
    assert ctrl.passivity is None or ctrl.passivity.position is None
    for kw, name in (({"cpu": -1}, "cpu"), ({"cpu": True}, "cpu"), ({"priority": 0}, "priority"),
                     ({"cpu_latency": -1e-6}, "cpu_latency"), ({"cpu_latency": float("nan")}, "cpu_latency"),
                     ({"cpu_latency": True}, "cpu_latency"), ({"cpu_latency": 2.0}, "cpu_latency")):
        with pytest.raises(InvalidInput, match=name):
            DeviceServer(SimLink(plant), dev, **kw)
