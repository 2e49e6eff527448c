"""Runtime faults a link adds, injected over UDP through a real proxy process and, where they apply, over SimLink.

Each must give zero torque from the fault tick, latched, with the reason and the time in the log, and the log and
the summary complete on disk. Sessions of protocol v1.1 against `DeviceServer` processes, too.
"""

from __future__ import annotations

import dataclasses
import json
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_runtime import _scenario, _sim_run
from test_udp import _server, _stop

import rhi
from rhi.control import ControllerConfig, ImpedanceControl, NullSpaceController
from rhi.errors import LinkError
from rhi.runtime import SafetyConfig, SimLink, protocol as P, run
from rhi.runtime.config import load_config
from rhi.runtime.inject import Inject
from rhi.runtime.udp import SessionLost, UDPLink
from rhi.sim import Log

HERE = Path(__file__).parent
pytestmark = pytest.mark.realtime  # real processes on real clocks: run alone (./run tests -m realtime)


@pytest.fixture(scope="module")
def dev():
    return rhi.device("rhi4")


def _proxy(port: int, *args: str) -> tuple[subprocess.Popen, int]:
    p = subprocess.Popen([sys.executable, str(HERE / "udp_proxy.py"), str(port), *args], stdout=subprocess.PIPE,
                         text=True)
    return p, int(p.stdout.readline())


def _proxied_run(dev, tmp_path: Path, server: tuple[str, ...], proxy: tuple[str, ...], *, timeout: float,
                 duration: float, log: str, safety: SafetyConfig):
    """`run` of `_scenario` over UDP through `udp_proxy.py` (`proxy` options) to a device server (`server` options).

    The run's log is written to tmp_path / log; the proxy and the server are stopped after it.
    """
    p, port = _server(tmp_path, *server)
    px, pport = _proxy(port, *proxy)
    try:
        plant, ctrl, hand, wall, phys = _scenario(dev)
        link = UDPLink("127.0.0.1", pport, timeout=timeout)
        return run(link, ctrl, duration=duration, virtual=wall, log=tmp_path / log, safety=safety)
    finally:
        px.kill()
        _stop(p)


def _safe_stop(res, log_path: Path, kind: str) -> float:
    """The run stopped on `kind`: zero torque from the fault tick, the reason and time in the log on disk."""
    s = res.summary
    assert s["fault_kind"] == kind, res.fault
    on_disk = Log.load(log_path)
    assert len(on_disk) == len(res.log) == s["ticks"] and on_disk.fault == res.fault
    k = int(np.flatnonzero(on_disk.safety)[0])  # the fault tick
    np.testing.assert_array_equal(on_disk.tau[k:], 0.0)
    ev = [e for e in on_disk.events if e.kind == kind]
    assert ev and ev[0].tick == k and ev[0].detail == res.fault
    json.dumps(s)  # the summary is complete and serialisable
    return float(on_disk.t[k])


def test_constant_link_delay_trips_the_round_trip_age(dev, tmp_path):
    """30 ms round trip (15 ms each way through the proxy): commands and readings flow, the age says how old."""
    res = _proxied_run(dev, tmp_path, (), ("--delay", "0.015"), timeout=5e-4, duration=3.0, log="d.rhilog",
                       safety=SafetyConfig(stale_ticks=100, silence=0.1))
    _safe_stop(res, tmp_path / "d.rhilog", "latency")
    age = float(res.fault.split("round-trip age ")[1].split(" ms")[0])
    assert 20.0 <= age < 200.0  # trips at the first age above 20 ms (printed to 0.01 ms)
    assert res.summary["round_trip"]["max"] >= 0.02
    assert res.summary["ticks"] < 1000  # stopped within the first second, not after a joint left its range


def test_constant_delay_over_simlink(dev, tmp_path):
    res = _sim_run(dev, duration=1.0, link_wrap=lambda k: Inject(k, delay=0.03), log=tmp_path / "s.rhilog",
                   safety=SafetyConfig(stale_ticks=100))
    t = _safe_stop(res, tmp_path / "s.rhilog", "latency")
    assert t < 0.03 and "above 20 ms" in res.fault


