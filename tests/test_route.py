"""The seam between what an objective means and how it runs fast: `compiled(device)`, the route, its warning.

A toy objective written in a temporary module (as a user's own file would be) runs in a controller
configuration on the route the controller reports: without ``compiled`` on the composed route (its gradient
in Python, a `RouteWarning` once), with a ``compiled`` form on the whole compiled tick; the simulation log
and the run summary name the route.
"""

from __future__ import annotations

import importlib
import sys
import textwrap
import warnings

import numpy as np
import pytest

from rhi.control import (
    Allocator,
    ControllerConfig,
    FMESchedule,
    ForceRendering,
    JointLimitBarrier,
    NullSpaceController,
    ObjectiveTerm,
    SpringPalpation,
    VMEMatching,
    allocate_lp,
    compiled as compiled_module,
    registry,
)
from rhi.errors import InvalidInput, RouteWarning
from rhi.runtime import SimLink, run
from rhi.runtime.config import load_config
from rhi.sim import Plant, simulate

TOY = '''
"""A user's objective in its own file: pull q towards q0 (nu = w/2 |q - q0|^2)."""

import dataclasses

import numpy as np

from rhi.control.compiled import CompiledObjective
from rhi.control.registry import POSITIVE, REQUIRED, VECTOR, ObjectiveType, register
from rhi.control.schedule import FMESchedule


@dataclasses.dataclass(frozen=True)
class Centering:
    q0: tuple
    weight: float = 1.0

    def value(self, device, q):
        d = np.asarray(q, dtype=float) - self.q0
        return 0.5 * self.weight * float(d @ d)

    def gradient(self, device, q):
        return self.weight * (np.asarray(q, dtype=float) - self.q0)


@dataclasses.dataclass(frozen=True)
class CompiledVME:
    """VME matching written outside rhi, with the compiled form the kernels know."""

    desired: np.ndarray

    def value(self, device, q):
        from rhi.metrics import jbld

        J = device.jacobian(q)
        return float(jbld(self.desired, J @ J.T))

    def gradient(self, device, q):
        from rhi.control.objectives import jbld_velocity_gradient

        return jbld_velocity_gradient(self.desired, device.jacobian(q), device.jacobian_derivative(q))

    def compiled(self, device):
        return CompiledObjective("vme", desired=self.desired)


def _centering(device, torque_max, *, q0, weight):
    return Centering(tuple(q0), weight)


def _compiled_vme(device, torque_max, *, u):
    from rhi.metrics import desired_vme

    return CompiledVME(desired_vme(u, 0.01))


# its registration line: usable in a configuration file as [[controller.objectives]] type = "centering"
register(ObjectiveType("centering", _centering, {"q0": (VECTOR, REQUIRED), "weight": (POSITIVE, 1.0)}))
register(ObjectiveType("compiled_vme", _compiled_vme, {"u": (VECTOR, REQUIRED)}))


class PlainSchedule(FMESchedule):
    """The FME schedule without a compiled form: a scheduled objective the kernels do not know."""

    def compiled(self, device):
        return None
'''

Q0 = np.array([0.3, 0.5, 0.2, 0.4])


@pytest.fixture
def toy(tmp_path, monkeypatch):
    """The toy objectives' module, imported from a temporary folder; route warnings not yet given.

    Its registrations go with the test (a copy of the registry is restored afterwards).
    """
    (tmp_path / "toy_objective.py").write_text(textwrap.dedent(TOY))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(compiled_module, "_WARNED", set())
    monkeypatch.setattr(registry, "_TYPES", dict(registry.objective_types()))
    monkeypatch.delitem(sys.modules, "toy_objective", raising=False)
    return importlib.import_module("toy_objective")


def _config(*terms, **kw) -> ControllerConfig:
    law = ForceRendering(damping=2.0, passivity=None)
    return ControllerConfig(primary=law, objectives=[ObjectiveTerm(o, 1.0) for o in terms], damping=0.5, **kw)


def _torques(ctrl: NullSpaceController) -> np.ndarray:
    out = []
    for k in range(20):
        q = Q0 + 0.05 * np.sin(0.3 * k + np.arange(4))
        out.append(ctrl.step(1e-3 * k, q, 0.2 * np.cos(0.2 * k + np.arange(4)), {"force": np.array([0.0, -3.0])}))
    return np.array(out)


def test_toy_objective_runs_on_the_route_it_reports(rhi4, toy):
    """Without `compiled`: the composed route, said and warned once; its gradient acts, as in the reference."""
    centering = toy.Centering(q0=(0.2, 0.4, 0.3, 0.3), weight=3.0)
    with pytest.warns(RouteWarning, match=r"composed route.*Centering"):
        fast = NullSpaceController(rhi4, _config(centering))
    assert fast.route.name == "composed" and "Centering" in fast.route.reason
    with warnings.catch_warnings():
        warnings.simplefilter("error", RouteWarning)  # once: a second controller with it says nothing
        again = NullSpaceController(rhi4, _config(centering))
        ref = NullSpaceController(rhi4, _config(centering, implementation="reference"))
    assert again.route == fast.route and ref.route.name == "reference"
    tau = _torques(fast)
    np.testing.assert_allclose(tau, _torques(ref), atol=1e-10)
    without = _torques(NullSpaceController(rhi4, _config()))
    assert np.max(np.abs(tau - without)) > 1e-3  # the objective acts


def test_toy_objective_with_a_compiled_form_runs_compiled(rhi4, toy):
    """With `compiled`: the whole compiled tick, the torques of the bundled objective it stands for."""
    bundled = VMEMatching((1.0, 0.0))
    mine = toy.CompiledVME(bundled.desired())
    with warnings.catch_warnings():
        warnings.simplefilter("error", RouteWarning)
        ctrl = NullSpaceController(rhi4, _config(mine, JointLimitBarrier(0.1)))
    assert ctrl.route.name == "whole" and str(ctrl.route) == "whole"
    ref = NullSpaceController(rhi4, _config(bundled, JointLimitBarrier(0.1), implementation="reference"))
    np.testing.assert_allclose(_torques(ctrl), _torques(ref), atol=1e-10)


