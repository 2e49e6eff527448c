"""App. A's controller on the compiled loop (`rhi.sim._compiled.velocity_loop`) against the Python loop and controller.

The kernel twin (`rhi.control._compiled.mobile_velocity.velocity_tick`) equals `WeightedDistributionController.step`
to 1e-12 on random configurations, every stage and setting; whole runs (App. A's tracking on the plant, the DM
phases kinematic) equal the Python loop's to 1e-9, the same progress calls and the plant's state.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_mobile_loop import FIELDS

import rhi
from rhi.control._compiled import mobile_velocity as vel
from rhi.control.mobile import DMConfig, WeightedConfig, WeightedDistributionController
from rhi.experiments.appa import Q0
from rhi.sim._compiled import velocity_loop
from rhi.sim.mobile import MobilePlant, SlipModel, circle, hold, simulate_mobile

DM = DMConfig()
SETTINGS = {
    "proposed": WeightedConfig(dt=0.01, dm=DM),
    "proposed_generalized": WeightedConfig(dt=0.01, weighting="generalized", dm=DM),
    "traditional": WeightedConfig(dt=0.01, distribution="pinv_generalized"),
    "traditional_wheel_speeds": WeightedConfig(dt=0.01, distribution="pinv", dm=DM),
    "weighted_null_printed": WeightedConfig(dt=0.01, null_space="weighted",
                                            dm=dataclasses.replace(DM, gradient="printed", axes="xz", x_min=(-9.0, 0.36),
                                                                   x_max=(9.0, 0.56))),
}


@pytest.fixture(scope="module")
def wmm():
    return rhi.device("wmm")


@pytest.mark.parametrize("name", list(SETTINGS))
def test_velocity_tick_equals_the_python_controller(wmm, name):
    ctl = WeightedDistributionController(wmm, SETTINGS[name])
    prm = velocity_loop.settings(ctl)
    b = ctl.bounds
    bnd = np.array([b.q_min, b.q_max, b.dq_min, b.dq_max, b.ddq_min, b.ddq_max])
    ints, joints, fc = wmm._fast_maps.chain
    rng = np.random.default_rng(7)
    stages = ("track", "dm_cartesian", "dm_null") if ctl.config.dm is not None else ("track",)
    for k in range(60):
        q = np.clip(Q0 + rng.normal(scale=0.5, size=wmm.n), b.q_min, b.q_max)
        bounded = np.flatnonzero(np.isfinite(b.q_min[3:]) & np.isfinite(b.q_max[3:])) + 3
        if k % 4 == 0:  # a joint at a position bound: held in the null space, bounded rates
            i = rng.choice(bounded)
            q[i] = b.q_max[i] if rng.uniform() < 0.5 else b.q_min[i]
        xd = wmm.fk(q) + rng.normal(scale=0.1, size=3)
        dxd = rng.normal(scale=0.2, size=3)
        for stage in stages:
            cmd = ctl.step(0.0, q, xd, dxd, stage=stage)
            x, dq, rec = np.empty(3), np.empty(wmm.n), np.empty(3)
            code = {"track": vel.TRACK, "dm_cartesian": vel.DM_CARTESIAN, "dm_null": vel.DM_NULL}[stage]
            assert vel.velocity_tick(prm, bnd, ints, joints, fc, code, q, xd, dxd, x, dq, rec) == vel.OK
            np.testing.assert_allclose(x, cmd.x, rtol=0, atol=1e-12)
            np.testing.assert_allclose(dq, cmd.dq, rtol=1e-12, atol=1e-12, err_msg=f"{stage} {k}")
            np.testing.assert_allclose(rec, [cmd.gamma, cmd.eta, cmd.dm], rtol=1e-12, atol=1e-12, err_msg=stage)


def test_unbounded_dm_is_left_to_python(wmm):
    """Jᵀu = 0 (the DM is unbounded; the Python controller raises): the kernel says so."""
    ctl = WeightedDistributionController(wmm, WeightedConfig(dm=dataclasses.replace(DM, u=(0.0, 0.0, 1.0))))
    prm = velocity_loop.settings(ctl)
    prm[vel.N_PARAMS + 3:vel.N_PARAMS + 3 + ctl.m] = 1.0
    prm[vel.N_PARAMS:vel.N_PARAMS + 3] = 0.0  # u = 0: Jᵀu = 0
    b = ctl.bounds
    bnd = np.array([b.q_min, b.q_max, b.dq_min, b.dq_max, b.ddq_min, b.ddq_max])
    ints, joints, fc = wmm._fast_maps.chain
    x, dq, rec = np.empty(3), np.empty(wmm.n), np.empty(3)
    assert vel.velocity_tick(prm, bnd, ints, joints, fc, vel.DM_NULL, Q0, np.zeros(3), np.zeros(3), x, dq,
                             rec) == vel.RAISES


def run(ctl, traj, q0, *, python: bool, plant, stage, monkeypatch):
    """(log, plant, progress calls, the compiled loop or None) of one run."""
    if python:
        monkeypatch.setattr(velocity_loop.VelocityLoop, "build", staticmethod(lambda *a, **k: None))
    calls: list[tuple[int, int]] = []
    log = simulate_mobile(ctl, traj, q0, plant=plant, stage=stage, progress=lambda k, K: calls.append((k, K)))
    if python:
        monkeypatch.undo()
    return log, plant, calls, velocity_loop.last


def check_same(a, b) -> None:
    (la, pa, calls_a, _), (lb, pb, calls_b, _) = a, b
    for name in FIELDS:
        x, y = getattr(la, name), getattr(lb, name)
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
        np.testing.assert_allclose(np.nan_to_num(x), np.nan_to_num(y), rtol=0, atol=1e-9, err_msg=name)
    assert la.bounds_ok == lb.bounds_ok and la.params == lb.params
    assert calls_a == calls_b
    if pa is not None:
        np.testing.assert_array_equal(pa._e, pb._e)  # the slip noise: the same draws
        assert pa._rng.bit_generator.state == pb._rng.bit_generator.state


@pytest.mark.parametrize("name", ["proposed", "traditional", "traditional_wheel_speeds", "proposed_generalized"])
def test_appa_tracking_on_the_plant_equals_python(wmm, monkeypatch, name):
    """§A.4.2's circle beyond the arm's workspace (the first 12 s: the base starts moving at ~7 s), on the plant."""
    traj = circle(wmm.fk(Q0), 0.25, duration=12.0, dt=0.01)
    runs = []
    for python in (False, True):
        ctl = WeightedDistributionController(wmm, dataclasses.replace(SETTINGS[name], dm=None))
        runs.append(run(ctl, traj, Q0, python=python, plant=MobilePlant(wmm, slip=SlipModel(seed=2)), stage="track",
                        monkeypatch=monkeypatch))
    a, b = runs
    assert a[3] is not None and a[3].calls >= 100 and b[3] is None
    assert np.abs(a[0].base_velocity).max() > 1e-3  # the base moves
    if name.startswith("proposed"):
        assert np.nanmax(a[0].gamma) > 0.0 and np.nanmin(a[0].gamma) == 0.0  # γ adapts
    check_same(a, b)


def test_dm_phases_kinematic_equal_python(wmm, monkeypatch):
    """App. A's DM enhancement (`_dm_phase`): the Cartesian stage, then the null-space stage, kinematic."""
    ctl = WeightedDistributionController(wmm, SETTINGS["proposed"])
    x0 = wmm.fk(Q0)
    for stage, dur in (("dm_cartesian", 3.0), ("dm_null", 3.0)):
        a = run(ctl, hold(x0, duration=dur, dt=0.01), Q0, python=False, plant=None, stage=stage, monkeypatch=monkeypatch)
        b = run(ctl, hold(x0, duration=dur, dt=0.01), Q0, python=True, plant=None, stage=stage, monkeypatch=monkeypatch)
        assert a[3] is not None and b[3] is None
        assert a[0].dm[-1] > a[0].dm[0]  # the DM grows
        check_same(a, b)
    stage = lambda t: "track" if t < 1.0 else "dm_null"  # noqa: E731  (a stage that changes with time)
    a = run(ctl, hold(x0, duration=2.0, dt=0.01), Q0, python=False, plant=None, stage=stage, monkeypatch=monkeypatch)
    b = run(ctl, hold(x0, duration=2.0, dt=0.01), Q0, python=True, plant=None, stage=stage, monkeypatch=monkeypatch)
    assert a[3] is not None
    check_same(a, b)


def test_runs_the_compiled_loop_does_not_take(wmm):
    ctl = WeightedDistributionController(wmm, WeightedConfig(dt=0.01))
    traj = hold(wmm.fk(Q0), duration=0.1, dt=0.01)
    simulate_mobile(ctl, traj, Q0, stage="track")
    assert velocity_loop.last is not None
    with pytest.raises(rhi.errors.InvalidInput, match="needs config.dm"):  # no DMConfig: the Python loop raises
        simulate_mobile(ctl, traj, Q0, stage="dm_null")
    assert velocity_loop.last is None
    ctl.step = ctl.step  # replaced on the instance
    assert "replaced" in velocity_loop.VelocityLoop.why_not(ctl)
