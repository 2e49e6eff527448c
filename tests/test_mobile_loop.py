"""The compiled loop of `simulate_mobile` (`rhi.sim._compiled.mobile_loop`) against its Python loop: same log, same state.

Each run twice from the same start: as `simulate_mobile` chooses (compiled), and with `MobileLoop.build` refusing
(the Python loop and controllers, the reference). Logs equal to 1e-9 (the kinematics are Pinocchio's there, the
kernels' own here: they differ by rounding), the same progress calls, the controller's and the plant's state.
"""

from __future__ import annotations

import numpy as np
import pytest

import rhi
from rhi.control._compiled import mobile, mobile_terms
from rhi.control.mobile import (
    AMDConfig,
    AMDController,
    PinvAccelConfig,
    PinvAccelController,
    WeightedDistributionController,
    WMMKinematics,
    det_terms,
)
from rhi.experiments.appa import Q0
from rhi.sim._compiled import mobile_loop
from rhi.sim.mobile import MobilePlant, SlipModel, circle, simulate_mobile

FIELDS = ("t", "q", "q_true", "dq", "ddq", "x", "x_est", "x_des", "wheels", "base_active", "alpha", "beta", "gamma",
          "eta", "sigma", "dm")


@pytest.fixture(scope="module")
def wmm():
    return rhi.device("wmm")


def run(dev, make, *, python: bool, radius: float, duration: float, dt: float, plant: bool, monkeypatch):
    """(log, controller, plant, progress calls, the compiled loop or None) of one run."""
    if python:
        monkeypatch.setattr(mobile_loop.MobileLoop, "build", staticmethod(lambda *a, **k: None))
    ctl = make(dev, dt)
    p = MobilePlant(dev, slip=SlipModel(seed=2)) if plant else None
    calls: list[tuple[int, int]] = []
    log = simulate_mobile(ctl, circle(dev.fk(Q0), radius, duration=duration, dt=dt), Q0, plant=p,
                          progress=lambda k, K: calls.append((k, K)))
    if python:
        monkeypatch.undo()
    return log, ctl, p, calls, mobile_loop.last


def check_same(a, b) -> None:
    (la, ca, pa, calls_a, _), (lb, cb, pb, calls_b, _) = a, b
    for name in FIELDS:
        x, y = getattr(la, name), getattr(lb, name)
        np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=name)
        np.testing.assert_allclose(np.nan_to_num(x), np.nan_to_num(y), rtol=0, atol=1e-9, err_msg=name)
    assert la.bounds_ok == lb.bounds_ok and la.params == lb.params
    assert calls_a == calls_b
    if isinstance(ca, AMDController):
        sa, sb = ca.state, cb.state
        assert (sa.t, sa.base_active, sa.steps, sa.stop_t0) == (sb.t, sb.base_active, sb.steps, sb.stop_t0)
        assert (sa.stop_v is None) == (sb.stop_v is None)
        if sa.stop_v is not None:
            np.testing.assert_allclose(sa.stop_v, sb.stop_v, rtol=0, atol=1e-12)
    else:
        assert ca.clipped == cb.clipped
    if pa is not None:
        np.testing.assert_array_equal(pa._e, pb._e)  # the slip noise: the same draws
        assert pa._rng.bit_generator.state == pb._rng.bit_generator.state


def amd(dev, dt):
    return AMDController(dev, AMDConfig(dt=dt))


def traditional(dev, dt):
    return PinvAccelController(dev, PinvAccelConfig(dt=dt))


def test_amd_beyond_the_workspace_on_the_plant_equals_python(wmm, monkeypatch):
    """§B.4.3's circle beyond the arm's workspace: the base is enabled, released and stopped (B.20) on the way."""
    kw = dict(radius=0.25, duration=9.0, dt=0.01, plant=True, monkeypatch=monkeypatch)
    a = run(wmm, amd, python=False, **kw)
    assert a[4] is not None and a[4].calls >= 100
    assert a[0].base_active.max() == 1.0 and a[0].alpha.min() <= 1.0 and np.any(a[0].beta > 0)
    b = run(wmm, amd, python=True, **kw)
    assert b[4] is None
    check_same(a, b)


@pytest.mark.parametrize("make, plant", [(traditional, True), (amd, False)])
def test_traditional_and_kinematic_runs_equal_python(wmm, monkeypatch, make, plant):
    kw = dict(radius=0.1, duration=3.0, dt=0.005, plant=plant, monkeypatch=monkeypatch)
    a = run(wmm, make, python=False, **kw)
    assert a[4] is not None
    check_same(a, run(wmm, make, python=True, **kw))


def test_a_tick_for_python_reruns_the_run_in_python(wmm, monkeypatch):
    """A call that hands a tick to Python (as for a singular arm): the run is Python's from its start, equal."""
    kernel = mobile_loop.ticks

    def stop_at_200(k0, k1, *args):
        out = kernel(k0, min(k1, 200), *args)
        if k1 > 200:
            args[3][2][1] = 200  # state: flags[1], the tick for Python
            return mobile_loop.PYTHON
        return out

    kw = dict(radius=0.25, duration=3.0, dt=0.01, plant=True, monkeypatch=monkeypatch)
    monkeypatch.setattr(mobile_loop, "ticks", stop_at_200)
    a = run(wmm, amd, python=False, **kw)
    monkeypatch.undo()
    b = run(wmm, amd, python=True, **kw)
    assert a[3][-len(b[3]):] == b[3] and len(a[3]) > len(b[3])  # progress: to tick 200, then the Python run's
    check_same((a[0], a[1], a[2], b[3], None), b)


def test_other_controllers_keep_the_python_loop(wmm):
    assert mobile_loop.MobileLoop.why_not(WeightedDistributionController(wmm), None).startswith("the controller")
    ctl = amd(wmm, 0.01)
    ctl.step = ctl.step  # replaced on the instance
    assert "replaced" in mobile_loop.MobileLoop.why_not(ctl, None)


def test_kernels_equal_their_python_oracles(wmm):
    """`point_terms` = Pinocchio's position, 6-D Jacobian and drift; `det_terms` = the Python kernel's."""
    kin = WMMKinematics(wmm)
    ints, joints, fc = wmm._fast_maps.chain
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = Q0 + rng.normal(scale=0.4, size=wmm.n)
        dq = rng.normal(scale=0.5, size=wmm.n)
        x, J6, drift = np.empty(3), np.empty((6, wmm.n)), np.empty(3)
        mobile_terms.point_terms(ints, joints, fc, q, dq, x, J6, drift)
        x_ref, J6_ref = kin.jacobian6(q)
        np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-14)
        np.testing.assert_allclose(J6, J6_ref, rtol=0, atol=1e-14)
        np.testing.assert_allclose(drift, kin.drift(q, dq), rtol=0, atol=1e-13)
        grad, hvp = np.empty(wmm.n - 3), np.empty(wmm.n - 3)
        sigma, ok = mobile_terms.det_terms(J6, dq[3:], grad, hvp)
        _, g_ref, h_ref, s_ref = det_terms(J6_ref[:, 3:], dq[3:])
        assert ok and sigma == pytest.approx(s_ref, abs=1e-14)
        np.testing.assert_allclose(grad, g_ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(hvp, h_ref, rtol=1e-12, atol=1e-15)
    J6[:, 3:] = 0.0  # a singular arm: the tick is the Python controller's (which raises)
    assert not mobile_terms.det_terms(J6, dq[3:], grad, hvp)[1]
    assert mobile.SINGULAR != mobile.OK