def test_off_route_configuration_warns_once_and_the_run_names_it(rhi4, toy):
    """An allocation without a compiled branch (HiGHS alone): one warning; the log and summary name the route."""
    law = SpringPalpation(stiffness=200.0, x0=rhi4.fk(Q0), damping=1.0, passivity=None)
    cfg = ControllerConfig(primary=law, saturation=Allocator("lp_highs", allocate_lp))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ctrls = [NullSpaceController(rhi4, cfg) for _ in range(3)]
    said = [w for w in caught if issubclass(w.category, RouteWarning)]
    assert len(said) == 1 and "allocation 'lp_highs'" in str(said[0].message), [str(w.message) for w in caught]
    assert ctrls[0].route.name == "reference"
    plant = Plant(rhi4)
    plant.reset(Q0)
    log = simulate(plant, ctrls[0], duration=0.01)
    assert log.meta["route"].startswith("python loop") and "allocation 'lp_highs'" in log.meta["route"]
    plant.reset(Q0)
    res = run(SimLink(plant), ctrls[1], duration=0.01, realtime=False)
    assert res.summary["route"] == str(ctrls[1].route) and res.log.meta["route"] == str(ctrls[1].route)
    fast = NullSpaceController(rhi4, ControllerConfig(primary=law))
    plant.reset(Q0)
    assert simulate(plant, fast, duration=0.01).meta["route"] == "compiled loop (whole tick)"


def test_scheduled_objective_is_a_term_and_its_route_is_reported(rhi4, toy):
    """The FME schedule is one objective term, compiled on the whole tick (= reference).

    Without its compiled form it runs on the reference route, said and warned; a second scheduled term is refused.
    """
    free, stiff = np.diag([3.0, 120.0]), np.diag([120.0, 3.0])
    sched = FMESchedule(free, stiff)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RouteWarning)
        fast = NullSpaceController(rhi4, _config(sched, VMEMatching((0.0, 1.0))))
    assert fast.route.name == "whole" and fast.schedule == (1.0, sched)
    ref = NullSpaceController(rhi4, _config(sched, VMEMatching((0.0, 1.0)), implementation="reference"))
    np.testing.assert_allclose(_torques(fast), _torques(ref), atol=1e-10)
    assert fast.state.transition == ref.state.transition and fast.state.omega == ref.state.omega
    plain = toy.PlainSchedule(free, stiff)
    with pytest.warns(RouteWarning, match=r"reference route.*PlainSchedule has no compiled form"):
        slow = NullSpaceController(rhi4, _config(plain, VMEMatching((0.0, 1.0))))
    assert slow.route.name == "reference" and "PlainSchedule" in slow.route.reason
    np.testing.assert_allclose(_torques(slow), _torques(ref), atol=1e-10)
    with pytest.raises(InvalidInput, match="at most one scheduled objective"):
        NullSpaceController(rhi4, _config(sched, plain))


CONFIG = """
description = "a toy objective from its own file, by its registered type"
[device]
name = "rhi4"
[controller]
damping = 0.5
[controller.primary]
law = "spring"
stiffness = 200.0
x0 = [0.5, 0.1]
passivity = "off"
{objectives}
[sim]
q0 = [0.3, 0.5, 0.2, 0.4]
"""


def test_toy_objective_from_a_configuration_file(toy, tmp_path):
    """A registered type is usable in TOML with no line in rhi.runtime.config; the run names the route it takes."""
    path = tmp_path / "toy.toml"
    path.write_text(CONFIG.format(objectives='[[controller.objectives]]\ntype = "centering"\ngain = 2.0\n'
                                             "q0 = [0.2, 0.4, 0.3, 0.3]\nweight = 3.0\n"))
    with pytest.warns(RouteWarning, match=r"composed route.*Centering"):  # said when the file is read
        cfg = load_config(path)
    (term,) = cfg.controller_config.objectives
    assert isinstance(term.objective, toy.Centering) and term.gain == 2.0 and term.objective.weight == 3.0
    ctrl = cfg.controller()
    res = run(cfg.sim_link(), ctrl, duration=0.02, realtime=False)
    assert res.summary["route"] == str(ctrl.route) and ctrl.route.name == "composed" and res.log.fault is None
    # a key it does not declare, and a value of the wrong kind, are refused by their key path
    path.write_text(CONFIG.format(objectives='[[controller.objectives]]\ntype = "centering"\ngain = 2.0\n'
                                             "q0 = [0.2, 0.4, 0.3, 0.3]\ncolour = 1\n"))
    with pytest.raises(InvalidInput, match=r"controller.objectives\[0\].colour: unknown key"):
        load_config(path)
    path.write_text(CONFIG.format(objectives='[[controller.objectives]]\ntype = "centering"\ngain = 2.0\nq0 = "x"\n'))
    with pytest.raises(InvalidInput, match=r"controller.objectives\[0\].q0: expected"):
        load_config(path)
    # with a compiled form: the whole compiled tick, no warning
    path.write_text(CONFIG.format(objectives='[[controller.objectives]]\ntype = "compiled_vme"\ngain = 0.5\n'
                                             "u = [0.0, 1.0]\n"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RouteWarning)
        cfg = load_config(path)
        ctrl = cfg.controller()
    res = run(cfg.sim_link(), ctrl, duration=0.02, realtime=False)
    assert ctrl.route.name == "whole" and res.summary["route"] == "whole"
