"""rhi.study: protocols, trial sequences, adaptive methods, crash-safe sessions, simulated participants."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rhi.analysis import psychophysics as pp
from rhi.errors import InvalidInput
from rhi.study.adaptive import QuestPlus, Staircase, replay
from rhi.study.protocol import load_protocol, parse_protocol, shipped_protocols
from rhi.study.sequence import plan
from rhi.study.session import Session, answer_row, read_responses

SRC = str(Path(__file__).resolve().parents[1] / "src")


def variant(name: str = "ch3_stiffness_2afc", **replace: str):
    """A shipped protocol with text replaced (old=new pairs given as keyword values "old|new")."""
    text = load_protocol(name).text
    for pair in replace.values():
        old, new = pair.split("|")
        assert old in text, old
        text = text.replace(old, new)
    return parse_protocol(tomllib.loads(text), name=name, text=text)


def test_shipped_protocols_load():
    assert {"ch3_stiffness_2afc", "ch5_path_following"} <= set(shipped_protocols())
    p = load_protocol("ch3_stiffness_2afc")
    assert p.condition_names == ["RHI", "PHANToM", "Rehab"] and p.stimulus["repetitions"] == 10
    assert p.display == ("next", "answers")
    q = load_protocol("ch5_path_following")
    assert q.kind == "path_following" and q.blocks["training"] == 1


@pytest.mark.parametrize("old_new, key", [
    ("[order]|[order]\nshuffle = true", "order.shuffle"),
    ("repetitions = 10|repetitions = 10\nrepetiton = 3", "stimulus.repetiton"),
    ("[-35.0, |[-135.0, ", r"stimulus.comparisons_percent\[0\]"),
    ("repetitions = 10|repetitions = 0", "stimulus.repetitions"),
    ('required = ["handedness"]|required = ["handedness", "weight"]', r"participant.required\[1\]"),
    ('participant = ["next", "answers"]|participant = ["next", "answers", "slave"]', r"display.participant\[2\]"),
    ('device = "phantom"|device = 3', r"conditions\[1\].device"),
    ('name = "Rehab"|name = "RHI"', r"conditions\[2\].name"),
])
def test_bad_protocols_are_refused_naming_the_key(old_new, key):
    with pytest.raises(InvalidInput, match=f"^{key}"):
        variant(x=old_new)


@pytest.mark.parametrize("old_new, key", [
    ("kp = 2000.0|kp = -1.0", "teleoperation.kp"),
    ("scale = 1.0 |scale = 0.0 ", "teleoperation.scale"),
    ("offset = [0.0, 0.0]|offset = [0.0, 0.0, 0.0]", "teleoperation.offset"),
    ("[teleoperation]|[teleoperation]\nrotation = 1.0", "teleoperation.rotation"),
])
def test_bad_teleoperation_is_refused_naming_the_key(old_new, key):
    with pytest.raises(InvalidInput, match=f"^{key}"):
        variant("ch5_path_following", x=old_new)


def test_teleoperation_is_the_ch5_set_up_and_only_for_path_following():
    p = load_protocol("ch5_path_following")
    t = p.teleoperation
    assert (t["slave"], t["kp"], t["kd"], t["scale"], t["offset"].tolist()) == ("rehab_slave", 2000.0, 60.0, 1.0,
                                                                                [0.0, 0.0])
    text = p.text[:p.text.index("[teleoperation]")] + p.text[p.text.index("[order]"):]
    absent = parse_protocol(tomllib.loads(text)).teleoperation  # its defaults: the same set-up
    assert {k: v.tolist() if k == "offset" else v for k, v in absent.items()} == \
        {k: v.tolist() if k == "offset" else v for k, v in t.items()}
    with pytest.raises(InvalidInput, match="^teleoperation: a discrimination_2afc task"):
        variant(x="[order]|[teleoperation]\nscale = 2.0\n[order]")


def test_impossible_adaptive_ranges_are_refused():
    st = ('method = "constant"|method = "staircase"\nstart_percent = 30.0\nstep_percent = 5.0\ntrials = 10\n'
          'min_percent = -20.0\nmax_percent = 20.0\n#')
    with pytest.raises(InvalidInput, match="^stimulus.comparisons_percent: unknown key"):
        variant(a=st)
    base = 'comparisons_percent = [-35.0, -25.0, -15.0, -5.0, 0.0, 5.0, 15.0, 25.0, 35.0]\nrepetitions = 10'
    with pytest.raises(InvalidInput, match="^stimulus.start_percent"):
        variant(a=st, b=f"{base}|")
    with pytest.raises(InvalidInput, match="^stimulus.min_percent"):
        variant(a=st.replace("-20.0", "-120.0"), b=f"{base}|")
    q = 'method = "constant"|method = "quest"\ntrials = 10\nmin_percent = 20.0\nmax_percent = 10.0\n#'
    with pytest.raises(InvalidInput, match="^stimulus.max_percent"):
        variant(a=q, b=f"{base}|")


def test_participant_fields_only_declared_ones():
    p = load_protocol("ch3_stiffness_2afc")
    assert p.participant_record({"handedness": "left", "age": "31"}) == {"handedness": "left", "age": 31}
    with pytest.raises(InvalidInput, match="^participant.weight: not a declared"):
        p.participant_record({"handedness": "left", "weight": "80"})
    with pytest.raises(InvalidInput, match="^participant.handedness: required"):
        p.participant_record({"age": 30})
    with pytest.raises(InvalidInput, match="^participant.age: expected an integer"):
        p.participant_record({"handedness": "right", "age": "thirty"})


def test_sequence_is_the_thesis_protocol_reproducible_per_participant():
    p = load_protocol("ch3_stiffness_2afc")
    s3 = plan(p, 3)
    assert s3 == plan(p, 3) and s3 != plan(p, 4)
    assert len(s3) == 270  # 3 devices × 9 comparisons × 10 repetitions
    ref = [t for t in pp.protocol(10, p.condition_names, seed=p.seed) if t.subject == "S04"]
    assert [(t.condition, t.percent, t.comparison_first, t.block) for t in s3] == \
        [(t.device, t.comparison_percent, t.comparison_first, t.block) for t in ref]
    for c in p.condition_names:  # each pair 10 times per device, in one block
        trials = [t for t in s3 if t.condition == c]
        assert len({t.block for t in trials}) == 1
        assert sorted(np.unique([t.percent for t in trials], return_counts=True)[1]) == [10] * 9
    # optional 10-min rests before comparisons 45, 90, 180, 225; the long rest before 135
    assert [(t.index, t.rest, t.rest_seconds) for t in s3 if t.rest] == \
        [(45, "rest", 600.0), (90, "rest", 600.0), (135, "long_rest", 3600.0), (180, "rest", 600.0),
         (225, "rest", 600.0)]
    fixed = variant(a='pair = "random"|pair = "reference_first"', b='conditions = "random"|conditions = "fixed"')
    f = plan(fixed, 3)
    assert not any(t.comparison_first for t in f)
    assert [t.condition for t in f[::90]] == ["RHI", "PHANToM", "Rehab"]


def test_training_and_path_following_sequence():
    p = load_protocol("ch5_path_following")
    s = plan(p, 0)
    assert len(s) == 3 * (1 + 3)
    for b in range(3):
        block = [t for t in s if t.block == b]
        assert block[0].training and not any(t.training for t in block[1:])
        assert block[0].percent is None and block[0].reference is None


def test_staircase_converges_near_its_target():
    from scipy.stats import norm

    rng = np.random.default_rng(0)
    s = Staircase(30.0, 2.0, -40.0, 40.0, down=2, up=1)
    xs = []
    for _ in range(400):
        x = s.next()
        p = norm.cdf(x / 10.0)
        s.update(x, int(rng.random() < p))
        xs.append(x)
    # 2-down 1-up: P(stiffer) = 0.707 at x = σ Φ⁻¹(0.707) = 5.45 %
    assert abs(np.mean(xs[100:]) - 5.45) < 2.0 and s.reversals > 20
    again = replay(Staircase(30.0, 2.0, -40.0, 40.0), [(30.0, 1), (30.0, 1), (28.0, 0)])
    assert again.next() == 30.0


def test_quest_plus_estimates_the_observer():
    from scipy.stats import norm

    rng = np.random.default_rng(1)
    q = QuestPlus(-40.0, 40.0, 2.5, lapse=0.02)
    for _ in range(120):
        x = q.next()
        q.update(x, int(rng.random() < 0.02 + 0.96 * norm.cdf((x - 4.0) / 8.0)))
    mu, sigma = q.estimate()
    assert abs(mu - 4.0) < 3.0 and 4.0 < sigma < 14.0
    with pytest.raises(InvalidInput, match="quest"):
        QuestPlus(10.0, 0.0, 1.0)


def test_session_commits_once_and_resumes(tmp_path):
    p = load_protocol("ch3_stiffness_2afc")
    s = Session(tmp_path, p, "P01", fields={"handedness": "right", "age": 30})
    assert s.index == 0 and s.next_trial == 0
    for t in s.plan[:3]:
        s.commit(answer_row(t, "P01", t.percent, "first"))
    with pytest.raises(InvalidInput, match="trial"):
        s.commit(answer_row(s.plan[1], "P01", 0.0, "first"))
    s.trial_log(3, "a").write_bytes(b"partial")
    with open(s.folder / "responses.csv", "a") as fh:
        fh.write("3,P01,0,RHI,0,50.0")  # a row cut short by a kill
    r = Session(tmp_path, None, "P01")
    assert r.next_trial == 3 and r.fields == {"handedness": "right", "age": 30}
    assert [row["trial"] for row in read_responses(r.folder / "responses.csv")] == ["0", "1", "2"]
    assert (r.folder / "trials" / "trial-0003-a.interrupted-1.rhilog").exists()
    assert Session(tmp_path, p, "P02", fields={"handedness": "left"}).index == 1
    with pytest.raises(InvalidInput, match="^participant.weight"):
        Session(tmp_path, p, "P03", fields={"handedness": "left", "weight": 70})
    with pytest.raises(InvalidInput, match="^participant"):
        Session(tmp_path, p, "../x")


def test_a_killed_writer_loses_and_repeats_nothing(tmp_path):
    """A process committing trials is SIGKILLed at random moments; resuming completes every trial exactly once."""
    code = textwrap.dedent(f"""
        import sys, time
        sys.path.insert(0, {SRC!r})
        from rhi.study.protocol import load_protocol
        from rhi.study.session import Session, answer_row
        s = Session({str(tmp_path)!r}, load_protocol("ch3_stiffness_2afc"), "P01", fields={{"handedness": "left"}})
        for t in s.plan[s.next_trial:]:
            s.commit(answer_row(t, "P01", t.percent, "first" if t.index % 3 else "second"))
            time.sleep(0.002)
    """)
    rng = np.random.default_rng(2)
    for _ in range(30):
        proc = subprocess.Popen([sys.executable, "-c", code])
        try:
            proc.wait(timeout=float(rng.uniform(0.3, 1.0)))
            break
        except subprocess.TimeoutExpired:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
    else:
        subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    rows = read_responses(tmp_path / "P01" / "responses.csv")
    assert [int(r["trial"]) for r in rows] == list(range(270))
    p = load_protocol("ch3_stiffness_2afc")
    expect = [answer_row(t, "P01", t.percent, "first" if t.index % 3 else "second") for t in plan(p, 0)]
    assert [r["response"] for r in rows] == [str(e["response"]) for e in expect]


def test_a_writer_killed_before_enrolment_leaves_no_second_header(tmp_path):
    """Killed between writing the header and participant.json: the next start enrols afresh, one header."""
    s = Session(tmp_path, load_protocol("ch3_stiffness_2afc"), "P01", fields={"handedness": "left"})
    (s.folder / "participant.json").unlink()  # the state a kill at that moment leaves
    s = Session(tmp_path, load_protocol("ch3_stiffness_2afc"), "P01", fields={"handedness": "left"})
    s.commit(answer_row(s.plan[0], "P01", s.plan[0].percent, "first"))
    assert [int(r["trial"]) for r in read_responses(s.folder / "responses.csv")] == [0]


def test_simulate_reproduces_ch3_psychophysics_and_analyze_reads_it_back(tmp_path, monkeypatch):
    """`rhi study simulate` of the §3.6 protocol = ch3.psychophysics (same seed, same lookup); analyze = both."""
    from rhi.design import executors
    from rhi.experiments.ch3.discrimination import psychophysics

    monkeypatch.setitem(executors.DEFAULTS, "executor", "serial")  # 27 small fits: no pool on a busy machine
    from rhi.experiments.participants import simulated_study
    from rhi.report.study import study_result

    p = variant(a="repetitions = 10|repetitions = 4", b="seed = 0|seed = 7")
    K = 50 * (1 + np.array(pp.COMPARISON_PERCENT) / 100)
    rng = np.random.default_rng(0)
    table = {"stiffness": K, "durations": np.array([0.6, 0.9]),
             **{d: K[:, None] * (1 + 0.05 * rng.standard_normal((9, 2))) for d in ("RHI", "PHANToM", "Rehab")},
             **{f"{d}_speed": np.ones((9, 2)) for d in ("RHI", "PHANToM", "Rehab")}}
    sim = simulated_study(p, 3, table=table, overdispersion=False, out=tmp_path / "sim")
    ref = psychophysics(subjects=3, repetitions=4, durations=(0.6, 0.9), seed=7, overdispersion=False, table=table)
    ours = {r.quantity: r.ours for t in study_result(tmp_path / "sim", overdispersion=False).tables for r in t.rows}
    theirs = {r.quantity: r.ours for t in ref.tables[:2] for r in t.rows}
    assert len(theirs) == 24 and set(theirs) <= set(ours)
    for k, v in theirs.items():
        assert ours[k] == pytest.approx(v, rel=1e-12, abs=1e-15), k
    assert sim.analysis.anova.statistic == pytest.approx(theirs[next(k for k in theirs if k.startswith("one-way"))])
    np.testing.assert_array_equal(sim.weber, ref.arrays["weber"])
    assert 0 < sim.power < 1


def test_ten_simulated_participants_of_the_shipped_protocol_are_ch3_psychophysics(tmp_path, monkeypatch):
    """The acceptance's study: the shipped protocol with 10 simulated participants is ch3.psychophysics to 1e-12.

    `ch3_stiffness_2afc` as shipped (seed 0, 270 trials each) and ch3.psychophysics's own MuJoCo lookup
    (108 palpations): `rhi study simulate` + `rhi study analyze` give every number of Table 3.3 and the §3.6
    statistics of `ch3.psychophysics(subjects=10)`.

    psignifit without overdispersion (`--fast`) keeps the 90 fits affordable; the fits with it are the same code.
    """
    from rhi.design import executors
    from rhi.experiments.ch3.discrimination import psychophysics, stimulus_table
    from rhi.experiments.participants import simulated_study
    from rhi.report.study import study_result

    monkeypatch.setitem(executors.DEFAULTS, "executor", "serial")  # short tasks: no pool on a busy machine
    p = load_protocol("ch3_stiffness_2afc")
    table = stimulus_table(("RHI", "PHANToM", "Rehab"))
    sim = simulated_study(p, 10, table=table, overdispersion=False, out=tmp_path / "sim")
    ref = psychophysics(subjects=10, seed=p.seed, overdispersion=False, table=table)
    assert len(sim.rows) == 10 * 270
    ours = {r.quantity: r.ours for t in study_result(tmp_path / "sim", overdispersion=False).tables for r in t.rows}
    theirs = {r.quantity: r.ours for t in ref.tables[:2] for r in t.rows}
    assert len(theirs) == 24 and set(theirs) <= set(ours)
    for k, v in theirs.items():
        assert ours[k] == pytest.approx(v, rel=1e-12, abs=1e-15), k
    np.testing.assert_array_equal(sim.weber, ref.arrays["weber"])


def test_a_discrimination_task_needs_its_fixture():
    text = load_protocol("ch3_stiffness_2afc").text
    a, b = text.index("[fixture]"), text.index("[display]")
    with pytest.raises(InvalidInput, match="^obstacle: needs a"):
        parse_protocol(tomllib.loads(text[:a] + text[text.index("[obstacle]"):]))
    with pytest.raises(InvalidInput, match="^fixture: a discrimination task"):
        parse_protocol(tomllib.loads(text[:a] + text[b:]))


def test_cli_simulate_then_analyze_reproduces_ch3_psychophysics_quick(tmp_path):
    """`rhi study simulate` (MuJoCo lookup, observers) + `rhi study analyze` = `ch3.psychophysics`, same seed.

    A small study (3 participants, 3 comparisons, one stroke duration) through the commands; the shipped protocol
    with 10 participants is compared through the API (`test_ten_simulated_participants_...`).
    """
    import json

    from rhi.experiments.ch3.discrimination import psychophysics

    text = load_protocol("ch3_stiffness_2afc").text.replace(
        "[-35.0, -25.0, -15.0, -5.0, 0.0, 5.0, 15.0, 25.0, 35.0]", "[-35.0, 0.0, 35.0]").replace(
        "repetitions = 10", "repetitions = 4").replace("seed = 0", "seed = 2")
    proto = tmp_path / "quick.toml"
    proto.write_text(text)
    env = {**os.environ, "PYTHONPATH": SRC, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa")}
    rhi = [sys.executable, "-m", "rhi", "study"]
    r = subprocess.run([*rhi, "simulate", str(proto), "--participants", "3", "--fast", "--durations", "1.0",
                        "--out", str(tmp_path / "sim"), "--executor", "serial"],  # the machine's cores run other tests
                       capture_output=True, text=True, env=env, timeout=900)
    assert r.returncode == 0, r.stderr
    assert "power of the one-way ANOVA" in r.stdout
    r = subprocess.run([*rhi, "analyze", str(tmp_path / "sim"), "--fast", "--out", str(tmp_path / "an")],
                       capture_output=True, text=True, env=env, timeout=900)
    assert r.returncode == 0, r.stderr
    got = {row["quantity"]: row["rhi"] for t in json.loads((tmp_path / "an" / "results.json").read_text())["results"][0]
           ["tables"] for row in t["rows"]}
    ref = psychophysics(subjects=3, repetitions=4, comparison_percent=(-35.0, 0.0, 35.0), durations=(1.0,),
                        overdispersion=False, seed=2)
    theirs = {row.quantity: row.ours for t in ref.tables[:2] for row in t.rows}
    assert len(theirs) == 24
    for k, v in theirs.items():
        assert got[k] == pytest.approx(v, rel=1e-12, abs=1e-15), k
    page = (tmp_path / "an" / "report.html").read_text()  # a study report judges no thesis claim
    assert "Headline claims" not in page and not (tmp_path / "an" / "fidelity.md").exists()


@pytest.mark.realtime  # Ray's start-up waits for its processes on the wall clock: run with the real-process tests
def test_cli_simulate_on_ray_gives_the_numbers_of_the_serial_executor(tmp_path):
    """`rhi study simulate --executor ray` prints the serial executor's numbers and writes the same answers.

    The palpations and the fits run as Ray tasks (a local instance of two workers).
    """
    pytest.importorskip("ray")
    text = load_protocol("ch3_stiffness_2afc").text.replace(
        "[-35.0, -25.0, -15.0, -5.0, 0.0, 5.0, 15.0, 25.0, 35.0]", "[-35.0, 0.0, 35.0]").replace(
        "repetitions = 10", "repetitions = 3")
    proto = tmp_path / "tiny.toml"
    proto.write_text(text)
    ray_dir = Path(tempfile.mkdtemp(prefix="rhi-ray-", dir="/tmp"))  # short: Ray's socket paths must fit 107 bytes
    env = {**os.environ, "PYTHONPATH": SRC, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "osmesa"),
           "RAY_TMPDIR": str(ray_dir)}
    out = {}
    try:
        for executor, workers in (("ray", "2"), ("serial", "1")):
            r = subprocess.run([sys.executable, "-m", "rhi", "study", "simulate", str(proto), "--participants", "2",
                                "--fast", "--durations", "1.0", "--out", str(tmp_path / executor), "--executor",
                                executor, "--workers", workers], capture_output=True, text=True, env=env, timeout=900)
            assert r.returncode == 0, r.stdout + r.stderr
            out[executor] = r.stdout.replace(str(tmp_path / executor), "OUT")
        # Ray's workers ran rhi's tasks (their logs name the task function)
        ran = [f for f in ray_dir.glob("ray/session_*/logs/worker-*.out") if "_ray_apply" in f.read_text()]
        assert ran, sorted(p.name for p in ray_dir.rglob("*"))[:40]
        sessions = [d for d in ray_dir.glob("ray/session_*") if not d.is_symlink()]
        assert len(sessions) == 1, sessions  # one Ray instance for every map of the study
    finally:
        shutil.rmtree(ray_dir, ignore_errors=True)
    assert out["ray"] == out["serial"] and "one-way ANOVA on WF" in out["ray"]
    for pid in ("S01", "S02"):
        assert (tmp_path / "ray" / pid / "responses.csv").read_text() == \
            (tmp_path / "serial" / pid / "responses.csv").read_text()


def test_simulated_users_refuse_another_teleoperation():
    from rhi.experiments.participants import simulated_path_study

    with pytest.raises(InvalidInput, match="^teleoperation.scale"):
        simulated_path_study(variant("ch5_path_following", x="scale = 1.0 |scale = 2.0 "), 2)
    with pytest.raises(InvalidInput, match="^teleoperation.offset"):
        simulated_path_study(variant("ch5_path_following", x="offset = [0.0, 0.0]|offset = [0.0, 0.01]"), 2)