def test_late_reading_counts_as_silence(dev, tmp_path):
    """Readings held 30 ms by the proxy, then delivered: silence on the host's clock, even with a 50 ms read wait."""
    # (the host waits in read, up to 50 ms for the next reading: the device's own watchdog is not tested)
    res = _proxied_run(dev, tmp_path, ("--watchdog", "0.2"), ("--hold", "0.8", "0.83"), timeout=0.05, duration=3.0,
                       log="h.rhilog", safety=SafetyConfig(stale_ticks=1000, max_age=1.0))
    _safe_stop(res, tmp_path / "h.rhilog", "silence")
    ms = float(res.fault.split(" for ")[1].split(" ms")[0])
    assert 20.0 < ms < 60.0, res.fault


def test_silence_over_simlink(dev, tmp_path):
    """Readings frozen (no new sequence number) in real time: silence after 20 ms on the wall clock."""
    res = _sim_run_realtime(dev, tmp_path / "f.rhilog", Inject, freeze=(0.3, 0.5))
    _safe_stop(res, tmp_path / "f.rhilog", "silence")
    assert float(res.fault.split(" for ")[1].split(" ms")[0]) < 60.0


def _sim_run_realtime(dev, log, wrap, **kw):
    plant, ctrl, hand, wall, phys = _scenario(dev)
    link = wrap(SimLink(plant, hand=hand, physical=phys), **kw)
    return run(link, ctrl, duration=1.0, virtual=wall, log=log, safety=SafetyConfig(stale_ticks=1000))


def test_frozen_sensors_over_udp(dev, tmp_path):
    """Frozen sensors over UDP: the frozen-sensor rule stops the run.

    The proxy freezes the values from a moving reading on, sequence numbers and device time advancing; the
    encoders are unchanged while their velocities imply motion.
    """
    res = _proxied_run(dev, tmp_path, ("--watchdog", "0.2"), ("--freeze", "0.3", "600"),  # frozen until the end
                       timeout=0.05, duration=60.0, log="z.rhilog",
                       safety=SafetyConfig(stale_ticks=1000, silence=1.0, max_age=1.0))  # only the frozen rule applies
    t = _safe_stop(res, tmp_path / "z.rhilog", "frozen")
    assert "encoders frozen" in res.fault and f"t={t:.4f} s" in res.fault
    run_log = Log.load(tmp_path / "z.rhilog")
    k = int(np.flatnonzero(run_log.safety)[0])
    n = SafetyConfig().frozen_ticks
    assert k >= n and np.all(run_log.q[k - n:k + 1] == run_log.q[k])  # the last frozen_ticks readings identical
    assert np.any(run_log.q[:k - n] != run_log.q[k])  # and it moved before the freeze


def test_skipped_readings_and_rate_reached_are_reported(dev, tmp_path):
    """--no-realtime against a free-running 1 kHz device, with a host that takes 3 ms a tick."""
    p, port = _server(tmp_path, "--watchdog", "0.2")  # (a shared machine may pause the host longer than 20 ms)
    try:
        plant, ctrl, hand, wall, phys = _scenario(dev)
        step = ctrl.step

        def slow(*a):
            time.sleep(0.003)
            return step(*a)

        ctrl.step = slow
        link = UDPLink("127.0.0.1", port, timeout=0.5)
        res = run(link, ctrl, duration=0.3, virtual=wall, realtime=False,
                  safety=SafetyConfig(silence=0.5, max_age=0.5, range_margin=1.0))
    finally:
        _stop(p)
    s = res.summary
    assert s["fault"] is None and s["ticks"] == 300
    assert s["skipped_readings"] == link.stats["skipped"] > 300  # about 2 of every 3 device periods
    assert s["rate_reached"] < 400 and s["skipped_readings_pct"] > 40
    assert s["missed"] == 0  # no deadlines without real time: the skipped readings are what says it


def test_device_clock_that_stalls_or_runs_backwards(dev, tmp_path):
    for name, shift in (("stalled", lambda t: min(t, 0.2)), ("ran backwards", lambda t: t if t < 0.2 else t - 0.1)):
        res = _sim_run(dev, link_wrap=lambda k, shift=shift: _Clock(k, shift), log=tmp_path / "c.rhilog")
        _safe_stop(res, tmp_path / "c.rhilog", "clock")
        assert name in res.fault


