"""The device link over UDP on loopback.

`rhi device-server`-style processes, the protocol, and the faults a network and two processes add (dropped and
reordered packets, either process killed).
"""

from __future__ import annotations

import os
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_runtime import _scenario

import rhi
from rhi.errors import InvalidInput, LinkError
from rhi.runtime import SafetyConfig, protocol as P, run
from rhi.runtime.udp import UDPLink, parse_url
from rhi.sim import Log, simulate

HERE = Path(__file__).parent

# real processes on real clocks: run alone (./run tests -m realtime), not beside CPU-heavy tests
pytestmark = pytest.mark.realtime

# lock-step over loopback on a shared machine: arrivals 20 ms apart happen, and are not what these tests test
LOADED = SafetyConfig(silence=1.0, max_age=1.0)


@pytest.fixture(scope="module")
def dev():
    return rhi.device("rhi4")


def _server(tmp_path, *args):
    """Start the device process; returns (process, port)."""
    pf = tmp_path / f"port{time.monotonic_ns()}"
    p = subprocess.Popen([sys.executable, str(HERE / "udp_device.py"), str(pf), *args],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    end = time.monotonic() + 60
    while not (pf.exists() and pf.read_text()):
        if p.poll() is not None or time.monotonic() > end:
            raise RuntimeError(f"device server did not start: {p.communicate()[0]}")
        time.sleep(0.02)
    return p, int(pf.read_text())


def _stop(p):
    if p.poll() is None:
        p.send_signal(signal.SIGTERM)
    try:
        return p.communicate(timeout=10)[0]
    except subprocess.TimeoutExpired:
        p.kill()
        return p.communicate()[0]


@pytest.mark.parametrize("spin", [False, True])
def test_lockstep_over_udp_equals_simulate(dev, tmp_path, spin):
    p, port = _server(tmp_path, "--lockstep", "--exit-on-bye", "--watchdog", "2.0", *(["--spin"] if spin else []))
    try:
        plant, ctrl, hand, wall, phys = _scenario(dev)
        link = UDPLink("127.0.0.1", port, timeout=0.5, spin=spin)
        res = run(link, ctrl, duration=0.6, virtual=wall, realtime=False, safety=LOADED)
    finally:
        out = _stop(p)
    plant, ctrl, hand, wall, phys = _scenario(dev)
    ref = simulate(plant, ctrl, duration=0.6, hand=hand, virtual=wall, physical=phys)
    assert res.fault is None, res.fault
    assert link.stats["lost"] == 0 and link.stats["reordered"] == 0, link.stats
    np.testing.assert_allclose(res.log.tau, ref.tau, atol=1e-9, rtol=0)
    # the device's ground truth crossed the wire (the runtime logs it at the reading, simulate at the period's end)
    np.testing.assert_allclose(res.log.work[1:], ref.work[:-1], atol=1e-12)
    assert link.info["device"] == "rhi4" and dict(link.sensors)["ft"] == 6
    assert "'watchdog_trips': 0" in out


@pytest.mark.parametrize("inject, reason", [(("--drop", "0.2", "0.3"), "stale"),
                                            (("--reorder", "0.2"), "link")])
def test_dropped_and_reordered_packets_fault(dev, tmp_path, inject, reason):
    p, port = _server(tmp_path, "--lockstep", "--exit-on-bye", "--watchdog", "2.0", *inject)
    try:
        plant, ctrl, hand, wall, phys = _scenario(dev)
        link = UDPLink("127.0.0.1", port, timeout=0.005)
        res = run(link, ctrl, duration=0.6, virtual=wall, realtime=False, log=tmp_path / "h.rhilog", safety=LOADED)
    finally:
        _stop(p)
    assert res.summary["fault_kind"] == reason, res.fault
    assert 0.19 <= res.log.t[-1] <= 0.21
    np.testing.assert_array_equal(res.log.tau[-1], 0.0)
    assert ("frozen" if reason == "stale" else "out-of-order") in res.fault
    assert len(Log.load(tmp_path / "h.rhilog")) == len(res.log)


def test_realtime_over_udp_and_server_killed(dev, tmp_path):
    """Free-running device at 1 kHz, host in real time; then the device process dies: a link fault."""
    p, port = _server(tmp_path, "--watchdog", "0.1")  # (a shared machine may pause the host longer than 20 ms)
    plant, ctrl, hand, wall, phys = _scenario(dev)
    link = UDPLink("127.0.0.1", port, timeout=4e-4)
    killer = None
    try:
        import threading

        t_kill = {}

        def kill():
            t_kill["t"] = time.monotonic()
            p.kill()

        killer = threading.Timer(0.5, kill)
        t_start = time.monotonic()

        def arm(status):  # the kill is timed from inside the running loop (start-up may be slow)
            if not killer.is_alive() and "t" not in t_kill:
                killer.start()

        res = run(link, ctrl, duration=6.0, virtual=wall, safety=SafetyConfig(stale_ticks=20, silence=0.05, max_age=0.05),
                  progress=arm)
    finally:
        if killer is not None:
            killer.cancel()
        _stop(p)
    s = res.summary
    assert s["fault_kind"] in ("link", "stale", "silence"), res.fault
    t_fault = t_start + res.log.wall[-1]
    assert t_fault - t_kill["t"] < 0.25, (t_fault - t_kill["t"], res.fault)
    assert s["ticks"] > 100 and link.stats["received"] > 100
    assert np.abs(res.log.tau[:-1]).max() > 0  # it rendered before the fault
    np.testing.assert_array_equal(res.log.tau[-1], 0.0)


def test_controller_killed_device_zeroes_torque(dev, tmp_path):
    """The host process dies mid-run: the device's watchdog gives zero torque within 20 ms plus one period."""
    log = tmp_path / "dev.rhilog"
    p, port = _server(tmp_path, "--log", str(log))
    h = subprocess.Popen([sys.executable, str(HERE / "udp_host.py"), str(port), "5.0"],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert "running" in h.stdout.readline()
        time.sleep(0.5)
        h.kill()
        h.wait()
        time.sleep(0.3)
    finally:
        h.kill()
        _stop(p)
    d = Log.load(log)
    trips = [e for e in d.events if e.kind == "watchdog"]
    assert len(trips) == 1, d.events
    k = trips[0].tick
    ms = float(trips[0].detail.split("for ")[1].split(" ms")[0])
    late_ms = 1e3 * d.late[k]
    assert ms <= 20.0 + 1.0 + late_ms + 1.0, (ms, late_ms)  # 20 ms + one period (+ the tick's own lateness)
    assert np.abs(d.tau[k - 30:k - 25]).max() > 0  # it was rendering a force before
    np.testing.assert_array_equal(d.tau[k:], 0.0)  # and nothing after
    assert np.all(d.safety[k + 1:].astype(int) & 4)  # WATCHDOG flag in every reading after the trip


def test_protocol_versions_and_bad_urls(tmp_path):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.settimeout(5)
    import threading

    def fake_device():  # a v1.0 device: answers HELLO with an INFO of version 1, then expects no BYE
        pkt, addr = s.recvfrom(1000)
        assert pkt[:4] == P.HELLO and len(pkt) == 16
        s.sendto(struct.pack("<4sHHHHdd", P.INFO, 1, 4, 6, 0, 1000.0, 0.02) + b'{"sensors": [["ft", 6]]}', addr)

    th = threading.Thread(target=fake_device)
    th.start()
    with pytest.raises(LinkError, match=r"wire version 1 \(v1.0: update the device"):
        UDPLink("127.0.0.1", port, connect_timeout=2.0).open()
    th.join()
    with pytest.raises(LinkError, match="no answer"):  # a socket that never answers
        UDPLink("127.0.0.1", port, connect_timeout=0.3).open()
    s.close()
    with pytest.raises(LinkError, match="unreachable"):  # nobody listens there any more
        UDPLink("127.0.0.1", port, connect_timeout=0.3).open()
    for bad in ["udp://127.0.0.1", "tcp://127.0.0.1:5", "udp://:5", "udp://h:99999", "127.0.0.1:5005", "udp://h:0"]:
        with pytest.raises(InvalidInput, match="link"):
            parse_url(bad)
    assert parse_url("udp://localhost:5005") == ("localhost", 5005)
    # what a device does not take: another version, a reserved flag bit, a non-finite torque; huge finite ones it takes
    cmd = P.command(9, 1, 0, P.ENABLE, 0.0, np.zeros(4))
    assert P.parse_command(cmd.replace(b"RHIC\x02", b"RHIC\x01", 1), 4) is None
    assert P.parse_command(P.command(9, 1, 0, P.ENABLE | 16, 0.0, np.zeros(4)), 4) is None
    assert P.parse_command(P.command(9, 1, 0, P.ENABLE, 0.0, np.array([0, np.nan, 0, 0])), 4) is None
    assert P.parse_command(cmd + b"\0", 4) is None
    assert P.parse_command(P.command(9, 7, 3, P.ENABLE, 1.5, np.arange(4.0)), 4)[:4] == (9, 7, 3, P.ENABLE)
    big = P.parse_command(P.command(9, 7, 3, P.ENABLE, 1.5, np.array([1e300, -1e300, 1e154, 0])), 4)
    assert big is not None and big[5][0] == 1e300
    assert P.newer(0, 0xFFFFFFFF) and P.newer(5, 4) and not P.newer(4, 4) and not P.newer(3, 4)
    assert isinstance(P.parse_hello(P.hello(5) + b"\0"), str) and isinstance(P.parse_hello(P.hello(0)), str)
    assert P.parse_hello(P.hello(5, P.TAKEOVER)) == (5, P.TAKEOVER)


def test_server_refuses_other_versions(dev, tmp_path):
    p, port = _server(tmp_path)
    try:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.settimeout(5)
        s.sendto(struct.pack("<4sHH", P.HELLO, 9, 0), ("127.0.0.1", port))
        pkt = s.recv(2000)
        assert pkt[:4] == P.ERROR and b"version 9" in pkt and P.parse_error(pkt)[0] == P.E_VERSION
        s.sendto(b"RHIH\x01\x00\x00\x00", ("127.0.0.1", port))  # a v1.0 host: refused in v1.0's layout
        pkt = s.recv(2000)
        assert pkt[:8] == b"RHIE\x01\x00\x00\x00" and b"v1.0 is not served" in pkt
    finally:
        _stop(p)


def test_packet_layout_is_the_documented_one():
    """docs/protocol.md gives byte offsets; the implementation must match them."""
    cmd = P.command(0x1122334455667788, 5, 4, P.ENABLE | P.RESET, 2.5, np.array([1.0, -2.0]))
    assert len(cmd) == 36 + 16
    assert struct.unpack_from("<4sHHQIIHHd", cmd) == (b"RHIC", 2, 5, 0x1122334455667788, 5, 4, 2, 0, 2.5)
    rd = P.reading(3, 9, 5, 17, 0.25, [1.0, 2.0], [3.0, 4.0], [5.0])
    assert len(rd) == 36 + 40
    assert struct.unpack_from("<4sHHQIIHHd5d", rd) == (b"RHIR", 2, 17, 3, 9, 5, 2, 1, 0.25, 1.0, 2.0, 3.0, 4.0, 5.0)
    doc = (HERE.parent / "docs" / "protocol.md").read_text()
    example = doc.split("## 7. Example bytes")[1].split("```")[1]
    assert bytes.fromhex(" ".join(example.split())) == cmd
    info = P.info(3, [("ft", 6)], 1000.0, 0.02, {"device": "d"}, 42)
    assert struct.unpack_from("<HHHddQ", info, 6) == (3, 6, 0, 1000.0, 0.02, 42) and info[36:37] == b"{"
    assert struct.unpack("<4sHHQ", P.hello(42, P.TAKEOVER)) == (b"RHIH", 2, 1, 42)
    assert struct.unpack_from("<4sHHQ", P.error(P.E_BUSY, 42, "x")) == (b"RHIE", 2, 3, 42)
    for magic in ("RHIH", "RHII", "RHIC", "RHIR", "RHIE", "SESSION_LOST", "BUSY", "TAKEOVER", "kit/c"):
        assert magic in doc
    assert os.path.getsize(HERE.parent / "docs" / "protocol.md") > 3000


def test_cli_device_server(tmp_path):
    """`rhi device-server` is a real process a UDPLink can talk to."""
    p = subprocess.Popen([sys.executable, "-c", "import sys; from rhi.cli import main; sys.exit(main())",
                          "device-server", "planar3r", "--port", "0", "--duration", "2"],
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        line = p.stdout.readline()
        port = int(line.rsplit(":", 1)[1].split(",")[0])
        link = UDPLink("127.0.0.1", port, timeout=0.1, connect_timeout=20.0)  # (the server may still be loading)
        link.open()
        r = link.read()
        assert link.n == 3 and r.q.shape == (3,) and r.sensors["ft"].shape == (6,)
        link.write(np.zeros(3), enable=True)
        r2 = link.read()
        assert r2.seq > r.seq
        link.close()
    finally:
        _stop(p)
