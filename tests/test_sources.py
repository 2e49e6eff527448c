"""The torque by source of a compiled tick (rhi.control.sources) equals the reference's parts; the energy books agree."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rhi.control import NullSpaceController, WeightedSum
from rhi.control.sources import TickSources
from rhi.experiments.beyond import passivity as P
from rhi.experiments.beyond.sources import source_work
from rhi.experiments.ch6 import setup as ch6


def _palpation(dev, case: str, duration: float = 0.6):
    """A short §6.4 palpation of `beyond.passivity`'s case (its controller, hand and wall): (controller, log)."""
    from rhi.sim import Hand, HandPath, Plant, Wall, simulate

    x0, u = np.array(ch6.X0), np.array(ch6.U)
    _, _, _, Ms = ch6.desired_fmes(dev, u, ch6.Q_HOME)
    q0 = ch6.best_match(dev, x0, WeightedSum(ch6.controller_terms(Ms, dev.torque_max)), starts=1)
    objectives, port, saturation, method, tank = P.CASES[case]
    ctrl = P.controller(dev, objectives=objectives, port=port, saturation=saturation, method=method, tank=tank)
    hand = Hand(HandPath(np.array([x0, x0 - P.OUT * u, x0 + P.DEPTH * u]), speed=0.05, start=0.05),
                stiffness=P.HAND[0], damping=P.HAND[1], max_force=P.HAND[2])
    plant = Plant(dev)
    plant.reset(q0)
    return ctrl, simulate(plant, ctrl, duration=duration, hand=hand, virtual=Wall(x0, u, P.K_E))


@pytest.mark.parametrize("case", ["objectives", "objectives_damper", "objectives_tank_damper", "scaling", "passive_empty"])
def test_compiled_split_equals_the_reference_parts_tick_by_tick(rhi4, case):
    """Each source's torque from the compiled split = `reference_tick`'s parts at the same inputs, to 1e-9 N m."""
    ctrl, log = _palpation(rhi4, case)
    fast = NullSpaceController(rhi4, ctrl.config)
    ref = NullSpaceController(rhi4, dataclasses.replace(ctrl.config, implementation="reference"))
    split = TickSources(fast)
    assert split.reason == ""
    ref.sources = {}
    held = compared = 0
    for k in range(len(log.t)):
        t, q, dq, sensors = float(log.t[k]), log.q[k], log.dq[k], {"force": log.F_env[k], "ft": log.ft[k]}
        fast.sources = {}
        tau = fast.step(t, q, dq, sensors)
        ref.step(t, q, dq, sensors)
        assert list(ref.sources) == split.names
        rows = np.array([fast.sources[name] for name in split.names]) if fast.sources else split(q, dq)
        assert rows is not None
        np.testing.assert_allclose(rows, np.array(list(ref.sources.values())), atol=1e-9, rtol=0)
        assert np.all(rows.sum(axis=0) <= ctrl.hi + 1e-12) and np.all(rows.sum(axis=0) >= ctrl.lo - 1e-12)
        if ctrl._pc is None:
            np.testing.assert_allclose(rows.sum(axis=0), tau, atol=1e-12, rtol=0)  # no passivity layer after it
        held += bool(fast.state.saturated.any())
        compared += 1
    assert compared == len(log.t) and held > 10  # the run saturates: the allocation and held parts are exercised


def test_energy_books_of_the_compiled_twin_equal_the_reference_twin(rhi4):
    """`source_work` with the controller's compiled twin = with a reference twin (the oracle), to 1e-9 J."""
    ctrl, log = _palpation(rhi4, "objectives_tank_damper")
    fast, err = source_work(rhi4, ctrl.config, log)
    ref, err_ref = source_work(rhi4, dataclasses.replace(ctrl.config, implementation="reference"), log)
    assert list(fast) == list(ref)
    np.testing.assert_allclose(list(fast.values()), list(ref.values()), atol=1e-9, rtol=0)
    assert err == 0.0 and err_ref < 1e-9  # the compiled twin is the simulated controller's own tick
    # both dampers acted (the allocation's, H&R's on the self-motion, takes out little here beside the series PC)
    assert abs(ref["tank damper"]) > 1e-8 and abs(ref["passivity controller"]) > 1e-6


def test_a_controller_without_the_whole_compiled_tick_is_not_split_here(rhi4):
    """The reference controller (and any tick that is not the whole compiled one) keeps the reference replay."""
    ctrl = P.controller(rhi4, objectives=True, port=None)
    ref = NullSpaceController(rhi4, dataclasses.replace(ctrl.config, implementation="reference"))
    assert TickSources(ref).reason != ""
    assert TickSources(ctrl).reason == ""
