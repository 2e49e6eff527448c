"""Run configurations (rhi.runtime.config) and the `rhi run` command: the shipped thesis set-ups, bad files, the CLI."""

from __future__ import annotations

import contextlib
import importlib.util
import json
import re
import signal
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import child_env

import rhi
from rhi.cli import main
from rhi.errors import InvalidInput
from rhi.runtime import run
from rhi.runtime.config import config_path, load_config, parse_config, shipped_configs
from rhi.sim import Log

SHIPPED = ("ch3_vme", "ch5_tmi", "ch6_fme_aso", "ch7_ascm_tertiary", "ch7_full")
BENCH = Path(__file__).parents[1] / "benchmarks" / "bench_runtime.py"


def _bench_module():
    spec = importlib.util.spec_from_file_location("bench_runtime", BENCH)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_thesis_setup_ships():
    assert set(SHIPPED) <= set(shipped_configs())


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_config_runs_over_simlink(name):
    cfg = load_config(name)
    assert cfg.device.name == "rhi4" and cfg.description and cfg.rate == 1000.0
    res = run(cfg.sim_link(), cfg.controller(), duration=0.2, safety=cfg.safety, virtual=cfg.virtual, realtime=False)
    assert res.fault is None, res.fault
    assert res.summary["ticks"] == 200 and len(res.log) == 200
    assert np.all(np.isfinite(res.log.tau)) and np.abs(res.log.tau).max() > 0
    lo, hi = cfg.device.torque_limits
    assert np.all(res.log.tau >= lo - 1e-12) and np.all(res.log.tau <= hi + 1e-12)


def _experiment_controller(name: str):
    """The controller the experiment module builds for the set-up of the shipped configuration `name`."""
    if name == "ch3_vme":
        from rhi.experiments.ch3 import nullspace

        return nullspace.controller(rhi.device("rhi4"))
    if name == "ch5_tmi":
        from rhi.control import TMIMatching
        from rhi.experiments.ch5 import setup as ch5

        dev, slave = rhi.device("rhi4", d2=ch5.D2), rhi.device("rehab_slave")
        qs = slave.ik(dev.fk(ch5.Q_FIXED), ch5.SLAVE_SEED)
        return ch5.controller(dev, TMIMatching(slave, qs, k_q=ch5.K_Q), ch5.GAIN, ch5.NULL_DAMPING)
    if name == "ch6_fme_aso":
        from rhi.control import FMESchedule, TransitionConfig
        from rhi.experiments.ch6 import setup as ch6

        dev = rhi.device("rhi4")
        _, _, Mf, Ms = ch6.desired_fmes(dev, np.array(ch6.U), ch6.Q_HOME)
        tc = TransitionConfig(eps1=ch6.EPS1, eps2=ch6.EPS2, rho=ch6.RHO, S=ch6.ASO_S)
        return ch6.palpation_controller(dev, None, FMESchedule(Mf, Ms, transition=tc))
    if name == "ch7_full":
        return _bench_module().controller(rhi.device("rhi4"))  # the runtime benchmark's full ch7 stack
    from rhi.experiments.ch7 import contact

    return contact.palpation_controller(rhi.device("rhi4"), "ascm")


@pytest.mark.parametrize("name", SHIPPED)
def test_config_controller_equals_the_experiments(name):
    """Same torques and state as the experiment's own controller over 60 seeded ticks (deep contact included)."""
    cfg = load_config(name)
    ours, theirs = cfg.controller(), _experiment_controller(name)
    dev = cfg.device
    rng = np.random.default_rng(7)
    q = np.array(cfg.sim["q0"])
    for k in range(60):
        q = q + rng.normal(0.0, 0.004, dev.n)  # a random walk: the spring/wall compresses, the ASO drains
        dq = rng.normal(0.0, 0.3, dev.n)
        kin = dev.terms(q, dq)
        F = np.zeros(dev.m) if cfg.virtual is None else cfg.virtual.force(kin.x, kin.xdot)
        sensors = {"force": F, "ft": rng.normal(0.0, 2.0, 6)}
        a = ours.step(1e-3 * k, q, dq, sensors)
        b = theirs.step(1e-3 * k, q, dq, sensors)
        np.testing.assert_array_equal(a, b)
        assert (ours.state.V, ours.state.omega, ours.state.alpha) == (theirs.state.V, theirs.state.omega,
                                                                      theirs.state.alpha)
    assert not ours.state.stopped


