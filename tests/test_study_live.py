"""rhi.study live: the pages' API over HTTP, the mouse as the hand, pause/resume, a device over UDP, path following."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
import tomllib
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from rhi.errors import InvalidInput
from rhi.study.haptics import Haptics
from rhi.study.live import StudyRun
from rhi.study.pages import make_server
from rhi.study.protocol import load_protocol, parse_protocol
from rhi.study.session import Session, read_responses

SRC = str(Path(__file__).resolve().parents[1] / "src")


def small(conditions: str = "both"):
    text = load_protocol("ch3_stiffness_2afc").text
    text = text.replace("[-35.0, -25.0, -15.0, -5.0, 0.0, 5.0, 15.0, 25.0, 35.0]", "[-25.0, 0.0, 25.0]").replace(
        "repetitions = 10", "repetitions = 1").replace("stroke_time = 1.0", "stroke_time = 0.3")
    if conditions == "rehab":
        a, b = text.index("[[conditions]]"), text.index('[[conditions]]\nname = "Rehab"')
        text = text[:a] + text[b:]
    return parse_protocol(tomllib.loads(text), name="small", text=text)


def wait(cond, timeout: float = 120.0, why=lambda: "") -> None:
    """Until cond() is true (the device loop starts after its controller's warm-up; the machine may be busy)."""
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, f"timed out {why()}"
        time.sleep(0.05)


class Pages:
    """A `StudyRun` served on a free port, driven over HTTP as the browser pages drive it."""

    def __init__(self, run: StudyRun) -> None:
        self.run = run
        self.srv = make_server(run, port=0)
        self.url = f"http://127.0.0.1:{self.srv.server_address[1]}"
        threading.Thread(target=self.srv.serve_forever, daemon=True).start()

    def get(self, view: str) -> dict:
        return json.load(urllib.request.urlopen(f"{self.url}/api/{view}", timeout=10))

    def post(self, action: str, **body) -> dict:
        req = urllib.request.Request(f"{self.url}/api/{action}", data=json.dumps(body).encode(), method="POST",
                                     headers={"Content-Type": "application/json"})
        try:
            return json.load(urllib.request.urlopen(req, timeout=30))
        except urllib.error.HTTPError as exc:
            return json.load(exc)

    def close(self) -> None:
        self.run.abort()
        self.srv.shutdown()
        self.srv.server_close()


def test_mouse_dry_run_pause_resume_and_what_each_page_sees(tmp_path):
    p = small()
    s = Session(tmp_path, p, "P01", fields={"handedness": "right"})
    pages = Pages(StudyRun(s, Haptics(p, "sim", rate=500.0, mouse=True)))
    try:
        assert pages.post("participant/answer", answer="first")["ok"] is False  # nothing to answer yet
        assert pages.post("participant/next")["ok"]
        view = pages.get("participant")
        assert view == {"phase": "probe_1", "message": "First sample.", "next": True, "answers": False}
        wait(lambda: pages.get("experimenter")["device"]["ticks"] > 100)
        x0 = np.array(pages.get("experimenter")["state"]["x"])
        for depth in np.linspace(0.0, 0.05, 6):  # the experimenter's hand pad: drag 5 cm along u
            assert pages.post("experimenter/hand", depth=float(depth))["ok"]
            time.sleep(0.1)
        time.sleep(1.0)
        ex = pages.get("experimenter")
        x1 = np.array(ex["state"]["x"])
        assert x1[1] - x0[1] > 0.02 and abs(x1[0] - 0.49) < 0.01  # along the fixture's line, into the spring
        assert ex["state"]["F_env"][1] < -0.5  # the spring pushes back
        assert ex["trial"]["stimulus"] in (37.5, 50.0, 62.5) and ex["device"]["fault"] is None
        assert pages.post("experimenter/hand", depth="x")["ok"] is False
        assert pages.post("experimenter/pause")["ok"]
        assert not pages.get("experimenter")["running"] and pages.get("participant")["next"] is False
        assert pages.post("participant/next")["ok"] is False  # paused
        assert pages.post("experimenter/resume")["ok"]
        assert pages.get("experimenter")["running"]
        wait(lambda: pages.get("experimenter")["device"]["ticks"] > 10)
        assert pages.post("participant/next")["ok"] and pages.post("participant/answer", answer="second")["ok"]
        assert pages.post("experimenter/note", text="a note, kept")["ok"]
    finally:
        pages.close()
    names = sorted(q.name for q in (s.folder / "trials").glob("*.rhilog"))
    assert names[:3] == ["trial-0000-a.rhilog", "trial-0000-a2.rhilog", "trial-0000-b.rhilog"]
    rows = read_responses(s.folder / "responses.csv")
    assert len(rows) == 1 and rows[0]["answer"] == "second"
    assert "a note, kept" in (s.folder / "notes.txt").read_text()
    with pytest.raises(InvalidInput, match="mouse"):
        Haptics(p, "udp://127.0.0.1:9", mouse=True)


@pytest.mark.realtime  # a device process at 1 kHz on wall clocks: run alone
def test_a_device_over_udp(tmp_path):
    """The probes run against `rhi device-server` over UDP; every probe's log holds its ticks."""
    from rhi.sim.log import Log

    env = {**os.environ, "PYTHONPATH": SRC}
    q0 = "0.2974622019652697,0.12039958701477757"  # rehab at the fixture's point (0.49, -0.22) m
    dev = subprocess.Popen([sys.executable, "-m", "rhi", "device-server", "rehab", "--port", "0", "--q0", q0,
                            "--watchdog-ms", "1000"],  # a shared test machine may stall a loop for > 20 ms
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    try:
        port = int(re.search(r"udp://127\.0\.0\.1:(\d+)", dev.stdout.readline()).group(1))
        p = small("rehab")
        s = Session(tmp_path, p, "P01", fields={"handedness": "left"})
        run = StudyRun(s, Haptics(p, f"udp://127.0.0.1:{port}", rate=1000.0))
        for _ in range(2):
            if run.phase == "ready":
                run.next()
            why = lambda: (run.phase, run.haptics.status, run.haptics.last)  # noqa: E731
            wait(lambda: run.haptics.status.get("ticks", 0) > 100, why=why)
            run.next()
            wait(lambda: run.haptics.status.get("ticks", 0) > 100, why=why)
            run.answer("first")
        run.abort()
        assert [r["trial"] for r in s.rows] == ["0", "1"]
        assert run.fault is None
        for k in (0, 1):
            for probe in "ab":
                log = Log.load(s.trial_log(k, probe))
                assert len(log.t) > 50 and log.fault is None
    finally:
        dev.send_signal(signal.SIGTERM)
        dev.communicate(timeout=20)


def test_path_following_run_measures(tmp_path):
    p = load_protocol("ch5_path_following")
    s = Session(tmp_path, p, "P01", fields={"handedness": "right", "sex": "female"})
    run = StudyRun(s, Haptics(p, "sim", rate=500.0))
    try:
        assert run.participant_view()["path"] and run.phase == "ready"
        run.next()  # the first trial: wait for "next" to start
        assert run.phase == "between"
        run.next()
        wait(lambda: run.haptics.status.get("ticks", 0) > 600, why=lambda: (run.phase, run.haptics.status,
                                                                             run.haptics.last))
        assert run.participant_view()["slave"] is not None
        run.next()
        row = s.rows[0]
        assert row["training"] == "1" and 1.0 < float(row["completion_time"]) < 60.0
        assert 0.0 <= float(row["tracking_error"]) < 0.05 and float(row["effort"]) > 0
    finally:
        run.abort()


def test_simulated_path_following_study(tmp_path):
    """`rhi study simulate` of a path-following protocol: ch. 5's teleoperation runs as the users, then analyze."""
    # a W of 10 cm at 5 cm/s: about 3.5 s simulated per run with the settling, 9 runs, one process (serial: the
    # test machine's cores are busy with other tests)
    text = load_protocol("ch5_path_following").text.replace("width = 0.16", "width = 0.02").replace(
        "height = 0.25", "height = 0.025").replace("speed = 0.02 ", "speed = 0.05 ").replace(
        "repetitions = 3", "repetitions = 1").replace("training = 1 ", "training = 0 ")
    proto = tmp_path / "paths.toml"
    proto.write_text(text)
    env = {**os.environ, "PYTHONPATH": SRC, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa")}
    r = subprocess.run([sys.executable, "-m", "rhi", "study", "simulate", str(proto), "--participants", "3", "--out",
                        str(tmp_path / "sim"), "--executor", "serial"], capture_output=True, text=True, env=env, timeout=900)
    assert r.returncode == 0, r.stderr
    assert "one-way ANOVA on completion_time: F(2, 6)" in r.stdout and "power" in r.stdout
    rows = [row for pid in ("S01", "S02", "S03") for row in read_responses(tmp_path / "sim" / pid / "responses.csv")]
    assert len(rows) == 9
    for row in rows:
        assert 0 <= float(row["tracking_error"]) < 0.02 and float(row["effort"]) != 0
        assert 1.0 < float(row["completion_time"]) < 5.0
    r = subprocess.run([sys.executable, "-m", "rhi", "study", "analyze", str(tmp_path / "sim"), "--out",
                        str(tmp_path / "an")], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "an" / "results.json").read_text())["results"][0]
    got = {row["quantity"]: row["rhi"] for t in res["tables"] for row in t["rows"]}
    per = {c: [float(x["completion_time"]) for x in rows if x["condition"] == c] for c in ("S1", "S2", "S3")}
    assert got["completion_time mean, S1"] == pytest.approx(np.mean(per["S1"]), rel=1e-12)
    assert (tmp_path / "an" / "figures" / "study.paths.by_condition.png").exists()  # the per-condition figure
