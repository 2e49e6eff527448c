"""Property-based bad-input suite.

Every generated call with one invalid argument must raise an `rhi.errors` error whose message names that argument —
never a foreign exception, never a result.

Each case is a public function, a valid call, and per argument the kinds of corruption that make
it invalid. Hypothesis draws (case, argument, kind, position, magnitude); the draws are
derandomized so the suite is reproducible. `CALLS` counts the calls made; each suite checks it made
as many as it asked for (450 + 250 + 200 + 200 + 150 = 1,250 in all).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import rhi
from rhi.errors import RhiError

ARRAY = ("str", "none", "complex", "object", "nan", "inf", "empty")
SCALAR = ("str", "none", "complex", "nan", "inf")
NAME = ("unknown", "none", "int")


@dataclasses.dataclass(frozen=True)
class Case:
    """fn(**valid()) is a valid call; `bad` maps each argument to the corruption kinds to try."""

    label: str
    fn: Callable
    valid: Callable[[], dict]
    bad: dict[str, tuple[str, ...]]
    names: dict[str, str] = dataclasses.field(default_factory=dict)  # argument -> name the error must contain

    def triples(self):
        return [(self, arg, kind) for arg, kinds in self.bad.items() for kind in kinds]


def corrupt(value, kind: str, pos: int, mag: float):
    """An invalid version of `value` of the given kind (pos/mag pick where and how much)."""
    if kind == "str":
        return "abc"
    if kind == "none":
        return None
    if kind == "int":
        return 7
    if kind == "unknown":
        return "no_such_name"
    if kind == "zero_scalar":
        return 0.0
    if kind == "tiny":
        return 1e-5
    if kind == "negative_scalar":
        return -abs(mag) - 1e-3
    if kind == "empty":
        return np.zeros((0,))
    a = np.array(value, dtype=float, copy=True)
    flat = a.reshape(-1)
    i = pos % max(flat.size, 1)
    if kind == "complex":
        return a + 1j
    if kind == "object":
        return np.array([None] * max(a.size, 1), dtype=object).reshape(a.shape if a.size else (1,))
    if kind == "nan":
        flat[i] = np.nan
        return a if a.ndim else float(flat[0])
    if kind == "inf":
        flat[i] = np.inf if pos % 2 else -np.inf
        return a if a.ndim else float(flat[0])
    if kind == "negative":
        flat[i] = -abs(mag) - 1e-3
        return a if a.ndim else float(flat[0])
    if kind == "zero":
        flat[i] = 0.0
        return a if a.ndim else float(flat[0])
    if kind == "zeros":
        return np.zeros_like(a)
    if kind == "shape":  # one entry too many along the last axis
        return np.concatenate([a, a[..., :1]], axis=-1) if a.ndim else np.array([float(a), 1.0])
    if kind == "ndim":  # one dimension too few
        return a[0] if a.ndim else a
    if kind == "asym":
        a[..., 0, -1] += 1.0 + abs(mag)
        return a
    if kind == "nonspd":
        return -a
    if kind == "huge":
        flat[i] = 1e6 + abs(mag)
        return a if a.ndim else float(flat[0])
    raise AssertionError(kind)


CALLS = {"n": 0}


def check(case: Case, arg: str, kind: str, pos: int, mag: float) -> None:
    kwargs = case.valid()
    kwargs[arg] = corrupt(kwargs[arg], kind, pos, mag)
    CALLS["n"] += 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # a NaN computed on the way is a failure too
        warnings.filterwarnings("ignore", category=UserWarning)
        try:
            out = case.fn(**kwargs)
        except RhiError as exc:
            want = case.names.get(arg, arg)
            assert want in str(exc), f"{case.label}({arg}={kind}): error does not name {want!r}: {exc}"
            return
        except Exception as exc:  # noqa: BLE001 - the point of the suite
            pytest.fail(f"{case.label}({arg}={kind}): foreign {type(exc).__name__}: {exc}")
    pytest.fail(f"{case.label}({arg}={kind}): accepted, returned {out!r:.200}")


def run_suite(triples, data) -> None:
    case, arg, kind = data.draw(st.sampled_from(triples), label="case")
    pos = data.draw(st.integers(0, 1000), label="pos")
    mag = data.draw(st.floats(0.0, 1e3), label="mag")
    check(case, arg, kind, pos, mag)


def suite_settings(n: int):
    return settings(max_examples=n, derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# ------------------------------------------------------------------ metrics
_R = np.random.default_rng(7)
J34 = _R.normal(size=(3, 4))
_B = _R.normal(size=(4, 4))
M44 = _B @ _B.T + 4 * np.eye(4)
U3 = np.array([1.0, 0.5, -0.2])
TMAX = np.array([2.0, 2.0, 1.0, 1.0])
A33 = np.array([[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 0.5]])
JS = _R.normal(size=(3, 3))
m = rhi.metrics
MAT = ARRAY + ("ndim",)
SPD = ARRAY + ("ndim", "asym", "nonspd")
DIR = ARRAY + ("zeros", "shape")
POS = ARRAY + ("negative", "zero", "shape")
NONNEG = ARRAY + ("negative", "shape")
POS_SCALAR = SCALAR + ("negative_scalar", "zero_scalar")
NONNEG_SCALAR = SCALAR + ("negative_scalar",)


def opt(kinds: tuple[str, ...]) -> tuple[str, ...]:
    """The kinds for an optional argument (None is valid there)."""
    return tuple(k for k in kinds if k != "none")


def _v(**kw):
    return lambda: {k: (np.array(v, copy=True) if isinstance(v, np.ndarray) else v) for k, v in kw.items()}


METRICS = [
    Case("apparent_inertia", m.apparent_inertia, _v(J=J34, M=M44), {"J": MAT, "M": SPD}),
    Case("effective_inertia", m.effective_inertia, _v(J=J34, M=M44, u=U3), {"J": MAT, "M": SPD, "u": DIR}),
    Case("dynamic_pinv", m.dynamic_pinv, _v(J=J34, M=M44), {"J": MAT, "M": opt(SPD)}),
    Case("nullspace_projector", m.nullspace_projector, _v(J=J34, M=M44), {"J": MAT, "M": opt(SPD)}),
    Case("weighted_pinv", m.weighted_pinv, _v(J=J34, Q=M44), {"J": MAT, "Q": opt(SPD)}),
    Case("velocity_nullspace_projector", m.velocity_nullspace_projector, _v(J=J34, Q=M44), {"J": MAT, "Q": opt(SPD)}),
    Case("effective_manipulability", m.effective_manipulability, _v(J=J34, u=U3), {"J": MAT, "u": DIR}),
    Case("velocity_transmission", m.velocity_transmission, _v(J=J34, u=U3), {"J": MAT, "u": DIR}),
    Case("reflected_friction", m.reflected_friction, _v(J=J34, u=U3), {"J": MAT, "u": DIR}),
    Case("directional_manipulability", m.directional_manipulability, _v(J=J34, u=U3, torque_max=TMAX),
         {"J": MAT, "u": DIR, "torque_max": POS}),
    Case("force_ellipsoid", m.force_ellipsoid, _v(J=J34, torque_max=TMAX), {"J": MAT, "torque_max": opt(POS)}),
    Case("velocity_ellipsoid", m.velocity_ellipsoid, _v(J=J34), {"J": MAT}),
    Case("manipulability", m.manipulability, _v(J=J34), {"J": MAT}),
    Case("isotropy", m.isotropy, _v(J=J34), {"J": MAT}),
    Case("ellipsoid_axes", m.ellipsoid_axes, _v(A=A33), {"A": SPD}),
    Case("jbld", m.jbld, _v(A=A33, B=A33 + np.eye(3)), {"A": SPD, "B": SPD}),
    Case("desired_vme", m.desired_vme, _v(u=U3, beta=0.1), {"u": ARRAY + ("zeros",), "beta": POS_SCALAR}),
    Case("desired_fme", m.desired_fme, _v(u=U3, major=2.0, minor=1.0),
         {"u": ARRAY + ("zeros",), "major": POS_SCALAR, "minor": POS_SCALAR}),
    Case("max_force_scaling", m.max_force_scaling, _v(J=J34, u=U3, torque_min=-TMAX, torque_max=TMAX),
         {"J": MAT, "u": DIR, "torque_min": ARRAY + ("huge", "shape"), "torque_max": ARRAY + ("negative", "shape")}),
    Case("max_force", m.max_force, _v(J=J34, u=U3, torque_min=-TMAX, torque_max=TMAX, M=M44, projector="dynamic"),
         {"J": MAT, "u": DIR, "torque_min": ARRAY + ("huge", "shape"), "torque_max": ARRAY + ("negative", "shape"),
          "M": SPD, "projector": NAME}),
    Case("global_index", m.global_index, _v(values=np.linspace(0.1, 1, 5), weights=np.ones(5)),
         {"values": ARRAY, "weights": opt(ARRAY) + ("negative", "shape", "zeros")}),
    Case("joint_limit_penalty", m.joint_limit_penalty,
         _v(q=np.zeros(4), q_min=-np.ones(4), q_max=np.ones(4), k_q=1.0),
         {"q": ARRAY + ("shape",), "q_min": ARRAY + ("huge", "shape"), "q_max": ARRAY + ("shape",), "k_q": SCALAR}),
    Case("penalized_jacobian", m.penalized_jacobian,
         _v(J=J34, q=np.zeros(4), q_min=-np.ones(4), q_max=np.ones(4), k_q=1.0),
         {"J": MAT, "q": ARRAY + ("shape",), "q_min": ARRAY + ("huge",), "k_q": SCALAR}),
    Case("teleoperation_ellipsoid", m.teleoperation_ellipsoid, _v(J_master=J34, J_slave=JS, H=np.eye(3)),
         {"J_master": MAT, "J_slave": MAT, "H": opt(MAT)}),
    Case("tmi", m.tmi, _v(J_master=J34, J_slave=JS), {"J_master": MAT, "J_slave": MAT}),
    Case("joint_energy", m.joint_energy, _v(tme=A33, xdot=U3), {"tme": SPD, "xdot": ARRAY + ("shape",)}),
]
METRIC_TRIPLES = [t for c in METRICS for t in c.triples()]


@suite_settings(450)
@given(data=st.data())
def _metrics_refuse_bad_inputs(data):
    run_suite(METRIC_TRIPLES, data)


def test_metrics_refuse_bad_inputs():
    before = CALLS["n"]
    _metrics_refuse_bad_inputs()
    assert CALLS["n"] - before >= 450  # every generated example made one call


# ------------------------------------------------------------- device, loaders
DEV = rhi.device("planar3r")
Q3 = np.array([0.3, 0.4, 0.5])
X2 = DEV.fk(Q3)
QV = ARRAY + ("shape",)
CHAIN_URDF = (
    '<robot name="r">' + '<link name="l0"/>' + "".join(
        f'<link name="l{i}"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" '
        f'iyz="0"/></inertial></link>' for i in range(1, 4)) + "".join(
        f'<joint name="j{i}" type="revolute"><parent link="l{i - 1}"/><child link="l{i}"/><origin xyz="0.3 0 0"/>'
        f'<axis xyz="0 0 1"/><limit effort="2" velocity="1" lower="-2" upper="2"/></joint>' for i in range(1, 4))
    + "</robot>")
LOADER = dict(path=CHAIN_URDF, ee_frame="l3", task="xy", ee_offset=np.zeros(3), lock=None, armature=np.zeros(3),
              torque_min=-np.ones(3), torque_max=np.ones(3))

DEVICE = [
    Case("Device.fk", DEV.fk, _v(q=Q3), {"q": QV}),
    Case("Device.jacobian", DEV.jacobian, _v(q=Q3), {"q": QV}),
    Case("Device.jacobian_derivative", DEV.jacobian_derivative, _v(q=Q3), {"q": QV}),
    Case("Device.mass_matrix", DEV.mass_matrix, _v(q=Q3), {"q": QV}),
    Case("Device.gravity", DEV.gravity, _v(q=Q3), {"q": QV}),
    Case("Device.theta", DEV.theta, _v(q=Q3), {"q": QV}),
    Case("Device.within_limits", DEV.within_limits, _v(q=Q3), {"q": QV}),
    Case("Device.skeleton", DEV.skeleton, _v(q=Q3), {"q": QV}),
    Case("Device.coriolis", DEV.coriolis, _v(q=Q3, dq=Q3), {"q": QV, "dq": QV}),
    Case("Device.terms", DEV.terms, _v(q=Q3, dq=Q3), {"q": QV + ("ndim",), "dq": opt(QV)}),
    Case("Device.ik", DEV.ik, _v(x=X2, q0=Q3, weights=np.ones(3)),
         {"x": ARRAY + ("shape", "huge"), "q0": QV, "weights": opt(ARRAY) + ("negative", "zero", "shape")}),
    Case("Device.lock(value)", lambda value: DEV.lock({"q1": value}), _v(value=0.1), {"value": SCALAR + ("huge",)},
         names={"value": "lock['q1']"}),
    Case("Device.lock(name)", lambda name: DEV.lock({name: 0.1}), _v(name="q1"), {"name": NAME}, names={"name": "lock"}),
    Case("device", rhi.device, _v(name="rhi4"), {"name": NAME}),
    Case("device(d2)", lambda d2: rhi.device("rhi4", d2=d2), _v(d2=0.141),
         {"d2": SCALAR + ("huge", "negative_scalar")}),
    Case("device_from_urdf", rhi.device_from_urdf, lambda: dict(LOADER),
         {"path": ("unknown", "none", "int", "str"), "ee_frame": NAME, "task": NAME,
          "ee_offset": opt(ARRAY) + ("shape",), "armature": opt(ARRAY) + ("negative", "shape"),
          "torque_min": opt(ARRAY) + ("huge", "shape"), "torque_max": opt(ARRAY) + ("negative", "zero", "shape")}),
    Case("device_from_urdf(lock)", lambda value: rhi.device_from_urdf(CHAIN_URDF, ee_frame="l3", lock={"j1": value}),
         _v(value=0.1), {"value": SCALAR + ("huge",)}, names={"value": "lock['j1']"}),
    Case("device_from_urdf(friction)",
         lambda damping: rhi.device_from_urdf(CHAIN_URDF, ee_frame="l3", friction={"damping": damping}),
         _v(damping=np.zeros(3)), {"damping": opt(ARRAY) + ("negative", "shape")}, names={"damping": "damping"}),
    Case("device_from_mjcf", rhi.device_from_mjcf, _v(path="x.xml", ee_frame="tip"), {"path": ("unknown", "none", "int")}),
    Case("description_path", rhi.description_path, _v(robot="panda"), {"robot": NAME}),
    Case("all_measures", rhi.all_measures, _v(device=DEV, q=Q3, u=np.array([1.0, 0.0])),
         {"q": QV, "u": opt(ARRAY) + ("zeros", "shape")}),
]
DEVICE_TRIPLES = [t for c in DEVICE for t in c.triples()]


@suite_settings(250)
@given(data=st.data())
def _device_and_loaders_refuse_bad_inputs(data):
    run_suite(DEVICE_TRIPLES, data)


def test_device_and_loaders_refuse_bad_inputs():
    before = CALLS["n"]
    _device_and_loaders_refuse_bad_inputs()
    assert CALLS["n"] - before >= 250  # every generated example made one call


# ------------------------------------------------------------------ control
from rhi import control as ctl, sim  # noqa: E402  (each section imports what it tests)

RHI4 = rhi.device("rhi4")
Q4 = np.deg2rad([30.0, 40.0, 20.0, 60.0])


def _controller(**cfg):
    return ctl.NullSpaceController(RHI4, ctl.ControllerConfig(**{"primary": ctl.ForceRendering(), **cfg}))


CTRL = _controller()


def _step(t, q, dq, force):
    c = _controller()
    return c.step(t, q, dq, {"force": force})


CONTROL = [
    Case("ControllerConfig", _controller,
         _v(damping=0.1, saturation="ascm", projector="dynamic", implementation="fast", aso_shape=50.0,
            torque_min=-np.ones(4), torque_max=np.ones(4)),
         {"damping": SCALAR + ("negative_scalar",), "saturation": NAME, "projector": NAME, "implementation": NAME,
          "aso_shape": POS_SCALAR, "torque_min": opt(ARRAY) + ("huge", "shape"),
          "torque_max": opt(ARRAY) + ("negative", "zero", "shape")}),
    Case("ControllerConfig(primary)", lambda primary: _controller(primary=primary), _v(primary=ctl.ForceRendering()),
         {"primary": ("none", "int", "str")}),
    Case("NullSpaceController.step", _step, _v(t=0.0, q=Q4, dq=np.zeros(4), force=np.zeros(2)),
         {"t": SCALAR, "q": QV, "dq": QV, "force": ARRAY + ("shape",)}, names={"force": "sensors['force']"}),
    Case("ObjectiveTerm", lambda gain: _controller(objectives=(ctl.ObjectiveTerm(ctl.Manipulability(), gain),)),
         _v(gain=0.1), {"gain": SCALAR + ("negative_scalar",)}),
    Case("VMEMatching", lambda u, beta: ctl.VMEMatching(u, beta), _v(u=np.array([0.0, 1.0]), beta=0.01),
         {"u": ARRAY + ("zeros",), "beta": POS_SCALAR}),
    Case("ForceRendering", ctl.ForceRendering, _v(damping=0.0, gain=1.0),
         {"damping": ARRAY + ("negative",), "gain": SCALAR}),
    Case("ImpedanceControl", ctl.ImpedanceControl, _v(damping=0.0, inertia=np.eye(2), sensor="ft"),
         {"damping": ARRAY + ("negative",), "inertia": opt(SPD), "sensor": NAME}),
    Case("SpringPalpation", ctl.SpringPalpation, _v(stiffness=100.0, x0=np.array([0.3, 0.2]), normal=np.array([0.0, 1.0])),
         {"stiffness": NONNEG_SCALAR, "x0": ARRAY, "normal": opt(ARRAY) + ("zeros",)}),
    Case("JointFriction", ctl.JointFriction, _v(viscous=0.1, coulomb=0.01, velocity_scale=0.01),
         {"viscous": ARRAY + ("negative",), "coulomb": ARRAY + ("negative",), "velocity_scale": POS_SCALAR}),
    Case("JointLimitBarrier", ctl.JointLimitBarrier, _v(margin=0.1, weight=1.0, kind="quadratic"),
         {"margin": POS_SCALAR, "weight": SCALAR + ("negative_scalar",), "kind": NAME}),
    Case("aso_volume", ctl.aso_volume, _v(tau=np.zeros(4), torque_min=-np.ones(4), torque_max=np.ones(4), S=50.0),
         {"tau": QV, "torque_min": ARRAY + ("huge",), "torque_max": ARRAY + ("negative",), "S": POS_SCALAR}),
]
CONTROL_TRIPLES = [t for c in CONTROL for t in c.triples()]


@suite_settings(200)
@given(data=st.data())
def _control_refuses_bad_inputs(data):
    run_suite(CONTROL_TRIPLES, data)


def test_control_refuses_bad_inputs():
    before = CALLS["n"]
    _control_refuses_bad_inputs()
    assert CALLS["n"] - before >= 200  # every generated example made one call


# ---------------------------------------------------------------------- sim
PLANT = sim.Plant(RHI4)


def _simulate(duration, rate):
    plant = sim.Plant(RHI4)
    plant.reset(Q4)
    return sim.simulate(plant, _controller(), duration=duration, rate=rate)


SIM = [
    Case("Plant", sim.Plant, _v(device=RHI4, timestep=5e-4, handle_mass=1e-3, friction="device"),
         {"device": ("none", "int", "str"), "timestep": POS_SCALAR, "handle_mass": SCALAR + ("negative_scalar",),
          "friction": ("unknown", "int")}),
    Case("Plant.reset", PLANT.reset, _v(q=Q4, dq=np.zeros(4)), {"q": QV, "dq": opt(QV)}),
    Case("simulate", _simulate, _v(duration=0.002, rate=1000.0),
         {"duration": POS_SCALAR + ("tiny",), "rate": POS_SCALAR}),
    Case("Wall", sim.Wall, _v(point=np.zeros(2), normal=np.array([0.0, 1.0]), stiffness=100.0, damping=0.0),
         {"point": ARRAY, "normal": ARRAY + ("zeros", "shape"), "stiffness": NONNEG_SCALAR,
          "damping": SCALAR + ("negative_scalar",)}),
    Case("Spring", sim.Spring, _v(point=np.zeros(2), stiffness=100.0, damping=0.0, direction=np.array([1.0, 0.0])),
         {"point": ARRAY, "stiffness": NONNEG_SCALAR, "damping": SCALAR + ("negative_scalar",),
          "direction": opt(ARRAY) + ("zeros", "shape")}),
    Case("Fixture", sim.Fixture, _v(point=np.zeros(2), direction=np.array([1.0, 0.0]), stiffness=100.0, damping=1.0),
         {"point": ARRAY, "direction": ARRAY + ("zeros", "shape"), "stiffness": NONNEG_SCALAR,
          "damping": SCALAR + ("negative_scalar",)}),
    Case("HandPath", sim.HandPath, _v(points=np.array([[0.3, 0.2], [0.35, 0.2]]), speed=0.02, start=0.0),
         {"points": ARRAY, "speed": NONNEG_SCALAR + ("zero_scalar",), "start": SCALAR}),
    Case("w_path", sim.w_path, _v(center=np.array([0.3, 0.2]), width=0.08, height=0.04, speed=0.02),
         {"center": ARRAY, "width": POS_SCALAR, "height": POS_SCALAR, "speed": POS_SCALAR}),
    Case("Hand", lambda path, stiffness, damping, max_force: sim.Hand(path, stiffness, damping, max_force),
         _v(path=sim.w_path(np.array([0.3, 0.2])), stiffness=300.0, damping=10.0, max_force=20.0),
         {"path": ("none", "int", "str"), "stiffness": NONNEG_SCALAR, "damping": SCALAR + ("negative_scalar",),
          "max_force": opt(POS_SCALAR)}),
    Case("PushForce", sim.PushForce, _v(direction=np.array([1.0, 0.0]), magnitude=1.0, start=0.0),
         {"direction": ARRAY + ("zeros",), "magnitude": SCALAR, "start": SCALAR}),
]
SIM_TRIPLES = [t for c in SIM for t in c.triples()]


@suite_settings(200)
@given(data=st.data())
def _sim_refuses_bad_inputs(data):
    run_suite(SIM_TRIPLES, data)


def test_sim_refuses_bad_inputs():
    before = CALLS["n"]
    _sim_refuses_bad_inputs()
    assert CALLS["n"] - before >= 200  # every generated example made one call


# ------------------------------------------------------------------ analysis
from rhi.analysis import psychophysics as psy, stats, sysid  # noqa: E402  (each section imports what it tests)

G = {"a": np.array([1.0, 2.0, 3.5, 4.0]), "b": np.array([2.0, 2.5, 4.0, 5.5]), "c": np.array([0.5, 1.0, 1.5, 3.0])}
STIM = np.repeat([30.0, 40.0, 50.0, 60.0, 70.0], 8)
RESP = (np.arange(STIM.size) % 8 < np.repeat([1, 2, 4, 6, 7], 8)).astype(float)


def _group(fn):
    return lambda a: fn({"a": a, "b": G["b"], "c": G["c"]})


ANALYSIS = [
    Case("one_way_anova", _group(stats.one_way_anova), _v(a=G["a"]), {"a": ARRAY + ("ndim",)}, names={"a": "groups['a']"}),
    Case("repeated_measures_anova", _group(stats.repeated_measures_anova), _v(a=G["a"]), {"a": ARRAY + ("shape",)},
         names={"a": "groups"}),
    Case("paired_t_tests", _group(stats.paired_t_tests), _v(a=G["a"]), {"a": ARRAY + ("shape",)}, names={"a": "groups"}),
    Case("describe", lambda a: stats.describe({"a": a}), _v(a=G["a"]), {"a": ARRAY}, names={"a": "groups['a']"}),
    Case("adjust", stats.adjust, _v(p_values=np.array([0.01, 0.2, 0.5]), correction="holm", alpha=0.05),
         {"p_values": ARRAY + ("huge", "negative"), "correction": NAME, "alpha": SCALAR + ("huge", "zero_scalar")}),
    Case("fit_psychometric", psy.fit_psychometric, _v(comparison=STIM, response=RESP, confidence=0.95),
         {"comparison": ARRAY + ("negative", "shape"), "response": ARRAY + ("huge", "shape"),
          "confidence": SCALAR + ("huge", "zero_scalar")}),
    Case("sysid.Record", sysid.Record, _v(time=np.arange(50) * 1e-3, position=np.linspace(0, 0.01, 50),
                                          force=np.linspace(0, 1, 50)),
         {"time": ARRAY + ("shape",), "position": ARRAY + ("shape",), "force": ARRAY + ("shape",)}),
    Case("sysid.project", sysid.project, _v(positions=np.zeros((50, 2)), forces=np.zeros((50, 2)), u=np.array([1.0, 0.0])),
         {"positions": ARRAY, "forces": ARRAY, "u": ARRAY + ("zeros", "shape")}),
    Case("sysid.lowpass", sysid.lowpass, _v(signal=np.linspace(0, 1, 200), sample_rate=1000.0, cutoff_hz=20.0),
         {"signal": ARRAY, "sample_rate": POS_SCALAR, "cutoff_hz": POS_SCALAR + ("huge",)}),
]
ANALYSIS_TRIPLES = [t for c in ANALYSIS for t in c.triples()]


@suite_settings(150)
@given(data=st.data())
def _analysis_refuses_bad_inputs(data):
    run_suite(ANALYSIS_TRIPLES, data)


def test_analysis_refuses_bad_inputs():
    before = CALLS["n"]
    _analysis_refuses_bad_inputs()
    assert CALLS["n"] - before >= 150  # every generated example made one call


def test_degenerate_statistics_and_fits_refused():
    const = {"a": np.ones(5), "b": np.ones(5), "c": np.ones(5)}
    with pytest.raises(rhi.errors.InvalidInput, match="groups: no variance"):
        stats.one_way_anova(const)
    with pytest.raises(rhi.errors.InvalidInput, match="groups: no residual variance"):
        stats.repeated_measures_anova(const)
    shifted = {"a": np.arange(5.0), "b": np.arange(5.0) + 1, "c": np.arange(5.0) + 3}  # additive offsets only
    with pytest.raises(rhi.errors.InvalidInput, match="groups: no residual variance"):
        stats.repeated_measures_anova(shifted)
    with pytest.raises(rhi.errors.InvalidInput, match="response: .*every response is 0"):
        psy.fit_psychometric(STIM, np.zeros_like(STIM))
    with pytest.raises(rhi.errors.InvalidInput, match="response: .*every response is 1"):
        psy.fit_psychometric(STIM, np.ones_like(STIM))
    t = np.arange(2000) * 1e-3
    flat = sysid.Record(t, 0.01 * np.sin(2 * np.pi * t), np.full(t.size, 0.5))
    with pytest.raises(rhi.errors.InvalidInput, match="records: the force is constant"):
        sysid.identify(flat)
    still = sysid.Record(t, np.zeros(t.size), np.sin(t))
    with pytest.raises(rhi.errors.InvalidInput, match="records: .*not independently excited"):
        sysid.identify(still)