def test_config_start_and_hand_match_the_experiments():
    from rhi.experiments.ch3 import measures as ch3, nullspace as ch3_control
    from rhi.experiments.ch5 import setup as ch5

    c3 = load_config("ch3_vme")
    np.testing.assert_allclose(c3.sim["q0"], ch3_control.start_configuration(c3.device, ch3.POINTS[0], "rehab"),
                               atol=1e-12)
    np.testing.assert_allclose(c3.sim["hand"].path.points[0], ch3.POINTS[0])
    c5 = load_config("ch5_tmi")
    np.testing.assert_array_equal(c5.sim["q0"], ch5.Q_FIXED)
    np.testing.assert_allclose(c5.sim["hand"].path.points[0], c5.device.fk(ch5.Q_FIXED), atol=1e-12)
    np.testing.assert_allclose(c5.sim["friction"].damping, ch5.GAMMA)
    full, bench = load_config("ch7_full"), _bench_module()
    plant, hand, wall = bench.plant_and_hand(full.device, 60.0)
    n = len(full.sim["hand"].path.points)
    assert n == 41 and full.sim["hand"].path.duration == pytest.approx(60.0)
    np.testing.assert_allclose(full.sim["hand"].path.points, hand.path.points[:n], atol=1e-15)
    np.testing.assert_allclose(full.virtual.point, wall.point, atol=1e-15)
    np.testing.assert_array_equal(full.sim["q0"], bench.Q0)


def _doc(name: str = "ch7_ascm_tertiary") -> dict:
    return tomllib.loads(config_path(name).read_text())


@pytest.mark.parametrize("edit, message", [
    (lambda d: d.update(colour="red"), "colour: unknown key"),
    (lambda d: d["controller"].update(dampning=1.0), "controller.dampning: unknown key"),
    (lambda d: d["controller"]["objectives"][1].update(gain="x"),
     "controller.objectives[1].gain: expected a number >= 0 and <= 1e+06 (plausibility bound), got 'x'"),
    (lambda d: d["controller"]["objectives"][0].update(sigma=1.0), "controller.objectives[0].sigma: unknown key"),
    (lambda d: d["controller"]["objectives"][0].update(type="banana"),
     "controller.objectives[0].type: expected one of"),
    (lambda d: d["controller"]["objectives"][0].pop("gain"), "controller.objectives[0].gain: missing"),
    (lambda d: d["controller"]["objectives"][0].update(desired=[[1.0, 0.0], [0.0]]),
     "controller.objectives[0].desired: expected a matrix"),
    (lambda d: d["controller"]["primary"].pop("law"), "controller.primary.law: missing"),
    (lambda d: d["controller"]["primary"].update(damping=-1.0), "controller.primary: damping: must be >= 0"),
    (lambda d: d["controller"].update(saturation="clip"), "controller.saturation: expected one of 'active_set', 'ascm'"),
    (lambda d: d["controller"].update(torque_max=[3.0, 3.0]), "controller.torque_max: expected shape (4,)"),
    (lambda d: d["controller"].update(damping=True), "controller.damping: expected a number"),
    (lambda d: d["virtual"][0].update(normal=[0.0, 1.0, 0.0]), "virtual[0].normal: expected shape (2,)"),
    (lambda d: d["sim"]["hand"].update(max_force="lots"), "sim.hand.max_force: expected a number > 0 and <= 1000 or \"none\""),
    (lambda d: d["sim"].update(q0=[0.0, 0.0]), "sim.q0: expected shape (4,)"),
    (lambda d: d["run"].update(duration=-1.0), "run.duration: expected a number > 0 and <= 1e+06 (plausibility bound), got -1.0"),
    (lambda d: d.update(safety={"silence_ms": 20}), "safety: unknown setting(s) ['silence_ms']"),
    (lambda d: d.update(safety={"stale_ticks": "3"}), "safety.stale_ticks: expected a number"),
    (lambda d: d.update(safety={"stale_ticks": 0}), "safety.stale_ticks: must be a finite integer > 0"),
    (lambda d: d["device"].update(params={"d9": 0.1}), "device.params: unknown parameter"),
    (lambda d: d["controller"].update(fme={"free_direction": [0.0, 1.0]}), "controller.fme.contact_direction: missing"),
    (lambda d: d["controller"].update(tank={"initial": -1.0}), "controller.tank.initial: expected a number >= 0"),
    (lambda d: d["controller"].update(tank={"initial": 0.2, "capacity": 0.1}), "controller: tank.initial: 0.2 J exceeds"),
    (lambda d: d["controller"].update(tank={"size": 0.1}), "controller.tank.size: unknown key in controller.tank"),
])
def test_bad_config_names_the_key(edit, message):
    d = _doc()
    edit(d)
    with pytest.raises(InvalidInput) as exc:
        parse_config(d)
    assert message in str(exc.value)


