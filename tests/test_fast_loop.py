"""The compiled simulation loop (`rhi.sim._compiled.fast_loop`) against the Python loop of `simulate`: same log, same state.

Each scenario runs twice from the same start: once as `simulate` chooses (the compiled loop), once with
`FastLoop.build` refusing (the Python loop, the reference). Logs equal to 1e-9 in every column but the
timing ones, the same fault and events, and the controller's state (FME transition, passivity observer)
equal afterwards.
"""

from __future__ import annotations

import dataclasses
import inspect
import math

import numpy as np
import pytest

import rhi
from rhi.control import (
    ControllerConfig,
    FMESchedule,
    ForceRendering,
    NullSpaceController,
    NullSpaceTank,
    ObjectiveTerm,
    SpringPalpation,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.sim import (
    Fixture,
    Hand,
    HandPath,
    HandSequence,
    MinimumJerkPalpation,
    Plant,
    Wall,
    compose,
    simulate,
    stop,
)
from rhi.sim._compiled import fast_loop

Q0 = np.array([-0.63, 0.25, 0.28, 0.09])
COLUMNS = ["t", "q", "dq", "tau", "x", "xdot", "F_hand", "F_env", "ft", "work", "V", "omega", "alpha", "beta",
           "E_obs", "alpha_pc", "seq", "safety"]


@pytest.fixture(scope="module")
def rhi4():
    return rhi.device("rhi4")


def palpation(dev, passivity=True, saturation="ascm"):
    """The ch7 controller of benchmarks/bench_sim.py (force rendering, FME schedule, ASO, ASCM or another allocation)."""
    K, z = fme_shape(dev.jacobian(np.zeros(4)), dev.torque_max, 5.0)
    law = ForceRendering(damping=0.01) if passivity else ForceRendering(damping=0.01, passivity=None)
    return NullSpaceController(dev, ControllerConfig(
        law, objectives=(ObjectiveTerm(FMESchedule(desired_fme_free([0, 1], K, z), desired_fme_stiff([0, 1], K, z)),
                                       20.0),), saturation=saturation))


def run(dev, make_controller, *, python: bool, duration: float = 0.4, hand="push", physical=None, virtual=True,
        monkeypatch=None):
    """(log, controller, the compiled loop or None) of one scenario."""
    if python:
        monkeypatch.setattr(fast_loop.FastLoop, "build", staticmethod(lambda *a, **k: None))
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    if hand == "push":
        hand = Hand(HandPath([x0, x0 + [0.01, 0.0], x0 + [0.01, 0.03]], speed=0.05), stiffness=300.0)
    ctrl = make_controller(dev)
    log = simulate(plant, ctrl, duration=duration, hand=hand, physical=physical,
                   virtual=Wall(x0 + [0.0, 0.005], [0, 1], 1000.0) if virtual else None)
    if python:
        monkeypatch.undo()
    return log, ctrl, fast_loop.last


def check_same(a, b, rtol: float = 0.0) -> None:
    """Two (log, controller) runs agree: every non-timing column to 1e-9 (+ rtol), fault, events and controller state."""
    (la, ca), (lb, cb) = a, b
    assert len(la) == len(lb)
    for name in COLUMNS:
        x, y = np.asarray(getattr(la, name)), np.asarray(getattr(lb, name))
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
        np.testing.assert_allclose(np.nan_to_num(x), np.nan_to_num(y), rtol=rtol, atol=1e-9, err_msg=name)
    assert la.fault == lb.fault
    assert [(e.t, e.kind, e.detail, e.tick) for e in la.events] == [(e.t, e.kind, e.detail, e.tick) for e in lb.events]
    sa, sb = ca.state, cb.state
    for f in dataclasses.fields(sa):
        va, vb = getattr(sa, f.name), getattr(sb, f.name)
        if f.name == "tank":
            continue  # below, field by field
        if isinstance(va, np.ndarray) or isinstance(vb, np.ndarray):
            np.testing.assert_allclose(va, vb, rtol=rtol, atol=1e-9, err_msg=f.name)
        elif isinstance(va, float) and math.isnan(va):
            assert math.isnan(vb), f.name
        elif rtol and isinstance(va, float):
            assert va == pytest.approx(vb, rel=rtol, abs=1e-9), f.name
        else:
            assert va == vb, f.name
    ta, tb = sa.tank, sb.tank
    assert (ta is None) == (tb is None)
    if ta is not None:
        for f in dataclasses.fields(ta):
            np.testing.assert_allclose(getattr(ta, f.name), getattr(tb, f.name), rtol=rtol, atol=1e-9, err_msg=f.name)
    pa, pb = ca.passivity, cb.passivity
    assert (pa is None) == (pb is None)
    if pa is not None:
        for f in ("energy", "alpha", "scale", "dissipated", "t"):
            assert getattr(pa, f) == pytest.approx(getattr(pb, f), abs=1e-9), f
        np.testing.assert_allclose(pa.position, pb.position, rtol=0, atol=1e-12)
        np.testing.assert_allclose(pa.effort, pb.effort, rtol=0, atol=1e-9)


@pytest.mark.parametrize("passivity", [True, False])
def test_palpation_equals_python_loop(rhi4, monkeypatch, passivity):
    make = lambda dev: palpation(dev, passivity)  # noqa: E731
    log, ctrl, fast = run(rhi4, make, python=False, duration=0.6)
    assert fast is not None and fast.ticks == len(log) == 600  # every tick compiled
    assert float(np.max(np.abs(log.F_env))) > 0.1  # the wall is reached
    assert ctrl.state.transition.stiff  # the FME schedule switched during the run
    if passivity:
        assert np.all(np.isfinite(log.E_obs))  # the passivity observer ran in every compiled tick
    ref, cref, none = run(rhi4, make, python=True, duration=0.6, monkeypatch=monkeypatch)
    assert none is None
    check_same((log, ctrl), (ref, cref))
    assert np.all(log.t_tick > 0) and np.all(np.isnan(log.t_step))  # timing: per-call averages, not per tick


def test_lp_allocation_palpation_equals_python_loop(rhi4, monkeypatch):
    """ch7.palpation's "lp" case: the LP optimum's compiled branch (the active set) in the compiled loop = the Python loop."""
    x0 = rhi4.fk(Q0)
    hand = Hand(HandPath([x0, x0 + [0.01, 0.0], x0 + [0.01, 0.03]], speed=0.05), stiffness=2000.0)
    make = lambda dev: palpation(dev, saturation="lp")  # noqa: E731
    log, ctrl, fast = run(rhi4, make, python=False, duration=0.6, hand=hand)
    assert fast is not None and fast.ticks == len(log) == 600 and log.meta["route"] == "compiled loop (whole tick)"
    assert np.sum(log.alpha < 1.0) > 50  # the allocation scaled the force
    ref, cref, none = run(rhi4, make, python=True, duration=0.6, hand=hand, monkeypatch=monkeypatch)
    assert none is None
    check_same((log, ctrl), (ref, cref))


def test_physical_stop_no_virtual_and_no_hand(rhi4, monkeypatch):
    """A spring law pushed into a physical stop by the hand; then the device left alone (no hand, no environment)."""
    spring = lambda dev: NullSpaceController(dev, ControllerConfig(  # noqa: E731
        SpringPalpation(800.0, x0=dev.fk(Q0) + [0.0, 0.004], normal=[0.0, 1.0], passivity=None)))
    x0 = rhi4.fk(Q0)
    wall = stop(x0 + [0.0, 0.008], [0.0, 1.0])
    for hand, physical, virtual in (("push", wall, False), (None, None, False), (None, wall, True)):
        make = spring if virtual is False else (lambda dev: palpation(dev))
        a = run(rhi4, make, python=False, hand=hand, physical=physical, virtual=virtual)
        assert a[2] is not None and a[2].ticks == 400
        b = run(rhi4, make, python=True, hand=hand, physical=physical, virtual=virtual, monkeypatch=monkeypatch)
        check_same(a[:2], b[:2])
    assert float(np.max(np.abs(a[0].F_hand))) == 0.0


def test_unstable_plant_fault_equals_python_loop(rhi4, monkeypatch):
    """A physical wall far too stiff for the timestep: MuJoCo diverges; same tick, time, reason and rows."""
    x0 = rhi4.fk(Q0)
    wall = Wall(x0 + [0.0, 0.002], [0.0, 1.0], 5e9, damping=0.0)
    a = run(rhi4, palpation, python=False, physical=wall)
    b = run(rhi4, palpation, python=True, physical=wall, monkeypatch=monkeypatch)
    assert a[0].fault is not None and "unstable" in a[0].fault and len(a[0]) < 400
    assert a[0].safety[-1] == 1.0
    check_same(a[:2], b[:2])


def test_one_compiled_loop_for_every_whole_tick(rhi4):
    """Controllers with different parts run on one compiled loop (compiled once), each on its own whole tick."""
    a = run(rhi4, palpation, python=False, duration=0.05)
    signatures = list(fast_loop.ticks.signatures)
    b = run(rhi4, lambda dev: palpation(dev, passivity=False), python=False, duration=0.05)
    assert a[1]._kernel.parts != b[1]._kernel.parts and a[1]._kernel._whole_fn is not b[1]._kernel._whole_fn
    assert list(fast_loop.ticks.signatures) == signatures and len(signatures) >= 1
    assert a[2].ticks == b[2].ticks == 50


def short_calls(seed: int, handed: list | None = None):
    """A stand-in for `fast_loop.ticks` whose calls end after a random 0–39 ticks and hand the next tick to Python.

    The ticks handed over are appended to `handed` (when given).
    """
    kernel = fast_loop.ticks
    rng = np.random.default_rng(seed)

    def short(count, k0, *args):
        lay = args[11]  # ticks(count, k0, dt, sub, mj, sens, kin, hand, ctrl, F_hand, wargs, cs, st, lay, ...)
        kernel(min(count, int(rng.integers(0, 40))), k0, *args)
        if lay[fast_loop.L_OUT] == fast_loop.DONE and lay[fast_loop.L_DONE] < count:
            lay[fast_loop.L_OUT] = fast_loop.PYTHON
            if handed is not None:
                handed.append(k0 + int(lay[fast_loop.L_DONE]))

    return short


def test_ticks_handed_to_python_resume(rhi4, monkeypatch):
    """Compiled calls that end early and hand ticks to the Python loop (as for a FALLBACK tick), then resume.

    The Python ticks in between advance the controller's FME transition and passivity state from the
    mirrors the compiled calls left, and the compiled calls continue from what Python left.
    """
    handed: list[int] = []
    monkeypatch.setattr(fast_loop, "ticks", short_calls(5, handed))
    a = run(rhi4, palpation, python=False, duration=0.6)
    monkeypatch.undo()
    assert a[2].ticks + len(handed) == 600 and len(handed) > 20
    b = run(rhi4, palpation, python=True, duration=0.6, monkeypatch=monkeypatch)
    check_same(a[:2], b[:2])


def test_stroke_hand_fixture_and_stop_equal_the_python_hand(rhi4, monkeypatch):
    """The §3.5 palpation set-up: a minimum-jerk stroke, a virtual spring wall plus a fixture, a physical stop.

    The reference is the hand's and the environments' own Python `force` at every physics step (neither
    the compiled loop nor the compiled control period).
    """
    from rhi.sim.loop import Session

    x0, u = rhi4.fk(Q0), np.array([0.0, 1.0])

    def once(python: bool):
        if python:
            monkeypatch.setattr(fast_loop.FastLoop, "build", staticmethod(lambda *a, **k: None))
            monkeypatch.setattr(Session, "_compiled", lambda self, hand, phys: None)
        plant = Plant(rhi4)
        plant.reset(Q0)
        ctrl = palpation(rhi4)
        log = simulate(plant, ctrl, duration=0.5, hand=MinimumJerkPalpation(x0, u, 0.03, 0.3, max_force=4.0),
                       virtual=compose(Wall(x0, u, 300.0), Fixture(x0, u, 1000.0, 5.0)),
                       physical=stop(x0 + 0.01 * u, u))
        monkeypatch.undo()
        return log, ctrl, fast_loop.last

    a = once(python=False)
    assert a[2] is not None and a[2].ticks == len(a[0]) == 500
    b = once(python=True)
    assert b[2] is None
    # bit for bit but the 1e-9 floor: the stroke's powers are products in one order in both (libm's pow(τ, 3)
    # rounded differently from Numba's τ·τ² once in a while; the passivity layer's damping, a ratio of energies,
    # carried that to 2e-10 of itself)
    check_same(a[:2], b[:2])
    F = a[0].F_hand @ u
    assert F.max() == pytest.approx(4.0)  # the stroke saturates the hand against the stop
    assert 0.0095 < (a[0].x[-1] - x0) @ u < 0.0105  # on the stop


@pytest.mark.parametrize("port", [None, "motors"])
def test_tank_equals_python_loop(rhi4, monkeypatch, port):
    """The null-space energy tank (beyond.passivity's tank cases): its accounts advance in the compiled ticks.

    Also with ticks handed to Python and back: the tank's slots as they were before a handed tick.
    """
    from rhi.experiments.beyond.passivity import controller

    make = lambda dev: controller(dev, objectives=True, port=port, method="damper", tank=NullSpaceTank())  # noqa: E731
    a = run(rhi4, make, python=False, duration=0.6)
    assert a[2] is not None and a[2].ticks == len(a[0]) == 600
    tank = a[1].state.tank
    assert tank.t == pytest.approx(0.599) and tank.energy != a[1].config.tank.initial
    b = run(rhi4, make, python=True, duration=0.6, monkeypatch=monkeypatch)
    check_same(a[:2], b[:2])
    monkeypatch.setattr(fast_loop, "ticks", short_calls(6))
    c = run(rhi4, make, python=False, duration=0.6)
    monkeypatch.undo()
    assert 0 < c[2].ticks < 600
    check_same(c[:2], b[:2])


def test_tank_probe_records_what_a_python_hook_reads(rhi4):
    """beyond.passivity's `Probe` on the compiled loop records what a plain hook reads on the Python loop.

    The tank's T_O + T_A, λ and μ, the held joints and the passivity λ.
    """
    from rhi.experiments.beyond.passivity import PROBE, controller
    from rhi.sim import Probe

    x0 = rhi4.fk(Q0)

    def once(record):
        plant = Plant(rhi4)
        plant.reset(Q0)
        ctrl = controller(rhi4, objectives=True, port="motors", method="damper", tank=NullSpaceTank())
        hook = record if isinstance(record, Probe) else record(ctrl)
        log = simulate(plant, ctrl, duration=0.6,
                       hand=Hand(HandPath([x0, x0 + [0.01, 0.0], x0 + [0.01, 0.03]], speed=0.05), stiffness=2000.0),
                       virtual=Wall(x0 + [0.0, 0.005], [0, 1], 1000.0), record=hook)
        return log, ctrl, fast_loop.last

    def reads(ctrl):
        def read():
            s = ctrl.state
            return {"pc_scale": ctrl.passivity.scale, "held": s.saturated.copy(), "tank_scale": s.tank.scale,
                    "tank": s.tank.energy + s.tank.allocation, "tank_damping": s.tank.damping}
        return read

    a = once(PROBE)
    assert a[2] is not None and a[2].ticks == 600
    b = once(reads)
    assert b[2] is None
    check_same(a[:2], b[:2])
    assert a[0].extra.keys() == b[0].extra.keys() == set(PROBE.names)
    for name, v in a[0].extra.items():
        np.testing.assert_allclose(v, b[0].extra[name], rtol=0, atol=1e-12, err_msg=name)
    tank = a[0].extra["tank"]
    assert np.ptp(tank) > 0 and np.all(np.isfinite(a[0].extra["tank_scale"]))  # the accounts moved


def _python_hands(monkeypatch):
    """The reference: the Python loop with the hand's own Python `force` at every physics step."""
    from rhi.sim.loop import Session

    monkeypatch.setattr(fast_loop.FastLoop, "build", staticmethod(lambda *a, **k: None))
    monkeypatch.setattr(Session, "_compiled", lambda self, hand, phys: None)


def test_hand_sequence_equals_the_python_hand(rhi4, monkeypatch):
    """A `HandSequence` (a path, a stroke, a hold) switching between physics steps, against a physical stop."""
    x0, u = rhi4.fk(Q0), np.array([0.0, 1.0])
    hand = HandSequence((Hand(HandPath([x0, x0 + 0.004 * u], speed=0.04, start=0.02), stiffness=500.0),
                         MinimumJerkPalpation(x0 + 0.004 * u, u, 0.01, 0.3, stiffness=2000.0, max_force=6.0),
                         Hand(HandPath([x0]), stiffness=400.0, max_force=None)), (0.1503, 0.3001))

    def once(python: bool):
        if python:
            _python_hands(monkeypatch)
        plant = Plant(rhi4)
        plant.reset(Q0)
        ctrl = palpation(rhi4)
        log = simulate(plant, ctrl, duration=0.45, hand=hand, physical=stop(x0 + 0.008 * u, u),
                       virtual=Wall(x0 + 0.005 * u, u, 1000.0))
        monkeypatch.undo()
        return log, ctrl, fast_loop.last

    a = once(python=False)
    assert a[2] is not None and a[2].ticks == len(a[0]) == 450
    b = once(python=True)
    assert b[2] is None
    check_same(a[:2], b[:2], rtol=1e-10)  # the stroke's powers round as in the stroke test
    F = a[0].F_hand @ u
    assert F[100:150].max() > 0.5  # the path pushes
    assert np.linalg.norm(a[0].F_hand, axis=1).max() == pytest.approx(6.0)  # the stroke saturates
    assert abs(F[-1]) < F.max()  # the last hand holds x0


def test_transition_and_free_space_hold_runs_are_compiled(monkeypatch):
    """The set-ups of ch6.transition (ASO-switched FME, `in_out_hand`) and ch3.nullspace_configurations.

    ch3's held handle in free space: the reference is the Python loop with a free-space virtual
    environment (F = 0) rendered in Python, as the experiment ran before it passed none.
    """
    from rhi.control import TransitionConfig
    from rhi.experiments.ch3 import nullspace as ch3
    from rhi.experiments.ch6 import setup as ch6
    from rhi.experiments.ch6.switching import in_out_hand

    dev = rhi.device("rhi4")
    u, x0 = np.array(ch6.U), np.array(ch6.X0)
    _, _, Mf, Ms = ch6.desired_fmes(dev, u, ch6.Q_HOME)
    q_start = dev.ik(x0, ch6.Q_HOME)
    tc = TransitionConfig(eps1=ch6.EPS1, eps2=ch6.EPS2, rho=ch6.RHO, S=ch6.ASO_S)

    class Free:
        def force(self, x, xdot):
            return np.zeros(2)

    def transition(python: bool):
        if python:
            _python_hands(monkeypatch)
        plant = Plant(dev)
        plant.reset(q_start)
        ctrl = ch6.palpation_controller(dev, None, FMESchedule(Mf, Ms, transition=tc), beta=ch6.BETA, limits=True,
                                        null_space="clipped")
        hand = in_out_hand(x0, u, 0.015, 0.03, 0.1, 0.2, 3000.0, 40.0)
        log = simulate(plant, ctrl, duration=1.3, hand=hand)
        monkeypatch.undo()
        return log, ctrl, fast_loop.last

    def hold(python: bool):
        if python:
            _python_hands(monkeypatch)
        x = np.asarray(ch3.POINTS[0], dtype=float)
        plant = Plant(dev)
        plant.reset(ch3.start_configuration(dev, x, "rehab"))
        ctrl = ch3.controller(dev)
        hand = Hand(HandPath([x]), stiffness=ch3.HAND_STIFFNESS, damping=ch3.HAND_DAMPING, max_force=None)
        log = simulate(plant, ctrl, duration=0.4, hand=hand, virtual=Free() if python else None)
        monkeypatch.undo()
        return log, ctrl, fast_loop.last

    logs = []
    for scenario in (transition, hold):
        a = scenario(python=False)
        assert a[2] is not None and a[2].ticks == len(a[0]), scenario.__name__
        assert a[0].meta["route"] == "compiled loop (whole tick)"
        b = scenario(python=True)
        assert b[2] is None and b[0].meta["route"].startswith("python loop")
        check_same(a[:2], b[:2])
        logs.append(a[0])
    assert logs[0].omega.min() == 0.0 and logs[0].omega[-1] > 0.0  # the desired FME moved to M_Stiff and back
    assert np.ptp(logs[1].q[:, 2]) > 1e-3  # ch3: the null space moves under the held handle


def test_python_loop_where_the_compiled_one_does_not_apply(rhi4):
    """A record hook, or a controller that is not a NullSpaceController: the Python loop."""
    plant = Plant(rhi4)
    plant.reset(Q0)
    simulate(plant, palpation(rhi4), duration=0.01, record=lambda: {"k": 1.0})
    assert fast_loop.last is None

    class Zero:
        def step(self, t, q, dq, sensors):
            return np.zeros(4)

    plant.reset(Q0)
    log = simulate(plant, Zero(), duration=0.01)
    assert fast_loop.last is None and len(log) == 10


def test_streamed_log_and_progress(rhi4, tmp_path):
    """Compiled rows stream to a .rhilog like Python rows; progress and telemetry see every tick."""
    from rhi.sim import Telemetry
    from rhi.sim.log import Log

    plant = Plant(rhi4)
    plant.reset(Q0)
    seen, tel = [], Telemetry(every=50)
    log = simulate(plant, palpation(rhi4), duration=0.45, log=tmp_path / "run.rhilog",
                   progress=lambda k, n: seen.append(k), telemetry=tel)
    assert fast_loop.last is not None and fast_loop.last.ticks == 450
    assert seen == [k + 1 for k in range(450) if k % 4 == 0 or k == 449] and tel.count == 9
    back = Log.load(tmp_path / "run.rhilog")
    np.testing.assert_array_equal(back.q, log.q)
    np.testing.assert_array_equal(back.seq, np.arange(450))
    assert np.all(np.isnan(back.t_read)) and np.all(back.t_tick > 0)


def raising_after(kernel, t_raise: float):
    """A whole tick that runs `kernel` until t_raise [s], then raises partway (R_DONE written 0 first, as `whole_for`'s)."""
    from numba import njit

    from rhi.control._compiled import whole as _whole

    names = ", ".join(f"a{i}" for i in range(len(inspect.signature(kernel.py_func).parameters)))
    res = names.rsplit(", ", 1)[1]
    space = {"kernel": kernel, "R_DONE": _whole.R_DONE}
    exec(f"def planted({names}):\n    {res}[R_DONE] = 0.0\n    if a0 >= {t_raise!r}:\n"
         f"        raise ValueError('a planted failure')\n    return kernel({names})\n", space)
    return njit(error_model="numpy")(space["planted"])  # not cached: its source is no file


@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")  # Numba prints what the pointer call ate
def test_tick_that_raises_in_the_compiled_loop_goes_to_python(rhi4, monkeypatch):
    """A whole tick that raises through the compiled loop's pointer call, which lets no exception through.

    The loop must see R_DONE unwritten and hand the tick to Python, whose call raises it, as in the Python loop.
    """
    from rhi.control._compiled import whole as _whole

    real = _whole.whole_for
    monkeypatch.setattr(_whole, "whole_for", lambda parts: raising_after(real(parts), 0.1))
    with pytest.raises(ValueError, match="a planted failure"):
        run(rhi4, palpation, python=False, duration=0.3)
    assert fast_loop.last is not None and fast_loop.last.ticks == 100  # compiled up to the failing tick
    with pytest.raises(ValueError, match="a planted failure"):
        run(rhi4, palpation, python=True, duration=0.3, monkeypatch=monkeypatch)
