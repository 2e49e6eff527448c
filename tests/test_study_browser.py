"""`rhi study run` in headless Chromium: a scripted participant, a kill mid-way, the resume, the analysis.

The participant answers through the participant's page (its buttons and its keys), each answer from rhi's
observer model, the one `rhi study simulate` and `ch3.psychophysics` use (`simulated_observers`: the §3.5 observer,
K̂ of a MuJoCo palpation through the condition's simulated device with Weber noise, by enrolment index and in
presentation order); `rhi study run` runs as its own process on the simulated devices and is SIGKILLed in the
middle of a trial, then started again with the same command. The answers given are therefore those of
`rhi study simulate` of the same protocol and seed, trial for trial.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from rhi.analysis import psychophysics as pp
from rhi.study.protocol import load_protocol
from rhi.study.session import read_responses
from rhi.study.simulate import simulate

pytest.importorskip("psignifit")

import browser  # noqa: E402  (tests/browser.py)
from conftest import child_env  # noqa: E402
from study_process import StudyProcess  # noqa: E402

pytestmark = pytest.mark.skipif(not browser.available(), reason="needs Debian's chromium")

PROTOCOL = """
description = "2 devices x 3 comparisons x 2 repetitions"
seed = 3
[task]
kind = "discrimination_2afc"
probe_time = 20.0
stroke_time = 0.4
[stimulus]
method = "constant"
reference = 50.0
comparisons_percent = [-25.0, 0.0, 25.0]
repetitions = 2
[[conditions]]
name = "RHI"
device = "rhi4"
config = "ch3_vme"
[[conditions]]
name = "Rehab"
device = "rehab"
[blocks]
rest_every = 5
[fixture]
point = [0.49, -0.22]
direction = [0.0, 1.0]
[obstacle]
distance = 0.08
[display]
participant = ["next", "answers"]
[participant]
fields = { handedness = ["right", "left"] }
"""


#: enrolment index of each participant of the test (the order they start in)
INDEX = {"P01": 0, "P02": 1}
#: stroke durations of the observers' lookup [s] (ch3.psychophysics has four; two keep the test short)
DURATIONS = (0.6, 1.3)


def observers(protocol: Path, monkeypatch):
    """The §3.5 observers (rhi's observer model) of the protocol's two participants (12 MuJoCo palpations, in this process)."""
    from rhi.design import executors
    from rhi.experiments.participants import simulated_observers

    monkeypatch.setitem(executors.DEFAULTS, "executor", "serial")  # 12 short simulations: no pool
    return lambda: simulated_observers(load_protocol(str(protocol)), len(INDEX), durations=DURATIONS)


def key(b: browser.Browser, k: str) -> None:
    code = {"1": "Digit1", "2": "Digit2", "n": "KeyN"}[k]
    for kind in ("keyDown", "keyUp"):
        b.call("Input.dispatchKeyEvent", type=kind, key=k, code=code, text=k if kind == "keyDown" else "")


def play(b: browser.Browser, study: StudyProcess, observer, decisions: dict, phases: list, *,
         kill_at: int | None = None) -> str:
    """Work through the participant's page until done (or kill `study` during the second sample of `kill_at`).

    The session's own state (the experimenter's view) says what happens now; the script acts once the
    participant's page shows it, and waits for the session to move on.
    """
    for _ in range(200):
        if study.proc.poll() is not None:
            assert study.proc.returncode == 0
            return "done"
        try:
            view = study.view()
        except OSError:
            study.proc.wait(timeout=30)
            continue
        k, ph = view["committed"], view["phase"]
        if ph == "done":  # the pages show the end for a moment, then the command exits with 0
            study.proc.wait(timeout=60)
            continue
        assert b.wait_for(f"document.body.dataset.phase === {json.dumps(ph)}", 60), \
            (k, ph, b.evaluate("document.body.dataset.phase"), phases[-5:])
        phases.append((k, ph))
        if ph in ("ready", "rest"):
            b.evaluate("document.getElementById('next').click()")
        elif ph == "probe_1":
            time.sleep(0.15)  # probing the first sample
            if k % 2:
                key(b, "n")
            else:
                b.evaluate("document.getElementById('next').click()")
        elif ph == "probe_2":  # feel the second sample, answer "which was stiffer"
            if k == kill_at:
                time.sleep(0.2)
                study.kill()
                return "killed"
            t = view["trial"]
            if (view["participant"], k) not in decisions:  # one answer per trial: one draw of the observer, which
                # is given again where the session has not taken it yet (a slow session under load)
                stiffer = bool(observer.answer(INDEX[view["participant"]], t["condition"], t["stimulus"]))
                decisions[(view["participant"], k)] = (t["condition"], t["stimulus"], int(stiffer))
            stiffer = bool(decisions[(view["participant"], k)][2])
            which = "first" if stiffer == t["comparison_first"] else "second"
            if k % 3 == 0:
                key(b, "1" if which == "first" else "2")
            else:
                b.evaluate(f"document.getElementById('answer-{which}').click()")
        else:
            raise AssertionError(f"unexpected phase {ph}")
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:  # the action reached the session: it committed or moved on
            try:
                v = study.view()
            except OSError:
                break
            if (v["committed"], v["phase"]) != (k, ph):
                break
            time.sleep(0.05)
    raise AssertionError("the session did not finish")


def test_scripted_participant_killed_and_resumed_through_the_pages(tmp_path, monkeypatch):
    proto = tmp_path / "small_2afc.toml"
    proto.write_text(PROTOCOL)
    folder = tmp_path / "study"
    make_observer = observers(proto, monkeypatch)
    observer = make_observer()
    decisions: dict = {}
    phases: list = []
    s = StudyProcess(proto, folder, "P01")
    with browser.Browser(s.url) as b:
        assert b.wait_for("document.body.dataset.phase === 'ready'", 60)
        # the participant's page shows nothing the protocol does not allow: no stimulus, no condition
        text = b.evaluate("document.body.innerText")
        assert "RHI" not in text and "Rehab" not in text and "N/m" not in text
        assert play(b, s, observer, decisions, phases, kill_at=7) == "killed"
        assert [int(r["trial"]) for r in read_responses(folder / "P01" / "responses.csv")] == list(range(7))
        s = StudyProcess(proto, folder, "P01")  # the same command resumes
        b.call("Page.navigate", url=s.url)
        assert play(b, s, observer, decisions, phases) == "done"
        s.proc.wait(timeout=60)
        s2 = StudyProcess(proto, folder, "P02")
        b.call("Page.navigate", url=s2.url)
        assert play(b, s2, observer, decisions, phases) == "done"
        s2.proc.wait(timeout=60)
    # every trial exactly once, answers as given; the rests where the protocol puts them (before trials 5, 10)
    assert {k for k, ph in phases if ph == "rest"} == {5, 10}
    subj, dev, comp, resp = [], [], [], []
    for pid in ("P01", "P02"):
        rows = read_responses(folder / pid / "responses.csv")
        assert [int(r["trial"]) for r in rows] == list(range(12))
        for r in rows:
            cond, stim, stiffer = decisions[(pid, int(r["trial"]))]
            assert (r["condition"], float(r["stimulus"]), int(r["response"])) == (cond, stim, stiffer)
            assert float(r["response_time"]) > 0
            subj.append(pid)
            dev.append(cond)
            comp.append(stim)
            resp.append(stiffer)
        logs = sorted(p.name for p in (folder / pid / "trials").glob("trial-*-[ab].rhilog"))
        assert len(logs) == 24  # one log per probe
    assert list((folder / "P01" / "trials").glob("trial-0007-*.interrupted-1.rhilog"))
    # the observer answered in presentation order, the killed trial once: the answers of `rhi study simulate`
    simulated = simulate(load_protocol(str(proto)), len(INDEX), make_observer())
    assert [(r["trial"], r["condition"], r["stimulus"], r["response"]) for r in simulated] == \
        [(int(r["trial"]), r["condition"], float(r["stimulus"]), int(r["response"])) for pid in INDEX
         for r in read_responses(folder / pid / "responses.csv")]
    assert 0 < np.mean(resp) < 1  # both answers occur
    # rhi study analyze = the analysis fed the same responses directly
    out = tmp_path / "analysis"
    env = child_env()
    r = subprocess.run([sys.executable, "-m", "rhi", "study", "analyze", str(folder), "--out", str(out), "--fast"],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    got = {row["quantity"]: row["rhi"] for t in json.loads((out / "results.json").read_text())["results"][0]["tables"]
           for row in t["rows"]}
    direct = pp.analyse(pp.Responses(subject=np.array(subj, dtype=object), device=np.array(dev, dtype=object),
                                     comparison=np.array(comp), response=np.array(resp)),
                        devices=["RHI", "Rehab"], overdispersion=False, min_trials=6)
    for m, label in (("wf", "WF"), ("jnd", "JND"), ("pse", "PSE")):
        for c, sm in zip(direct.devices, direct.summary[m]):
            assert got[f"{label} mean, {c}"] == pytest.approx(sm.mean, rel=1e-12)
            assert got[f"{label} std, {c}"] == pytest.approx(sm.std, rel=1e-12, abs=1e-15)
    anova = next(v for k, v in got.items() if k.startswith("one-way ANOVA on WF: F"))
    assert anova == pytest.approx(direct.anova.statistic, rel=1e-12)
    assert (out / "figures" / "study.small_2afc.psychometric_curves.png").exists()