class _Clock:
    """A link whose device clock is rewritten by `shift(t)`."""

    def __init__(self, link, shift) -> None:
        self.link, self.shift, self.n, self.rate = link, shift, link.n, link.rate

    def open(self) -> None:
        self.link.open()

    def read(self):
        r = self.link.read()
        return dataclasses.replace(r, t=self.shift(r.t))

    def write(self, tau, *, enable: bool) -> None:
        self.link.write(tau, enable=enable)

    def close(self) -> None:
        self.link.close()


def test_required_sensors_are_checked_at_connect(dev):
    cfg = load_config("ch5_tmi")
    assert cfg.controller().required_sensors() == {}  # M_x^d = M_x (eq. 5.6): no F/T sensor
    # inertia shaping (eq. 5.4) reads the hand's force from the F/T sensor
    ctrl = NullSpaceController(cfg.device, ControllerConfig(primary=ImpedanceControl(inertia=np.eye(2))))
    assert ctrl.required_sensors() == {"ft": 6}
    assert load_config("ch7_ascm_tertiary").controller().required_sensors() == {}  # the host renders the wall

    class NoFT(_Clock):
        sensors = [("x", 2)]

    with pytest.raises(LinkError, match="needs 'ft'"):
        run(NoFT(cfg.sim_link(), lambda t: t), ctrl, duration=0.01, realtime=False)


def test_sessions_on_the_device_server(dev, tmp_path):
    """BUSY for a second host, SESSION_LOST for the first on a takeover, BYE ends the stream, sequences restart."""
    p, port = _server(tmp_path)
    try:
        a = UDPLink("127.0.0.1", port, timeout=0.1)
        a.open()
        a.write(np.zeros(4), enable=False)
        with pytest.raises(LinkError, match="BUSY"):
            UDPLink("127.0.0.1", port).open()
        b = UDPLink("127.0.0.1", port, timeout=0.1, takeover=True)
        b.open()
        with pytest.raises(SessionLost, match="taken over"):
            for _ in range(100):
                a.read()
        r = b.read()
        assert r.seq < 50 and r.cmd_seq == -1  # the new session's readings start at 0, nothing echoed
        b.write(np.zeros(4), enable=False)
        b.close()
        a.close()
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # after BYE: the device is free, its stream stopped
        s.settimeout(2)
        s.connect(("127.0.0.1", port))
        s.send(P.hello(99))
        assert P.parse_info(s.recv(4000))["session"] == 99
        assert P.parse_reading(s.recv(4000), 4, 6 + 2 + 2 + 2 + 1)[1] == 0
    finally:
        out = _stop(p)
    assert "'takeovers': 1" in out and "'refused': 1" in out


def test_the_host_says_bye_after_refusing_an_info():
    """A v1.1 INFO the host refuses (here: its description is not JSON; likewise a wrong rate, name or sensor)."""
    import threading

    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(5)
    got = []

    def device():
        pkt, addr = s.recvfrom(1000)
        session, _ = P.parse_hello(pkt)
        s.sendto(P.info(4, [], 1000.0, 0.02, {}, session)[:36] + b"not json", addr)
        got.append((session, P.parse_command(s.recvfrom(1000)[0], 4)))

    th = threading.Thread(target=device)
    th.start()
    with pytest.raises(LinkError, match="not a JSON object"):
        UDPLink("127.0.0.1", s.getsockname()[1]).open()
    th.join()
    s.close()
    (session, cmd), = got
    assert cmd is not None and cmd[0] == session and cmd[3] == P.BYE


def test_a_link_error_names_the_link_once(dev):
    """A link's own LinkError ("link: ...") is the fault reason as it is; another gets "link: " before it."""

    class Failing(_Clock):
        def __init__(self, link, message) -> None:
            super().__init__(link, lambda t: t)
            self.message, self.reads = message, 0

        def read(self):
            self.reads += 1
            if self.reads > 3:
                raise LinkError(self.message)
            return super().read()

    cfg = load_config("ch5_tmi")
    for message, want in [("link: reading 4 has status bits 0xffe0", "link: reading 4 has status bits 0xffe0"),
                          ("device: reading of protocol wire version 1", "link: device: reading of protocol wire")]:
        res = run(Failing(cfg.sim_link(), message), cfg.controller(), duration=0.02, realtime=False)
        assert res.fault is not None and res.fault.startswith(want) and "link: link:" not in res.fault, res.fault
