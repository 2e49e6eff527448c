"""Property-based bad input on the newer surfaces (issue 24): runtime API, leftovers, CLI flags, configurations, files.

Hypothesis generates the invalid values (derandomized, so the suite is reproducible). A library call must raise an
`rhi.errors` error naming the argument (never a foreign exception, never a result); a CLI flag must end the command
with status 2 and one line on stderr naming the flag, before any work; a damaged file must be refused with an
`rhi.errors` error or read into a consistent object.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from bad_values import NON_FINITE, NOT_A_NUMBER, bad_matrix, bad_object, bad_scalar, bad_vector, cli_exit, examples, expect_error
from hypothesis import given, strategies as st

import rhi
from rhi import control as ctl
from rhi._validate import writable_file
from rhi.errors import InvalidInput, RhiError
from rhi.runtime import SafetyConfig, SimLink, run
from rhi.runtime.config import config_path, parse_config
from rhi.sim import Hand, HandPath, Log, Plant, Wall
from rhi.sim.log import LogWriter, layout

RHI4 = rhi.device("rhi4")
Q4 = np.array([-0.63, 0.25, 0.28, 0.09])

# ------------------------------------------------------------------ the runtime API
def _controller():
    return ctl.NullSpaceController(RHI4, ctl.ControllerConfig(primary=ctl.ForceRendering()))


def _plant():
    p = Plant(RHI4)
    p.reset(Q4)
    return p


PLANT = _plant()


def _run(**kw):
    args = {"link": SimLink(PLANT), "controller": _controller(), "duration": 0.002, "realtime": False, **kw}
    return run(**args)


RUN_ARGS = {
    "link": bad_object(), "controller": bad_object(), "safety": bad_object(), "log": st.one_of(st.integers(),
                                                                                               st.floats(), st.just([1])),
    "virtual": bad_object(), "telemetry": bad_object(), "progress": st.one_of(st.text(max_size=3), st.integers()),
    "rate": bad_scalar(low_ok=0.0),
    "duration": bad_scalar(low_ok=0.001, high_ok=1e6).filter(lambda v: v is not None),  # None: until stopped
    "realtime": st.one_of(st.text(max_size=2), st.integers(2, 5)), "spin": st.one_of(st.text(max_size=2), st.none()),
    "cpu": st.one_of(st.integers(max_value=-1), st.text(max_size=2)), "priority": st.integers(100, 1000),
}


@examples(120)
@given(data=st.data())
def test_run_refuses_generated_bad_arguments(data):
    name = data.draw(st.sampled_from(sorted(RUN_ARGS)), label="argument")
    expect_error(_run, name, **{name: data.draw(RUN_ARGS[name], label="value")})


def test_run_refuses_a_link_of_another_device():
    planar = rhi.device("planar3r")
    p = Plant(planar)
    p.reset(np.zeros(3) + 0.3)
    expect_error(lambda link: run(link, _controller(), duration=0.002, realtime=False), "link", link=SimLink(p))


SIMLINK_ARGS = {"plant": bad_object(), "hand": bad_object(), "physical": bad_object(),
                "rate": bad_scalar(low_ok=0.0)}


@examples(40)
@given(data=st.data())
def test_simlink_refuses_generated_bad_arguments(data):
    name = data.draw(st.sampled_from(sorted(SIMLINK_ARGS)), label="argument")
    value = data.draw(SIMLINK_ARGS[name], label="value")
    expect_error(lambda **kw: SimLink(kw.pop("plant", PLANT), **kw), name, **{name: value})


SAFETY_FIELDS = {"stale_ticks": st.one_of(st.integers(max_value=0), st.floats(0.5, 3.5), NOT_A_NUMBER),
                 "frozen_ticks": st.one_of(st.integers(max_value=0), NOT_A_NUMBER),
                 "frozen_motion": bad_scalar(low_ok=0.0), "silence": bad_scalar(low_ok=0.0),
                 "range_margin": bad_scalar(low_ok=0.0), "max_handle_speed": bad_scalar(low_ok=0.0),
                 "max_joint_speed": st.one_of(NON_FINITE, st.text(max_size=3), st.none(), st.floats(-1e300, 0.0),
                                              st.just([]), st.just([math.nan, 1.0]), st.just({"a": 1}))}


@examples(60)
@given(data=st.data())
def test_safety_config_refuses_generated_bad_fields(data):
    name = data.draw(st.sampled_from(sorted(SAFETY_FIELDS)), label="field")
    expect_error(SafetyConfig, name, **{name: data.draw(SAFETY_FIELDS[name], label="value")})


# ------------------------------------------------------------------ library leftovers
_J = RHI4.jacobian(Q4)
_M = RHI4.mass_matrix(Q4)
_Z = ctl.null_basis(_J, _M)
_TAU = np.array([0.5, -0.3, 0.2, 0.1])
_LIM = {"torque_min": -np.full(4, 0.2), "torque_max": np.full(4, 0.2)}
_WALL = Wall(RHI4.fk(Q4) - [0.0, 0.01], [0.0, 1.0], 1000.0)  # the handle is 1 cm inside it
_HAND = Hand(HandPath([RHI4.fk(Q4), RHI4.fk(Q4) + [0.0, 0.02]], speed=0.02))


def _leftovers():
    """(label, function, valid kwargs, {argument: strategy of invalid values})."""
    alloc = {"a": bad_vector(4), "b": bad_vector(4), "torque_min": st.one_of(bad_vector(4), st.just(np.full(4, 0.1))),
             "torque_max": st.one_of(bad_vector(4), st.just(-np.ones(4)))}
    return [
        ("ascm", ctl.ascm, {"a": _TAU, "b": np.zeros(4), "Z": _Z, **_LIM}, {**alloc, "Z": bad_matrix(4, 2)}),
        ("allocate_lp", ctl.allocate_lp, {"a": _TAU, "b": np.zeros(4), "Z": _Z, **_LIM}, {**alloc, "Z": bad_matrix(4, 2)}),
        ("allocate_scaling", ctl.allocate_scaling, {"a": _TAU, "b": np.zeros(4), **_LIM}, alloc),
        ("output_force", ctl.output_force, {"J": _J, "tau": _TAU}, {"J": bad_matrix(2, 4), "tau": bad_vector(4)}),
        ("null_basis", ctl.null_basis, {"J": _J, "M": _M}, {"J": bad_matrix(2, 4),
                                                             "M": bad_matrix(4, 4, none_is_valid=True)}),
        ("Plant.apply", PLANT.apply, {"tau": np.zeros(4), "force": np.zeros(2)},
         {"tau": bad_vector(4), "force": bad_vector(2, none_is_valid=True)}),
        ("Plant.step", PLANT.step, {"steps": 1}, {"steps": st.one_of(st.integers(max_value=-1), NOT_A_NUMBER,
                                                                     st.floats(0.5, 3.5), st.integers(10**10))}),
        ("Plant.reset", PLANT.reset, {"q": Q4}, {"q": st.one_of(bad_vector(4), st.floats(4.0, 1e6).map(
            lambda v: Q4 + [v, 0, 0, 0]))}),
        ("Wall.force", _WALL.force, {"x": RHI4.fk(Q4), "xdot": np.zeros(2)}, {"x": bad_vector(2), "xdot": bad_vector(2)}),
        ("Hand.force", _HAND.force, {"t": 0.1, "x": RHI4.fk(Q4), "xdot": np.zeros(2)},
         {"x": bad_vector(2), "xdot": bad_vector(2)}),
    ]


LEFTOVERS = _leftovers()


@examples(200)
@given(data=st.data())
def test_library_leftovers_refuse_generated_bad_inputs(data):
    label, fn, valid, bad = data.draw(st.sampled_from(LEFTOVERS), label="function")
    name = data.draw(st.sampled_from(sorted(bad)), label="argument")
    value = data.draw(bad[name], label="value")
    want = "torque_min" if name == "torque_max" and isinstance(value, np.ndarray) and value.shape == (4,) and \
        np.isfinite(value).all() else name  # a negative torque_max: named with its pair
    expect_error(fn, want if want != "torque_min" else "torque", **{**valid, name: value})
    PLANT.reset(Q4)


def test_teleoperation_design_and_sweep_leftovers(tmp_path):
    from rhi.design import sweep
    from rhi.experiments import ch4
    from rhi.sim import Teleoperation

    slave = Plant(rhi.device("planar3r"))
    slave.reset(np.full(3, 0.3))
    tele = Teleoperation(slave)
    for bad in ([np.nan, 0.0], [0.0], "x"):
        expect_error(tele.follow, "x_master", x_master=bad, dt=1e-3)
    for bad in (0.0, -1.0, math.nan):
        expect_error(tele.follow, "dt", x_master=slave.x, dt=bad)
    prob = ch4.setup.problem("theta_z", density=20)
    import dataclasses

    expect_error(lambda **kw: dataclasses.replace(prob, **kw), "fixed", fixed={**prob.fixed, "z_ph": math.nan})
    expect_error(lambda **kw: dataclasses.replace(prob, **kw), "center", center=(math.nan, 0.0))
    for batch in (-1, 0, 1.5, "2"):
        expect_error(sweep, "batch", problem=prob, xs=[[0.0]], batch=batch)


# ------------------------------------------------------------------ the experiments (rhi.experiments.arguments)
def _bad_for(default, optional: bool, zero: bool = False):
    """Invalid values for a parameter whose default is `default` (None passing when `optional`, 0 when `zero`)."""
    none = [] if optional else [st.none()]
    if isinstance(default, bool):
        return st.one_of(st.integers(), st.text(max_size=3), *none)
    if isinstance(default, int):
        low = 1 if default >= 1 else 0
        return st.one_of(st.integers(max_value=low - 1), st.integers(min_value=int(100 * default) + 1).filter(
            lambda v: default > 0), st.floats(0.5, 3.5), st.booleans(), st.text(max_size=3), NON_FINITE, *none)
    if isinstance(default, float):
        parts = [NON_FINITE, st.text(max_size=3), st.booleans(), *none]
        if default > 0:
            parts += [st.floats(max_value=0.0, exclude_max=zero, min_value=-1e300),
                      st.floats(min_value=100 * default, exclude_min=True, max_value=1e300)]
        elif default == 0:
            parts.append(st.floats(max_value=0.0, exclude_max=True, min_value=-1e300))
        return st.one_of(*parts)
    if isinstance(default, str):
        return st.one_of(st.integers(), st.just(["a"]), *none)
    if isinstance(default, tuple):
        entry = NON_FINITE if isinstance(default[0], float) else st.integers() if isinstance(default[0], str) else \
            st.just(1.5)
        return st.one_of(st.text(min_size=1, max_size=3), st.integers(), st.just({"a": 1}),
                         entry.map(lambda e: (*default[:-1], e)), *none)
    return None


def _experiment_arguments():
    """[(id, function, {argument: strategy of invalid values})] for every experiment and plan of the reproduction."""
    import inspect

    from rhi.report.steps import STEPS

    out = []
    for step in STEPS:
        for fn in (step.run, step.plan):
            params = inspect.signature(fn).parameters.values() if fn is not None else ()
            bad = {p.name: b for p in params if p.default is not p.empty and p.default is not None
                   and (b := _bad_for(p.default, "None" in str(p.annotation),
                                      p.name in getattr(fn, "skip_at_zero", ()))) is not None}
            bad.update({"progress": st.one_of(st.text(max_size=2), st.integers())} if "progress" in
                       {p.name for p in params} else {})
            if bad:
                out.append((f"{step.name} ({fn.__name__})", fn, bad))
    return out


@examples(300)
@given(data=st.data())
def test_experiments_refuse_generated_bad_arguments(data):
    """ch7.example_3dof(steps=-1) and the like: an rhi error naming the argument before any work (the plans too)."""
    label, fn, bad = data.draw(st.sampled_from(_EXPERIMENTS), label="experiment")
    name = data.draw(st.sampled_from(sorted(bad)), label="argument")
    expect_error(fn, name, **{name: data.draw(bad[name], label="value")})


_EXPERIMENTS = _experiment_arguments()


# ------------------------------------------------------------------ CLI flags
PORT = st.one_of(st.integers(max_value=-1), st.integers(min_value=65536), st.text(max_size=4))
HOST = st.one_of(st.tuples(st.integers(256, 999), st.integers(0, 255), st.integers(0, 255), st.integers(0, 255))
                 .map(lambda t: ".".join(map(str, t))),
                 st.text(st.sampled_from(" !@#$%^&*()=+[]{};:'\"<>,?/\\|"), min_size=1, max_size=6))
POSITIVE = st.one_of(st.sampled_from(["nan", "inf", "-inf", "0", "-1", "abc", ""]),
                     st.floats(max_value=0.0, allow_nan=False, min_value=-1e300).map(repr))
FINITE = st.sampled_from(["nan", "inf", "-inf", "abc", ""])
DURATION = st.one_of(POSITIVE, st.floats(min_value=1e6, exclude_min=True, max_value=1e300).map(repr))  # MAX_DURATION
WATCHDOG = st.one_of(POSITIVE, st.floats(min_value=1e4, exclude_min=True, max_value=1e300).map(repr))  # <= 10 s
RATE = st.one_of(FINITE, st.floats(max_value=10.0, exclude_max=True, min_value=-1e300).map(repr),
                 st.floats(min_value=1e5, exclude_min=True, max_value=1e300).map(repr))  # [10 Hz, 100 kHz]
ELEVATION = st.one_of(FINITE, st.floats(min_value=90.0, exclude_min=True, max_value=1e300).map(repr))
COUNT = st.one_of(st.integers(max_value=0).map(str), st.sampled_from(["1.5", "abc", ""]))
FLOATS = st.one_of(st.sampled_from(["nan,0,0,0", "0,inf,0,0", "a,b", "", "1;2"]))
# (command line before the flag, flag, invalid values)
FLAGS = [
    (["run", "rhi4", "--config", "ch7_full"], "--duration", DURATION),
    (["run", "rhi4", "--config", "ch7_full"], "--rate", RATE),
    (["run", "rhi4", "--config", "ch7_full"], "--view-port", PORT.map(str)),
    (["run", "rhi4", "--config", "ch7_full"], "--cpu", st.integers(max_value=-1).map(str)),
    (["run", "rhi4", "--config", "ch7_full"], "--priority", st.one_of(st.integers(max_value=0), st.integers(100)).map(str)),
    (["run", "rhi4", "--config", "ch7_full"], "--cpu-latency",
     st.one_of(FINITE, st.floats(max_value=0.0, exclude_max=True, min_value=-1e300).map(repr),
               st.floats(min_value=1e6, exclude_min=True, max_value=1e300).map(repr))),  # [0, 1e6] µs
    (["device-server", "rhi4"], "--port", PORT.map(str)),
    (["device-server", "rhi4"], "--host", HOST),
    (["device-server", "rhi4"], "--rate", RATE),
    (["device-server", "rhi4"], "--watchdog-ms", WATCHDOG),
    (["device-server", "rhi4"], "--duration", DURATION),
    (["device-server", "rhi4"], "--q0", FLOATS),
    (["view"], "--port", PORT.map(str)),
    (["view"], "--host", HOST),
    (["view"], "--duration", DURATION),
    (["render", "rhi4"], "--width", COUNT),
    (["render", "rhi4"], "--height", COUNT),
    (["render", "rhi4"], "--azimuth", FINITE),
    (["render", "rhi4"], "--elevation", ELEVATION),
    (["render", "rhi4"], "--q", FLOATS),
    (["measure", "rhi4", "--q", "0,0,0,0"], "--u", FLOATS),
    (["reproduce", "--only", "ch3"], "--jobs", COUNT),
    (["reproduce", "--only", "ch3"], "--workers", COUNT),
]


@examples(150)
@given(data=st.data())
def test_cli_flags_refuse_generated_bad_values(data, capsys):
    before, flag, values = data.draw(st.sampled_from(FLAGS), label="flag")
    value = data.draw(values, label="value")
    assert cli_exit([*before, f"{flag}={value}"]) == 2, (flag, value)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and flag in err[0] and "Traceback" not in err[0], (flag, value, err)


@examples(12)
@given(which=st.sampled_from(["--log", "--summary"]), where=st.sampled_from(["dir", "proc", "file_parent"]))
def test_cli_run_checks_its_outputs_before_the_run(which, where, tmp_path_factory, capsys):
    tmp = tmp_path_factory.mktemp("out")
    (tmp / "afile").write_text("x")
    target = {"dir": tmp, "proc": Path("/proc/rhi-no/x.json"), "file_parent": tmp / "afile" / "x.json"}[where]
    before = set(Path("out").glob("run-*"))
    assert cli_exit(["run", "rhi4", "--config", "ch7_full", "--duration", "60", which, str(target)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{which}:" in err[0], err
    assert set(Path("out").glob("run-*")) == before  # a refused run leaves no folder behind


def test_an_output_check_leaves_no_folder_behind(tmp_path):
    deep = tmp_path / "a" / "b" / "log.rhilog"
    assert writable_file("--log", deep) == deep and not (tmp_path / "a").exists()
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "afile").write_text("x")
    with pytest.raises(InvalidInput, match="--log: cannot create the folder"):
        writable_file("--log", tmp_path / "a" / "afile" / "c" / "x.rhilog")
    assert [p.name for p in (tmp_path / "a").iterdir()] == ["afile"]


def test_cli_other_bad_combinations(tmp_path, capsys):
    for argv, want in [(["run", "rhi4", "--config", "ch7_full", "--mouse"], "--mouse"),
                       (["render", "rhi4", "-o", str(tmp_path)], "out:"),
                       (["render", "rhi4", "-o", str(tmp_path / "x.txt")], "out:"),
                       (["view", str(tmp_path / "cut.rhilog")], "path:")]:
        if want == "path:":
            (tmp_path / "cut.rhilog").write_bytes(b"RHILOG\x00\x01\x02")
        assert cli_exit(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and want in err[0], (argv, err)


# ------------------------------------------------------------------ run configurations
SHIPPED = tomllib.loads(config_path("ch7_full").read_text())
BOUNDED = {("run", "rate"), ("run", "duration"), ("controller", "damping"), ("sim", "timestep"),
           ("sim", "hand", "repeat"), ("sim", "hand", "speed"), ("sim", "hand", "stiffness"),
           ("safety", "range_margin"), ("controller", "objectives", 0, "gain"), ("virtual", 0, "stiffness")}


def _paths(d, prefix=()):
    """Every key path of a parsed TOML document (tables and arrays of tables walked)."""
    items = d.items() if isinstance(d, dict) else enumerate(d) if isinstance(d, list) and d and isinstance(
        d[0], dict) else ()
    for k, v in items:
        yield (*prefix, k)
        yield from _paths(v, (*prefix, k))


PATHS = sorted(_paths(SHIPPED), key=str)
TOML_VALUES = st.one_of(st.text(max_size=4), st.booleans(), st.integers(-10**9, 10**9), st.floats(),
                        st.just(1e300), st.just(-1e300), st.lists(st.floats(-1, 1), max_size=5),
                        st.just({"nested": {"deeper": 1}}), st.just([[1.0, 2.0, 3.0]] * 3))


def _edit(doc, path, value):
    doc = json.loads(json.dumps(doc))
    node = doc
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return doc


@examples(200)
@given(data=st.data())
def test_run_configuration_keys_with_generated_values(data):
    """Any value at any key path: a RunConfig or an rhi.errors error naming the key path; absurd sizes refused."""
    path = data.draw(st.sampled_from(PATHS), label="key path")
    value = data.draw(TOML_VALUES, label="value")
    try:
        parse_config(_edit(SHIPPED, path, value))
    except RhiError as exc:
        top = str(path[0])
        assert top in str(exc) or "device" in str(exc), (path, value, str(exc))
        return
    except Exception as exc:  # noqa: BLE001 - the point of the suite
        pytest.fail(f"{path}={value!r:.60}: foreign {type(exc).__name__}: {exc}")
    assert not (path in BOUNDED and isinstance(value, float) and abs(value) >= 1e300), (path, value)


def test_run_configuration_bombs_and_device_checks():
    bad = [
        (("sim", "hand", "repeat"), 10**9, "sim.hand.repeat"),
        (("controller", "torque_max"), [100.0] * 4, "controller.torque_max"),
        (("sim", "q0"), [10.0] * 4, "sim.q0"),
        (("run", "rate"), 0.001, "run.rate"),
        (("safety", "max_joint_speed"), 1e300, "safety.max_joint_speed"),
        (("sim", "friction"), {"damping": 1e300}, "sim.friction.damping"),
        (("controller", "objectives"), [{"type": "joint_limits", "gain": 1.0, "margin": 1e300}],
         "controller.objectives[0].margin"),
    ]
    for path, value, name in bad:
        expect_error(lambda doc: parse_config(doc), name, doc=_edit(SHIPPED, path, value))
    ell = _edit(SHIPPED, ("controller", "objectives"), [{"type": "ellipsoid", "gain": 1.0, "desired": np.eye(3).tolist()}])
    expect_error(lambda doc: parse_config(doc), "controller.objectives[0].desired", doc=ell)
    deep: dict = {}
    node = deep
    for _ in range(5000):
        node["a"] = {}
        node = node["a"]
    expect_error(lambda doc: parse_config(doc), "sim.a", doc={**SHIPPED, "sim": deep})


def test_a_deeply_nested_configuration_file_is_refused(tmp_path):
    from rhi.runtime.config import load_config

    path = tmp_path / "deep.toml"
    path.write_text("description = " + "[" * 100000 + "]" * 100000 + "\n")
    expect_error(lambda config: load_config(config), "config", config=path)


# ------------------------------------------------------------------ .rhilog files
def _log_file(path: Path) -> bytes:
    w = LogWriter(layout(4, 2), path, meta={"device": "rhi4"}, chunk=4)
    for k in range(10):
        row = w.row()
        row[:] = 0.0
        row[0] = k * 1e-3
    w.event(0.005, "info", "hello", 5)
    w.close()
    return path.read_bytes()


@examples(150)
@given(data=st.data())
def test_rhilog_reader_on_generated_damage(data, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("log")
    path = tmp / "run.rhilog"
    raw = bytearray(_log_file(path))
    events = path.with_name(path.name + ".events.jsonl")
    kind = data.draw(st.sampled_from(["cut", "byte", "length", "events", "time"]), label="damage")
    if kind == "cut":
        path.write_bytes(bytes(raw[:data.draw(st.integers(0, len(raw) - 1), label="at")]))
    elif kind == "byte":
        i = data.draw(st.integers(0, len(raw) - 1), label="at")
        raw[i] = data.draw(st.integers(0, 255), label="byte")
        path.write_bytes(bytes(raw))
    elif kind == "length":
        raw[8:16] = data.draw(st.integers(0, 2**64 - 1), label="length").to_bytes(8, "little")
        path.write_bytes(bytes(raw))
    elif kind == "events":
        line = data.draw(st.one_of(st.binary(max_size=20), st.sampled_from(
            [b"[1, 2]", b"3", b'"x"', b'{"t": 1}', b'{"t": "a", "kind": 1, "detail": 2, "tick": 3}'])), label="line")
        events.write_bytes(events.read_bytes() + line + b"\n" + b'{"closed": true}\n')
    else:
        t = np.frombuffer(bytes(raw), dtype="<f8", offset=len(raw) - 10 * 8 * sum(w for _, w in layout(4, 2)))
        k = data.draw(st.integers(1, 9), label="row")
        value = data.draw(st.sampled_from([math.nan, math.inf, -1.0]), label="t")
        width = sum(w for _, w in layout(4, 2))
        pos = len(raw) - (10 - k) * 8 * width
        raw[pos:pos + 8] = np.float64(value).tobytes()
        path.write_bytes(bytes(raw))
        assert t.size
    try:
        log = Log.load(path)
    except RhiError as exc:
        assert "path" in str(exc) or "events" in str(exc), str(exc)
        return
    except Exception as exc:  # noqa: BLE001 - the point of the suite
        pytest.fail(f"{kind}: foreign {type(exc).__name__}: {exc}")
    assert len(log) == 0 or (np.isfinite(log.t).all() and (np.diff(log.t) >= 0).all())
    assert kind not in ("time",), "a damaged time column was read"


# ------------------------------------------------------------------ checkpoints
def _checkpoint(path: Path):
    from rhi.design import EvalCache

    path.unlink(missing_ok=True)
    c = EvalCache(path, tag="t")
    c.map(_score, [[0.1], [0.2], [0.3], [0.4]], lambda f, xs: [f(x) for x in xs])


def _score(x):
    return {"C2": float(x[0]) * 2.0, "coverage": 1.0}


@examples(80)
@given(data=st.data())
def test_checkpoint_reader_on_generated_edits(data, tmp_path_factory):
    """Edits with a recomputed checksum: refused (InvalidInput) on load or when a recomputed entry differs."""
    from rhi.design import EvalCache
    from rhi.design.checkpoint import _digest

    path = tmp_path_factory.mktemp("ck") / "ck.json"
    _checkpoint(path)
    blob = json.loads(path.read_text())
    keys = sorted(blob["results"])
    key = data.draw(st.sampled_from(keys), label="entry")
    field = data.draw(st.sampled_from(["C2", "coverage", "key", "drop", "type"]), label="edit")
    value = data.draw(st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=3), st.none()),
                      label="value")
    res = blob["results"]
    if field == "key":
        res[str(value)] = res.pop(key)
    elif field == "drop":
        del res[key]["C2"]
    elif field == "type":
        res[key] = value
    else:
        res[key][field] = value
    blob["sha256"] = _digest(blob["tag"], res)
    path.write_text(json.dumps(blob))
    try:
        c = EvalCache(path, tag="t", spot_checks=len(keys))  # every loaded entry recomputed with the first batch
        c.map(_score, [[float.fromhex(k)] for k in keys], lambda f, xs: [f(x) for x in xs])
    except RhiError as exc:
        assert "checkpoint" in str(exc), str(exc)
        return
    except Exception as exc:  # noqa: BLE001 - the point of the suite
        pytest.fail(f"{field}={value!r}: foreign {type(exc).__name__}: {exc}")
    for k, r in c.data.items():  # accepted: nothing wrong is replayed
        assert r == _score([float.fromhex(k)]), (field, value, k, r)