def test_null_space_tank_from_the_file():
    """``[controller.tank]`` turns on the null-space energy tank (rhi.control.tank); absent, it is off."""
    from rhi.control import NullSpaceTank

    d = _doc()
    assert parse_config(d).controller().config.tank is None
    d["controller"]["tank"] = {"capacity": 0.2}
    ctrl = parse_config(d).controller()
    assert ctrl.config.tank == NullSpaceTank(initial=0.0, capacity=0.2) and ctrl.state.tank.energy == 0.0


def test_every_saturation_method_of_the_controller_is_accepted():
    import typing

    from rhi.control.allocation import Saturation

    for method in typing.get_args(Saturation):
        d = _doc()
        d["controller"]["saturation"] = method
        assert parse_config(d).controller().config.saturation == method


def test_a_strategy_registered_by_the_user_is_accepted(monkeypatch):
    """A run configuration names any registered strategy, not only the bundled ones (read when the file is)."""
    import dataclasses

    from rhi.control.allocation import Allocator, allocate_scaling, base

    def half(a, b, Z, *, torque_min, torque_max):
        return dataclasses.replace(allocate_scaling(0.5 * a, b, torque_min=torque_min, torque_max=torque_max),
                                   method="half")

    d = _doc()
    d["controller"]["saturation"] = "half"
    known = "'active_set', 'ascm', 'lp', 'none', 'scaling'"
    with pytest.raises(InvalidInput, match=f"controller.saturation: expected one of {known}, got 'half'"):
        parse_config(d)
    monkeypatch.setitem(base._METHODS, "half", Allocator("half", half, safe=False))
    assert parse_config(d).controller().config.saturation == "half"


def test_device_mismatch_and_unknown_file():
    with pytest.raises(InvalidInput, match="device: ch7_ascm_tertiary is written for 'rhi4'"):
        load_config("ch7_ascm_tertiary", device_name="phantom")
    with pytest.raises(InvalidInput, match="config: no file 'ch9_nothing'.*shipped: ch3_vme"):
        load_config("ch9_nothing")


def test_bad_toml_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text("[controller\nlaw = 1")
    with pytest.raises(InvalidInput, match="config: cannot read .*bad.toml.* as TOML"):
        load_config(p)


def test_cli_run_over_sim_writes_summary_and_log(tmp_path, capsys):
    log, summ = tmp_path / "r.rhilog", tmp_path / "s.json"
    assert main(["run", "rhi4", "--config", "ch7_ascm_tertiary", "--duration", "0.3", "--fast",
                 "--log", str(log), "--summary", str(summ)]) == 0
    out = capsys.readouterr().out
    assert "300 ticks" in out and str(summ) in out
    s = json.loads(summ.read_text())
    assert s["ticks"] == 300 and s["fault"] is None and s["config"]["name"] == "ch7_ascm_tertiary"
    assert {"tick", "read_to_write", "missed", "missed_pct", "events", "clamped"} <= set(s)
    lg = Log.load(log)
    assert len(lg) == 300 and lg.tau.shape == (300, 4) and np.all(np.isfinite(lg.tau))
    np.testing.assert_allclose(lg.t[-1], 0.299, atol=1e-9)


def test_cli_fault_exits_nonzero_with_reason(tmp_path, capsys):
    cfg = tmp_path / "tight.toml"
    cfg.write_text(config_path("ch7_ascm_tertiary").read_text() + "\n[safety]\nmax_handle_speed = 1e-9\n")
    summ = tmp_path / "s.json"
    assert main(["run", "rhi4", "--config", str(cfg), "--duration", "0.3", "--fast", "--log",
                 str(tmp_path / "r.rhilog"), "--summary", str(summ)]) == 1
    assert "fault (handle_speed): handle speed" in capsys.readouterr().err
    s = json.loads(summ.read_text())
    assert s["fault_kind"] == "handle_speed" and any(e["kind"] == "handle_speed" for e in s["events"])


