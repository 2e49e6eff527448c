"""The user's intent as u (issue 15 §2): estimators on seeded synthetic strokes, bit-for-bit equality with known u."""

import numpy as np
import pytest

import rhi
from rhi.control import (
    ControllerConfig,
    FMEMatching,
    ImpedanceControl,
    NullSpaceController,
    ObjectiveTerm,
    SpringPalpation,
    VMEMatching,
)
from rhi.control.intent import FilteredIntent, HMMIntent, KnownIntent, axial_error, primitives
from rhi.control.intent_control import IntentController, IntentFME, IntentVME
from rhi.errors import InvalidInput
from rhi.experiments.beyond.intent import error_and_lag, trained_hmm
from rhi.experiments.ch6 import setup as ch6
from rhi.experiments.setups import path_hand
from rhi.sim import Hand, HandPath, Plant, simulate
from rhi.sim._compiled import fast_loop
from rhi.sim.strokes import synthetic_strokes

#: Stated bounds (measured on 40 test strokes, seed 202: filtered 9.4° / 10.8°, HMM 5.4° / 9.3° mean axial error
#: while moving in 2-D / 3-D; median lag to < 20°: filtered 0.53 s, HMM 0.05 / 0.08 s).
MEAN_ERROR_BOUND_DEG = 15.0
HMM_LAG_BOUND_S = 0.3


@pytest.mark.parametrize("m", [2, 3])
def test_estimators_bounded_error_on_seeded_strokes(m):
    s = synthetic_strokes(8, m=m, seed=202)
    h = trained_hmm(m, strokes=20)
    out = {}
    for name, est in (("filtered", FilteredIntent(m=m, u0=np.eye(m)[0])),
                      ("hmm", HMMIntent(m=m, u0=np.eye(m)[0], kappa=h.kappa, switch=h.switch))):
        U = np.array([est.update(f, v) for f, v in zip(s.force, s.xdot)])
        assert np.allclose(np.linalg.norm(U, axis=1), 1.0)
        out[name] = error_and_lag(s.t, U, s.u_true, s.moving)
        assert out[name]["mean"] < MEAN_ERROR_BOUND_DEG, (name, out[name])
    assert out["hmm"]["lag"] < HMM_LAG_BOUND_S
    assert out["hmm"]["lag"] < out["filtered"]["lag"]  # the learned model reacts faster than the baseline
    # and the same seed gives the same estimates
    s2 = synthetic_strokes(8, m=m, seed=202)
    np.testing.assert_array_equal(s.force, s2.force)


def test_hmm_fit_learns_concentration_from_noise():
    quiet = synthetic_strokes(20, seed=3, force_noise=0.02, speed_noise=0.0002)
    noisy = synthetic_strokes(20, seed=3, force_noise=0.3, speed_noise=0.004)
    k_quiet = HMMIntent.fit(quiet.force, quiet.xdot, quiet.u_true).kappa
    k_noisy = HMMIntent.fit(noisy.force, noisy.xdot, noisy.u_true).kappa
    assert k_quiet > k_noisy > 0


def test_primitives_and_axial_error():
    for m, k in ((2, 90), (3, 400)):
        E = primitives(m, k)
        assert E.shape == (k, m) and np.allclose(np.linalg.norm(E, axis=1), 1.0)
    assert axial_error([1.0, 0.0], [-1.0, 0.0]) == 0.0
    assert np.isclose(axial_error([1.0, 0.0, 0.0], [0.0, 0.0, 2.0]), np.pi / 2)


def _run(dev, ctrl, q0, hand, duration=0.3):
    plant = Plant(dev)
    plant.reset(q0)
    return simulate(plant, ctrl, duration=duration, hand=hand)


