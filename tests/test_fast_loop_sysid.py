"""The identification runs on the compiled simulation loop: the motors off (`ZeroTorque`) and a constant push (`PushForce`).

ch3.sysid_table_3_2 pushes the devices with their motors off (`rhi.sim._compiled.motors_off`), ch6.sysid_table_6_1
pushes rhi4 under the ch. 6 null-space controller (`rhi.sim._compiled.fast_loop`); both hands are `PushForce`. Each
run is compared with the Python loop with the hand's own `force` at every physics step (the reference): logs equal
to 1e-9 in every column but the timing ones, the same fault and events; and every `simulate` call the two
experiments make runs every tick compiled.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_fast_loop import COLUMNS, Q0, check_same

import rhi
from rhi.control import ZeroTorque
from rhi.errors import InvalidInput
from rhi.experiments import identification as ID
from rhi.experiments.ch3 import sysid_table_3_2
from rhi.experiments.ch6 import sysid_table_6_1
from rhi.sim import Plant, PushForce, Wall, simulate, stop
from rhi.sim._compiled import fast_loop, motors_off
from rhi.sim.loop import Session


@pytest.fixture(scope="module")
def rhi4():
    return rhi.device("rhi4")


def python_loop(monkeypatch) -> None:
    """The reference: the Python loop (neither compiled loop builds) with the hand's Python `force` at every step."""
    monkeypatch.setattr(fast_loop.FastLoop, "build", staticmethod(lambda *a, **k: None))
    monkeypatch.setattr(motors_off.MotorsOffLoop, "build", staticmethod(lambda *a, **k: None))
    monkeypatch.setattr(Session, "_compiled", lambda self, hand, phys: None)


def same_logs(a, b) -> None:
    """Every non-timing column to 1e-9 (NaN where the other is NaN), the same fault and events."""
    assert len(a) == len(b)
    for name in COLUMNS:
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
        np.testing.assert_allclose(np.nan_to_num(x), np.nan_to_num(y), rtol=0, atol=1e-9, err_msg=name)
    assert a.fault == b.fault
    assert [(e.t, e.kind, e.detail, e.tick) for e in a.events] == [(e.t, e.kind, e.detail, e.tick) for e in b.events]


def push_off(dev, physical, duration: float, monkeypatch=None):
    """(log, the motors-off loop or None): a push from 3.5 ms on with the motors off, 10 ms per `simulate` call."""
    if monkeypatch is not None:
        python_loop(monkeypatch)
    plant = Plant(dev)
    plant.reset(Q0)
    hand = PushForce([0.0, 1.0], 1.5, start=0.0035)
    logs, ticks = [], 0
    while plant.time < duration - 1e-9:
        logs.append(simulate(plant, ZeroTorque(dev.n), duration=0.01, hand=hand, physical=physical))
        ticks += 0 if motors_off.last is None else motors_off.last.ticks
        if logs[-1].fault is not None:
            break
    if monkeypatch is not None:
        monkeypatch.undo()
    return logs, ticks


def test_motors_off_push_into_a_stop_equals_python_loop(rhi4, monkeypatch):
    """Zero torque, no force before the push starts, then the handle pushed into a physical stop."""
    wall = stop(rhi4.fk(Q0) + [0.0, 0.004], [0.0, 1.0])
    a, ticks = push_off(rhi4, wall, 0.3)
    assert ticks == sum(len(g) for g in a) == 300 and {g.meta["route"] for g in a} == {"compiled loop (motors off)"}
    b, none = push_off(rhi4, wall, 0.3, monkeypatch)
    assert none == 0 and b[0].meta["route"].startswith("python loop")
    for x, y in zip(a, b):
        same_logs(x, y)
    F = np.concatenate([g.F_hand for g in a])
    assert np.all(F[:3] == 0.0) and np.all(F[4:] == [0.0, 1.5])  # the push starts between ticks 3 and 4
    assert np.all(a[0].tau == 0.0) and np.all(np.isnan(a[0].V)) and a[-1].work[-1] > 0.0
    assert np.concatenate([g.x for g in a])[-1, 1] > wall.point[1]  # the handle went into the stop


def test_motors_off_unstable_plant_fault_equals_python_loop(rhi4, monkeypatch):
    """A physical wall far too stiff for the timestep: MuJoCo diverges; the same tick, reason and rows."""
    wall = Wall(rhi4.fk(Q0) + [0.0, 0.001], [0.0, 1.0], 5e9, damping=0.0)
    a, ticks = push_off(rhi4, wall, 0.3)
    b, _ = push_off(rhi4, wall, 0.3, monkeypatch)
    assert a[-1].fault is not None and "unstable" in a[-1].fault and a[-1].safety[-1] == 1.0
    assert ticks == sum(len(g) for g in a) < 300
    assert len(a) == len(b)
    for x, y in zip(a, b):
        same_logs(x, y)


def test_motors_off_keeps_the_python_loop_where_it_does_not_apply(rhi4):
    plant = Plant(rhi4)
    plant.reset(Q0)
    log = simulate(plant, ZeroTorque(4), duration=0.01, record=lambda: {"k": 1.0})
    assert motors_off.last is None and log.meta["route"].startswith("python loop (a record hook")
    assert np.all(log.tau == 0.0)
    with pytest.raises(InvalidInput, match="n: expected a positive integer"):
        ZeroTorque(0)


def record_calls(monkeypatch) -> list:
    """Every `simulate` call of the identification protocol: (log, ticks its compiled loop ran)."""
    calls = []

    def recorded(*args, **kwargs):
        log = simulate(*args, **kwargs)
        loop = motors_off.last if type(args[1]) is ZeroTorque else fast_loop.last
        calls.append((log, 0 if loop is None else loop.ticks, args[1]))
        return log

    monkeypatch.setattr(ID, "simulate", recorded)
    return calls


@pytest.mark.parametrize("experiment", ["ch3", "ch6"])
def test_sysid_experiments_run_compiled_and_equal_python_loop(monkeypatch, experiment):
    """Every `simulate` call of the experiment runs every tick compiled, its log and its tables equal the Python loop's."""
    def run(python: bool):
        calls = record_calls(monkeypatch)
        if python:
            python_loop(monkeypatch)
        if experiment == "ch3":
            result = sysid_table_3_2(trials=2)
        else:
            result = sysid_table_6_1(trials=2, projectors=("dynamic",), starts=1)
        monkeypatch.undo()
        return result, calls

    res, calls = run(python=False)
    route = "compiled loop (motors off)" if experiment == "ch3" else "compiled loop (whole tick)"
    assert len(calls) > 40 and {log.meta["route"] for log, _, _ in calls} == {route}
    assert all(ticks == len(log) for log, ticks, _ in calls)  # no tick handed to Python
    ref, ref_calls = run(python=True)
    assert all(log.meta["route"].startswith("python loop") for log, _, _ in ref_calls)
    assert len(calls) == len(ref_calls)
    for (a, _, ca), (b, _, cb) in zip(calls, ref_calls):
        if experiment == "ch3":
            same_logs(a, b)
        else:
            check_same((a, ca), (b, cb))
    for ta, tb in zip(res.tables, ref.tables):
        for ra, rb in zip(ta.rows, tb.rows):
            assert ra.quantity == rb.quantity and ra.ours == pytest.approx(rb.ours, rel=1e-9, abs=1e-12), ra.quantity
