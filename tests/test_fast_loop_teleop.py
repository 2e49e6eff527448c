"""The compiled simulation loop with a teleoperated slave, chapter 5's objectives and a `Probe`, against the Python loop.

As `test_fast_loop`: each scenario runs once as `simulate` chooses (the compiled loop) and once with
`FastLoop.build` refusing (the Python loop, the reference); logs, the slave's path, the probe's values and
the controller's state agree.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_fast_loop import Q0, check_same, palpation, short_calls

import rhi
from rhi.control import (
    ControllerConfig,
    ImpedanceControl,
    Manipulability,
    NullSpaceController,
    ObjectiveTerm,
    TMIMatching,
)
from rhi.errors import InvalidInput
from rhi.sim import Hand, HandPath, Plant, Probe, Teleoperation, simulate
from rhi.sim._compiled import fast_loop

Q_SLAVE = np.array([0.5, 1.3])


@pytest.fixture(scope="module")
def devices():
    return rhi.device("rhi4"), rhi.device("rehab_slave")


def teleoperated(devices, objective: str, *, python: bool, monkeypatch, duration: float = 0.5, short=None):
    """(log, controller, compiled loop or None) of a ch5-like run: the hand drives rhi4, the slave follows."""
    dev, slave = devices
    if python:
        monkeypatch.setattr(fast_loop.FastLoop, "build", staticmethod(lambda *a, **k: None))
    if short is not None:
        monkeypatch.setattr(fast_loop, "ticks", short)
    sp = Plant(slave)
    sp.reset(Q_SLAVE)
    obj = {"tmi": TMIMatching(slave, sp, k_q=10.0), "tmi_plain": TMIMatching(slave, sp),
           "log_mu": Manipulability(log=True, k_q=10.0), "mu": Manipulability()}[objective]
    ctrl = NullSpaceController(dev, ControllerConfig(ImpedanceControl(damping=2.0 * np.eye(2)),
                                                     objectives=(ObjectiveTerm(obj, 0.05),), damping=0.02,
                                                     saturation="none", null_space="clipped"))
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    hand = Hand(HandPath([x0, x0 + [0.02, 0.0], x0 + [0.02, 0.02]], speed=0.08), stiffness=400.0)
    log = simulate(plant, ctrl, duration=duration, hand=hand, teleop=Teleoperation(sp, offset=[0.0, 0.01]),
                   record=Probe(slave_q="slave_q", held="held", scale="pc_scale"))
    monkeypatch.undo()
    return log, ctrl, fast_loop.last


def same_teleoperation(a, b) -> None:
    check_same(a[:2], b[:2])
    np.testing.assert_allclose(a[0].slave_x, b[0].slave_x, rtol=0, atol=1e-9)
    assert a[0].extra.keys() == b[0].extra.keys() == {"slave_q", "held", "scale"}
    np.testing.assert_allclose(a[0].extra["slave_q"], b[0].extra["slave_q"], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(a[0].extra["held"], b[0].extra["held"])
    np.testing.assert_array_equal(a[0].extra["scale"], b[0].extra["scale"])


@pytest.mark.parametrize("objective", ["tmi", "tmi_plain", "log_mu", "mu"])
def test_teleoperation_and_chapter5_objectives_equal_the_python_loop(devices, objective, monkeypatch):
    a = teleoperated(devices, objective, python=False, monkeypatch=monkeypatch)
    assert a[2] is not None and a[2].ticks == len(a[0]) == 500  # every tick compiled
    assert a[0].meta["route"] == "compiled loop (whole tick)"
    b = teleoperated(devices, objective, python=True, monkeypatch=monkeypatch)
    assert b[2] is None and b[0].meta["route"].startswith("python loop")
    same_teleoperation(a, b)
    moved = np.linalg.norm(a[0].extra["slave_q"][-1] - Q_SLAVE)
    assert moved > 0.05 and a[0].extra["slave_q"].shape == (500, 2)  # the slave followed the master
    assert np.isnan(a[0].extra["scale"]).all() and a[0].extra["held"].dtype == bool  # no passivity layer


@pytest.mark.parametrize("k_q", [10.0, None])
def test_fixed_slave_configuration_is_compiled_and_equals_the_live_python_loop(devices, k_q):
    """ch5.fixed_point: TMI to a fixed slave configuration runs compiled (ˢM held), = ˢM read each tick in Python."""
    dev, slave = devices
    x0 = dev.fk(Q0)

    def once(slave_q):
        ctrl = NullSpaceController(dev, ControllerConfig(
            ImpedanceControl(damping=2.0 * np.eye(2)), objectives=(ObjectiveTerm(TMIMatching(slave, slave_q, k_q=k_q), 1.0),),
            damping=0.02, saturation="none", null_space="clipped"))
        plant = Plant(dev)
        plant.reset(Q0)
        log = simulate(plant, ctrl, duration=0.5, hand=Hand(HandPath(x0[None]), stiffness=3000.0, damping=20.0))
        return log, ctrl, fast_loop.last

    a = once(Q_SLAVE.copy())
    assert a[2] is not None and a[2].ticks == len(a[0]) == 500 and a[0].meta["route"] == "compiled loop (whole tick)"
    b = once(lambda: Q_SLAVE)  # the route before: ˢM from a callable, read in Python each tick
    assert b[2] is None and b[0].meta["route"].startswith("python loop (an objective's desired ellipsoid")
    check_same(a[:2], b[:2])
    assert np.abs(a[0].q[-1] - Q0).max() > 1e-4  # the objective moved the null space


def test_teleoperated_ticks_handed_to_python_resume(devices, monkeypatch):
    """Compiled calls that end early hand ticks to the Python loop: the slave, the probe and the state carry on."""
    handed: list[int] = []
    a = teleoperated(devices, "tmi", python=False, monkeypatch=monkeypatch, short=short_calls(3, handed))
    assert a[2].ticks + len(handed) == 500 and len(handed) > 10
    b = teleoperated(devices, "tmi", python=True, monkeypatch=monkeypatch)
    same_teleoperation(a, b)


def test_probe_keeps_a_palpation_compiled_and_records_what_a_python_hook_reads(monkeypatch):
    """ASCM's held set and the passivity λ by a `Probe` (compiled) = a plain hook reading the controller (Python)."""
    dev = rhi.device("rhi4")
    x0 = dev.fk(Q0)

    def once(record):
        plant = Plant(dev)
        plant.reset(Q0)
        ctrl = palpation(dev)
        probe = record(ctrl) if callable(record) and not isinstance(record, Probe) else record
        log = simulate(plant, ctrl, duration=0.6,
                       hand=Hand(HandPath([x0, x0 + [0.01, 0.0], x0 + [0.01, 0.03]], speed=0.05), stiffness=2000.0),
                       virtual=rhi.sim.Wall(x0 + [0.0, 0.005], [0, 1], 1000.0), record=probe)
        return log, ctrl, fast_loop.last

    a = once(Probe(held="held", pc_scale="pc_scale"))
    assert a[2] is not None and a[2].ticks == 600
    b = once(lambda ctrl: lambda: {"held": ctrl.state.saturated.copy(), "pc_scale": ctrl.passivity.scale})
    assert b[2] is None
    check_same(a[:2], b[:2])
    np.testing.assert_array_equal(a[0].extra["held"], b[0].extra["held"])
    np.testing.assert_allclose(a[0].extra["pc_scale"], b[0].extra["pc_scale"], rtol=0, atol=1e-12)
    assert a[0].extra["held"].any() and np.isfinite(a[0].extra["pc_scale"]).all()  # ASCM held joints; the layer ran


