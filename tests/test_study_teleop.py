"""The §5.5 path-following study through the pages: the participant drives the master, a simulated slave follows.

`rhi study run --mouse` runs as its own process on the simulated devices; a scripted participant in headless
Chromium drags the pointer along the reference path on the participant's canvas (the mouse as the hand: the
master is pulled to where the teleoperation map sends the slave onto the pointer) and presses "Done". The
protocol's map is a scaling and a shift, so the slave's path and the master's differ by it; the responses'
measures are those of the slave's logged path.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import browser  # noqa: E402  (tests/browser.py)
import numpy as np
import pytest
from conftest import child_env
from study_process import StudyProcess

from rhi.devices.model import device
from rhi.experiments.ch5.setup import distance_to_polyline
from rhi.sim.log import Log
from rhi.study import slave as sl
from rhi.study.haptics import Haptics
from rhi.study.live import StudyRun
from rhi.study.protocol import parse_protocol
from rhi.study.session import Session, read_responses

pytestmark = [pytest.mark.realtime, pytest.mark.skipif(not browser.available(), reason="needs Debian's chromium")]

SCALE, OFFSET = 1.25, np.array([-0.05, 0.0])  # the master traces the W 0.8 times as large, 6 cm nearer
PROTOCOL = f"""
description = "a short §5.5 protocol: two scenarios, one run each, a scaled and shifted slave"
seed = 5
[task]
kind = "path_following"
time_limit = 600.0
center = [0.50, 0.0]
width = 0.04
height = 0.05
speed = 0.05
[stimulus]
method = "none"
repetitions = 1
[[conditions]]
name = "S1"
device = "rhi4"
config = "ch5_tmi"
params = {{ d2 = 0.1405 }}
[[conditions]]
name = "S3"
device = "rehab"
params = {{ d2 = 0.1405 }}
[teleoperation]
slave = "rehab_slave"
scale = {SCALE}
offset = {OFFSET.tolist()}
[display]
participant = ["next", "progress", "reference_path", "slave"]
[participant]
fields = {{ handedness = ["right", "left"] }}
"""


class Study(StudyProcess):
    """`rhi study run --mouse` of participant P01 (`StudyProcess`; its warm-up compiles: 300 s to serve)."""

    def __init__(self, protocol: Path, study: Path) -> None:
        super().__init__(protocol, study, extra=("--mouse",), timeout=300.0)

    def committed(self) -> int:
        """Trials committed so far (all of them once the command has ended)."""
        try:
            return int(self.view()["committed"])
        except OSError:
            return 99 if self.proc.poll() is not None else -1


def wait(cond, timeout: float, why) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, f"timed out: {why()}"
        time.sleep(0.05)


def waypoints(P: np.ndarray, step: float = 0.004) -> np.ndarray:
    """Points every `step` [m] along the polyline P (k, 2)."""
    out = [P[0]]
    for a, b in zip(P[:-1], P[1:]):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        out += [a + (b - a) * (i / k) for i in range(1, k + 1)]
    return np.array(out)


def pixel(b: browser.Browser, path: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """The page coordinates of slave-frame point x on the participant's canvas (its drawing transform)."""
    r = b.evaluate("(() => { const r = document.getElementById('path').getBoundingClientRect();"
                   " const c = document.getElementById('path');"
                   " return [r.left, r.top, c.width, c.height, window.innerWidth, window.innerHeight]; })()")
    left, top, w, h, width, height = r
    assert 0 <= left and left + w <= width and 0 <= top and top + h <= height, f"the canvas leaves the window: {r}"
    lo, hi = path.min(axis=0), path.max(axis=0)
    s = 0.8 * min(w / (hi[0] - lo[0]), h / (hi[1] - lo[1]))
    mid = (lo + hi) / 2
    return left + w / 2 + s * (x[0] - mid[0]), top + h / 2 - s * (x[1] - mid[1])


def mouse(b: browser.Browser, kind: str, xy: tuple[float, float]) -> None:
    b.call("Input.dispatchMouseEvent", type=kind, x=float(xy[0]), y=float(xy[1]), button="left",
           buttons=0 if kind == "mouseReleased" else 1, clickCount=1)