def test_known_u_equals_existing_controllers():
    """A known intent gives the existing objectives' torques.

    The static FME and barrier objectives run in the whole compiled tick; the intent ones too, in the compiled
    simulation loop, which writes M_Stiff^des(u) of the known u before each tick: equal to rounding.
    """
    dev = rhi.device("rhi4")
    u, x0 = np.array(ch6.U), np.array(ch6.X0)
    K, zeta, _, Ms = ch6.desired_fmes(dev, u, ch6.Q_HOME)
    q0 = dev.ik(x0, np.array([0.3, 0.5, 0.4, 0.3]))
    hand = lambda: path_hand([x0, x0 + 0.01 * u], 0.02, 0.05, 3000.0, 40.0)  # noqa: E731
    law = SpringPalpation(ch6.K_E, tuple(x0), normal=tuple(u), damping=0.0, coriolis=False, gravity=False)
    common = dict(primary=law, damping=ch6.K_D, saturation="scaling", aso_shape=ch6.ASO_S)
    ref = NullSpaceController(dev, ControllerConfig(objectives=ch6.controller_terms(Ms, dev.torque_max), **common))
    known = KnownIntent(u)
    terms = (ObjectiveTerm(IntentFME(known, K, zeta, dev.torque_max, "stiff"), ch6.BETA),
             ObjectiveTerm(ch6.BARRIER, ch6.LIMIT_GAIN))
    new = IntentController(NullSpaceController(dev, ControllerConfig(objectives=terms, **common)), known)
    a, b = _run(dev, ref, q0, hand()), _run(dev, new, q0, hand())
    assert ref._kernel.whole_ok and new.controller._kernel.whole_ok and fast_loop.last.ticks == len(b) == 300
    np.testing.assert_allclose(a.tau, b.tau, rtol=0, atol=1e-11)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
    # VME matching (ch. 3/5) with the impedance law
    p = HandPath(np.array([x0, x0 + [0.02, 0.0]]), speed=0.05)
    for obj in (VMEMatching((0.0, 1.0), 0.01), IntentVME(KnownIntent([0.0, 1.0]), 0.01)):
        cfg = ControllerConfig(primary=ImpedanceControl(damping=0.3), objectives=(ObjectiveTerm(obj, 1.0),),
                               damping=0.05, saturation="none")
        ctrl = NullSpaceController(dev, cfg)
        log = _run(dev, ctrl if isinstance(obj, VMEMatching) else IntentController(ctrl, obj.source), q0,
                   Hand(p, stiffness=300.0, damping=10.0))
        if isinstance(obj, VMEMatching):
            ref_tau = log.tau
        else:
            np.testing.assert_allclose(log.tau, ref_tau, rtol=0, atol=1e-12)


@pytest.mark.parametrize("estimator", ["filtered", "hmm"])
def test_estimated_intent_runs_the_whole_tick(estimator):
    """`IntentVME` on an estimator: VME matching to the u of each tick inside the whole compiled tick = the reference."""
    dev = rhi.device("rhi4")
    q0 = np.array([0.3, 0.5, 0.4, 0.3])
    x0 = dev.fk(q0)
    logs = {}
    for impl in ("fast", "reference"):
        est = FilteredIntent(m=2, u0=[1.0, 0.0], tau=0.05) if estimator == "filtered" else HMMIntent(m=2, u0=[1.0, 0.0])
        ctrl = NullSpaceController(dev, ControllerConfig(primary=ImpedanceControl(damping=0.3), damping=0.05,
                                                         objectives=(ObjectiveTerm(IntentVME(est, 0.01), 1.0),),
                                                         saturation="none", implementation=impl))
        wrapped = IntentController(ctrl, est)
        hand = Hand(HandPath(np.array([x0, x0 + [0.02, 0.0], x0 + [0.02, 0.02]]), speed=0.1), stiffness=300.0)
        logs[impl] = _run(dev, wrapped, q0, hand, duration=0.5), np.array([h[1] for h in wrapped.history])
        assert (impl == "reference") or ctrl._kernel.whole_ok
    (a, ua), (b, ub) = logs["fast"], logs["reference"]
    assert axial_error(ua[-1], [1.0, 0.0]) > 0.5  # u turned with the motion
    np.testing.assert_allclose(ua, ub, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.tau, b.tau, rtol=0, atol=1e-9)