def test_probe_arguments_and_where_it_cannot_read(devices):
    with pytest.raises(InvalidInput, match="names"):
        Probe()
    with pytest.raises(InvalidInput, match="speed"):
        Probe(v="speed")
    dev = devices[0]
    plant = Plant(dev)
    plant.reset(Q0)
    with pytest.raises(InvalidInput, match="no teleop"):
        simulate(plant, palpation(dev), duration=0.01, record=Probe(q_s="slave_q"))
    assert fast_loop.last is None
    plant.reset(Q0)
    with pytest.raises(InvalidInput, match="log columns"):
        simulate(plant, palpation(dev), duration=0.01, record=Probe(q="held"))


def intent_run(devices, kind: str, *, python: bool, monkeypatch):
    """(log, IntentController, compiled loop or None) of a beyond.intent_w_trajectory-like run (VME matching along u)."""
    from rhi.control import JointLimitBarrier
    from rhi.control.intent import FilteredIntent, HMMIntent, KnownIntent
    from rhi.control.intent_control import IntentController, IntentVME
    from rhi.experiments.beyond.intent import PathIntent

    dev, slave = devices
    if python:
        monkeypatch.setattr(fast_loop.FastLoop, "build", staticmethod(lambda *a, **k: None))
    x0 = dev.fk(Q0)
    path = HandPath([x0, x0 + [0.02, 0.0], x0 + [0.02, 0.02]], speed=0.08, start=0.05)
    est = {"known": KnownIntent([0.0, 1.0]), "filtered": FilteredIntent(m=2, u0=[0.0, 1.0], tau=0.05),
           "hmm": HMMIntent(m=2, u0=[0.0, 1.0]), "path": PathIntent(path, [1.0, 0.0])}[kind]
    ctrl = IntentController(NullSpaceController(dev, ControllerConfig(
        ImpedanceControl(damping=2.0 * np.eye(2)), damping=0.02, saturation="none", null_space="clipped",
        objectives=(ObjectiveTerm(IntentVME(est, 0.01), 0.5), ObjectiveTerm(JointLimitBarrier(0.1), 2.0)))), est)
    sp = Plant(slave)
    sp.reset(Q_SLAVE)
    plant = Plant(dev)
    plant.reset(Q0)
    log = simulate(plant, ctrl, duration=0.5, hand=Hand(path, stiffness=400.0), teleop=Teleoperation(sp),
                   record=Probe(slave_q="slave_q"))
    monkeypatch.undo()
    return log, ctrl, fast_loop.last