def follow_path(b: browser.Browser, study: Study, path: np.ndarray) -> None:
    """Drag the pointer along the path; at each waypoint wait until the slave is there (the machine may be busy).

    A hand that has not got there within 5 s moves the pointer again by half a pixel (a person's hand is never
    still), so one mouse event the browser coalesced or dropped under load does not end the test; the failure
    message shows where the mouse-hand pulls (`hand`, master frame) beside the slave.
    """
    pts = waypoints(path)
    mouse(b, "mousePressed", pixel(b, path, pts[0]))
    for p in pts:
        deadline, k = time.monotonic() + 120, 0
        while np.linalg.norm(np.array(study.view()["state"].get("slave_x", [9, 9])) - p) >= 0.004:
            assert time.monotonic() < deadline, f"timed out: {(p, study.view()['state'])}"
            if k % 100 == 0:
                u, v = pixel(b, path, p)
                mouse(b, "mouseMoved", (u + 0.5 * (k // 100 % 2), v))
            k += 1
            time.sleep(0.05)
    mouse(b, "mouseReleased", pixel(b, path, pts[-1]))


def test_mouse_drives_the_master_and_the_slave_follows_the_path(tmp_path):
    proto = tmp_path / "ch5_small.toml"
    proto.write_text(PROTOCOL)
    folder = tmp_path / "study"
    s = Study(proto, folder)
    try:
        with browser.Browser(s.url, width=1000, height=900) as b:  # the whole canvas inside the window
            assert b.wait_for("document.body.dataset.phase === 'ready'", 120)
            path = np.array(s.view("participant")["path"])
            order = []
            for run in range(2):
                b.evaluate("document.getElementById('next').click()")  # ready (first) -> between -> running
                if run == 0:
                    assert b.wait_for("document.body.dataset.phase === 'between'", 60)
                    b.evaluate("document.getElementById('next').click()")
                assert b.wait_for("document.body.dataset.phase === 'running'", 60)
                ex = s.view()
                order.append(ex["trial"]["condition"])
                wait(lambda: "slave_x" in s.view()["state"], 600, lambda: s.view()["device"])  # warm-up, compiles
                assert s.view("participant")["hand"] is True and s.view("participant")["slave"] is not None
                assert b.wait_for("document.body.innerText.includes('accuracy first')", 30)  # §5.5's instruction
                if run == 1:  # the experimenter's page draws the slave on the path
                    b.call("Page.navigate", url=s.url + "experimenter")
                    assert b.wait_for("document.getElementById('slave').hidden === false", 60)
                    assert b.evaluate("document.getElementById('device').innerText").count("slave_x") == 1
                    b.call("Page.navigate", url=s.url)
                    assert b.wait_for("document.body.dataset.phase === 'running'", 60)
                    assert b.wait_for("document.getElementById('path').hidden === false", 60)
                follow_path(b, s, path)
                b.evaluate("document.getElementById('next').click()")  # "Done"
                wait(lambda r=run: s.committed() > r, 120, lambda: s.proc.poll())
                if run == 0:
                    assert b.wait_for("document.body.dataset.phase === 'between'", 60)
            s.proc.wait(timeout=120)
            assert s.proc.returncode == 0
    finally:
        s.kill()
    rows = read_responses(folder / "P01" / "responses.csv")
    assert [r["condition"] for r in rows] == order and sorted(order) == ["S1", "S3"]
    for r in rows:
        log = Log.load(folder / "P01" / "trials" / f"trial-{int(r['trial']):04d}-run.rhilog")
        assert log.fault is None and log.slave_x.shape == log.x.shape
        # the slave's path differs from the master's by the map: x_s ≈ s x_m + p (a PD's lag), not x_m
        mapped = SCALE * log.x + OFFSET
        assert np.median(np.linalg.norm(log.slave_x - mapped, axis=1)) < 0.003
        assert np.median(np.linalg.norm(log.slave_x - log.x, axis=1)) > 0.02
        span_s, span_m = np.ptp(log.slave_x, axis=0), np.ptp(log.x, axis=0)
        np.testing.assert_allclose(span_s / span_m, SCALE, rtol=0.1)
        # the measures are the slave's: distance to the path, the hand's work on the master, the duration
        err = distance_to_polyline(log.slave_x, path).mean()
        assert float(r["tracking_error"]) == pytest.approx(err, rel=1e-9)
        assert err < 0.004 < distance_to_polyline(log.x, path).mean()
        power = np.einsum("tj,tj->t", log.F_hand, log.xdot)
        work = np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(log.t))
        assert float(r["effort"]) == pytest.approx(work, rel=1e-9, abs=1e-12) and work > 0
        assert float(r["completion_time"]) == pytest.approx(log.t[-1] - log.t[0], rel=1e-9)


def test_the_master_over_udp_drives_the_slave(tmp_path):
    """A device process over UDP is the master (`rhi device-server`); the slave follows it in the study's process."""
    cfg = tmp_path / "rehab_lenient.toml"  # rendering only; the link's timing limits of a loaded test machine
    cfg.write_text('[device]\nname = "rehab"\n[controller]\ndamping = 0.0\nsaturation = "none"\n'
                   '[controller.primary]\nlaw = "force_rendering"\ndamping = 0.0\npassivity = "off"\n'
                   '[safety]\nsilence = 1.0\nmax_age = 1.0\nstale_ticks = 1000\n')
    text = PROTOCOL[:PROTOCOL.index("[[conditions]]")] + f'[[conditions]]\nname = "S3"\ndevice = "rehab"\n' \
        f'config = "{cfg}"\n' + PROTOCOL[PROTOCOL.index("[teleoperation]"):]
    p = parse_protocol(tomllib.loads(text), name="udp", text=text)
    x0 = sl.master_path(p).points[0]
    q0 = device("rehab").ik(x0, np.array([0.3, 0.9]))
    env = child_env()
    dev = subprocess.Popen([sys.executable, "-m", "rhi", "device-server", "rehab", "--port", "0", "--q0",
                            ",".join(map(repr, q0.tolist())), "--watchdog-ms", "1000"],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        port = int(re.search(r"udp://127\.0\.0\.1:(\d+)", dev.stdout.readline()).group(1))
        s = Session(tmp_path, p, "P01", fields={"handedness": "left"})
        run = StudyRun(s, Haptics(p, f"udp://127.0.0.1:{port}", rate=1000.0))
        run.next()
        run.next()
        wait(lambda: run.haptics.status.get("ticks", 0) > 300, 300, lambda: (run.haptics.status, run.haptics.last))
        assert len(run.experimenter_view()["state"]["slave_x"]) == 2
        run.next()
        run.abort()
        assert run.fault is None and len(s.rows) == 1
    finally:
        dev.send_signal(signal.SIGTERM)
        dev.communicate(timeout=20)
    log = Log.load(s.trial_log(0, "run"))
    assert log.fault is None and log.slave_x.shape == log.x.shape and len(log.t) > 300
    path = sl.reference(p).points
    np.testing.assert_allclose(log.slave_x[-1], path[0], atol=0.003)  # the master held still at the start
    np.testing.assert_allclose(log.slave_x[-1], SCALE * log.x[-1] + OFFSET, atol=0.003)
    assert float(s.rows[0]["tracking_error"]) == pytest.approx(distance_to_polyline(log.slave_x, path).mean(),
                                                               rel=1e-9)