@pytest.mark.parametrize("args, message", [
    (["--link", "udp://127.0.0.1"], "--link: link: expected udp://HOST:PORT"),
    (["--link", "tcp://127.0.0.1:5005"], "--link: expected sim or udp://HOST:PORT"),
    (["--link", "udp://127.0.0.1:99999"], "--link: link: cannot parse"),
    (["--duration", "-1"], "argument --duration: must be > 0, got '-1'"),
    (["--rate", "0"], "argument --rate: must be in [10, 100000] Hz"),
    (["--rate", "1500"], "rate: 1500"),
])
def test_cli_bad_arguments_exit_2(args, message, capsys):
    try:
        code = main(["run", "rhi4", "--config", "ch7_ascm_tertiary", "--fast", *args])
    except SystemExit as exc:  # a flag refused by its type: argparse's one-line error
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1, err


@contextlib.contextmanager
def _device_server(*args: str):
    """`rhi device-server ARGS --lockstep --port 0` in a process; yields its port."""
    env = child_env()
    p = subprocess.Popen([sys.executable, "-m", "rhi", "device-server", *args, "--lockstep", "--port", "0"],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        first = p.stdout.readline()
        port = re.search(r"udp://127\.0\.0\.1:(\d+)", first)
        assert port, first + p.stdout.read() if p.poll() is not None else first
        yield int(port.group(1))
    finally:
        p.send_signal(signal.SIGTERM)
        try:
            p.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()


def test_cli_run_over_udp_equals_simlink(tmp_path, capsys):
    """`rhi run` over UDP against `rhi device-server --lockstep` gives the in-process SimLink torques.

    `rhi device-server --config X --lockstep` + `rhi run --link udp://... --config X`: the torques of the
    in-process SimLink run of X (no packet lost). A long device watchdog: a loaded test machine must not trip it.
    """
    summ, log = tmp_path / "s.json", tmp_path / "u.rhilog"
    with _device_server("rhi4", "--config", "ch7_ascm_tertiary", "--watchdog-ms", "5000") as port:
        code = main(["run", "rhi4", "--link", f"udp://127.0.0.1:{port}", "--config", "ch7_ascm_tertiary",
                     "--duration", "0.3", "--fast", "--log", str(log), "--summary", str(summ)])
    assert code == 0, capsys.readouterr().err
    s = json.loads(summ.read_text())
    assert s["ticks"] == 300 and s["fault"] is None and s["config"]["link"].startswith("udp://")
    assert s["link_stats"]["lost"] == 0 and s["link_stats"]["reordered"] == 0
    cfg = load_config("ch7_ascm_tertiary")
    ref = run(cfg.sim_link(), cfg.controller(), duration=0.3, safety=cfg.safety, virtual=cfg.virtual, realtime=False)
    np.testing.assert_allclose(Log.load(log).tau, ref.log.tau, atol=1e-9, rtol=0)
    assert np.abs(ref.log.tau).max() > 0.1


def test_cli_run_refuses_a_device_server_of_another_device(tmp_path, capsys):
    with _device_server("planar3r") as port:
        code = main(["run", "rhi4", "--link", f"udp://127.0.0.1:{port}", "--config", "ch7_ascm_tertiary",
                     "--duration", "0.1", "--fast", "--log", str(tmp_path / "u.rhilog")])
    assert code == 2
    assert "link: the device has 3 motors, the configuration's 'rhi4' has 4" in capsys.readouterr().err


class _Stream:
    def __init__(self, tty: bool) -> None:
        self.tty, self.text = tty, ""

    def isatty(self) -> bool:
        return self.tty

    def write(self, s: str) -> None:
        self.text += s

    def flush(self) -> None:
        pass


def test_status_line_in_place_on_a_terminal_and_every_few_seconds_when_piped():
    from rhi.cli import _Status

    tick = {"t": 1.0, "ticks": 1000, "missed": 2, "max_torque_ratio": 0.5, "V": 0.9, "fault": None}
    for tty, lines in ((True, 4), (False, 1)):
        s = _Stream(tty)
        st = _Status(s, 10.0)
        clock = iter([0.5, 1.0, 2.0, 6.0])  # seconds since the start: piped, only the call at 6 s prints
        st.clock, st.last = (lambda clock=clock: next(clock)), 0.0
        for _ in range(4):
            st(tick)
        st.close()
        if tty:
            assert s.text.count("\r") == lines and s.text.endswith("\n")
        else:
            assert s.text.count("\n") == lines and "\r" not in s.text
        assert "missed 2" in s.text and "max|τ|/limit 0.50" in s.text and "V 0.900" in s.text and "/10 s" in s.text