@pytest.mark.parametrize("kind", ["known", "filtered", "hmm", "path"])
def test_intent_controller_equals_the_python_loop(devices, kind, monkeypatch):
    """The estimator's tick, M_des(u) and the controller's history in the compiled loop = the Python loop."""
    a = intent_run(devices, kind, python=False, monkeypatch=monkeypatch)
    assert a[2] is not None and a[2].ticks == len(a[0]) == 500
    b = intent_run(devices, kind, python=True, monkeypatch=monkeypatch)
    assert b[2] is None
    # the estimator reads ẋ from the compiled handle kinematics (Python: J q̇ from Pinocchio): equal to rounding
    check_same((a[0], a[1].controller), (b[0], b[1].controller), rtol=1e-10)
    np.testing.assert_allclose(a[0].extra["slave_q"], b[0].extra["slave_q"], rtol=0, atol=1e-9)
    (ha, hb), (ea, eb) = (a[1].history, b[1].history), (a[1].estimator, b[1].estimator)
    assert len(ha) == len(hb) == 500
    np.testing.assert_allclose([h[0] for h in ha], [h[0] for h in hb], rtol=0, atol=0)
    np.testing.assert_allclose(np.array([h[1] for h in ha]), np.array([h[1] for h in hb]), rtol=0, atol=1e-9)
    np.testing.assert_allclose([h[2] for h in ha], [h[2] for h in hb], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ea.u, eb.u, rtol=0, atol=1e-9)
    if kind != "known":
        assert np.ptp(np.array([h[1] for h in ha]), axis=0).max() > 0.5  # u turned during the run
    for attr in ("T", "p", "active"):
        if hasattr(eb, attr):
            np.testing.assert_allclose(getattr(ea, attr), getattr(eb, attr), rtol=0, atol=1e-9)