def test_estimated_u_feeds_the_objective():
    est = FilteredIntent(m=2, u0=[1.0, 0.0], tau=0.01)
    obj = IntentVME(est, 0.01)
    dev = rhi.device("rhi4")
    q = np.array([0.3, 0.5, 0.4, 0.3])
    g0 = obj.gradient(dev, q)
    for _ in range(200):
        est.update([0.0, 2.0], [0.0, 0.02])
    assert axial_error(est.u, [0.0, 1.0]) < 1e-6 and est.confidence > 0.99
    np.testing.assert_allclose(obj.gradient(dev, q), VMEMatching((0.0, 1.0), 0.01).gradient(dev, q), atol=1e-12)
    assert not np.allclose(obj.gradient(dev, q), g0)
    fme = IntentFME(est, 100.0, 3.0, dev.torque_max, "free")
    want = FMEMatching(rhi.control.desired_fme_free([0.0, 1.0], 100.0, 3.0), dev.torque_max)
    np.testing.assert_allclose(fme.gradient(dev, q), want.gradient(dev, q), atol=1e-9)


def test_bad_input():
    with pytest.raises(InvalidInput, match="c_off"):
        FilteredIntent(m=2, u0=[1.0, 0.0], c_on=0.2, c_off=0.5)
    with pytest.raises(InvalidInput, match="tau"):
        FilteredIntent(m=2, u0=[1.0, 0.0], tau=0.0)
    with pytest.raises(InvalidInput, match="u0"):
        FilteredIntent(m=2, u0=[0.0, 0.0])
    with pytest.raises(InvalidInput, match="m"):
        FilteredIntent(m=4, u0=[1.0, 0.0, 0.0, 0.0])
    with pytest.raises(InvalidInput, match="switch"):
        HMMIntent(m=2, u0=[1.0, 0.0], switch=0.0)
    with pytest.raises(InvalidInput, match="force/xdot"):
        FilteredIntent(m=2, u0=[1.0, 0.0]).update([1.0, 0.0, 0.0], [0.0, 0.0])
    with pytest.raises(InvalidInput, match="force/xdot"):
        FilteredIntent(m=2, u0=[1.0, 0.0]).update([np.nan, 0.0], [0.0, 0.0])
    with pytest.raises(InvalidInput, match="count"):
        synthetic_strokes(0)
    with pytest.raises(InvalidInput, match="mode"):
        IntentFME(KnownIntent([1.0, 0.0]), 100.0, 3.0, [1.0, 1.0], "loose")
    with pytest.raises(InvalidInput, match="source"):
        IntentVME(object())
    with pytest.raises(InvalidInput, match="force/xdot"):
        HMMIntent.fit(np.zeros((5, 2)), np.zeros((5, 3)), np.zeros((5, 2)))


def test_intent_palpation_runs_compiled_and_equals_the_python_loop(monkeypatch):
    """beyond.intent_palpation: every run on the compiled loop, its table and arrays equal to the Python loop's.

    The compiled loop writes `IntentFME`'s M_Stiff^des(u) of the estimator's u before each tick.
    """
    from rhi.experiments import setups
    from rhi.experiments.beyond import intent as exin

    routes, simulate_ = [], setups.simulate

    def spy(*args, **kw):
        log = simulate_(*args, **kw)
        routes.append((log.meta["route"], fast_loop.last is not None and fast_loop.last.ticks == len(log)))
        return log

    monkeypatch.setattr(setups, "simulate", spy)
    kw = dict(settle=0.1, depth=0.01, speed=0.02, hold=0.05, starts=1)
    a = exin.intent_palpation(**kw)
    assert routes == [("compiled loop (whole tick)", True)] * 4  # known, filtered, hmm, fixed
    monkeypatch.setattr(fast_loop.FastLoop, "build", staticmethod(lambda *a, **k: None))
    b = exin.intent_palpation(**kw)
    assert [r.startswith("python loop") for r, _ in routes[4:]] == [True] * 4
    ra, rb = a.tables[0].rows, b.tables[0].rows
    assert [r.quantity for r in ra] == [r.quantity for r in rb]
    np.testing.assert_allclose([r.ours for r in ra], [r.ours for r in rb], rtol=1e-9, atol=1e-9)
    assert a.arrays.keys() == b.arrays.keys()
    for key in a.arrays:
        np.testing.assert_allclose(a.arrays[key], b.arrays[key], rtol=1e-9, atol=1e-9, err_msg=key)  # err: deg
