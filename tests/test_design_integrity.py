"""Design runs that can be trusted.

Checkpoints refuse tampered/truncated/foreign files; a killed pooled run leaves no worker process behind; bad
optimiser settings and misspelled parameters are refused.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import child_env

from rhi.design import EvalCache
from rhi.errors import InvalidInput


def _cache(path: Path) -> EvalCache:
    """A fresh checkpoint with three evaluations at `path`."""
    path.unlink(missing_ok=True)
    c = EvalCache(path, tag="problem-A")
    c.map(lambda x: {"C2": float(x[0]) * 2.0, "coverage": 1.0}, [[0.1], [0.2], [0.3]], lambda f, xs: [f(x) for x in xs])
    return c


def test_checkpoint_round_trip_and_integrity(tmp_path):
    path = tmp_path / "ck.json"
    _cache(path)
    assert len(EvalCache(path, tag="problem-A")) == 3  # a good file replays
    blob = json.loads(path.read_text())
    assert blob["schema"] == "rhi.design.checkpoint" and blob["version"] == 1 and len(blob["sha256"]) == 64
    # one tampered entry (the case changed the C2 optimum silently)
    key = next(iter(blob["results"]))
    bad = json.loads(path.read_text())
    bad["results"][key]["C2"] += 0.5
    path.write_text(json.dumps(bad))
    with pytest.raises(InvalidInput, match="checkpoint: .* checksum"):
        EvalCache(path, tag="problem-A")
    # truncated
    _cache(path)
    text = path.read_text()
    path.write_text(text[: len(text) // 2])
    with pytest.raises(InvalidInput, match="checkpoint: .* [(]truncated"):
        EvalCache(path, tag="problem-A")
    # foreign JSON, another schema version, another problem
    path.write_text(json.dumps({"tag": "problem-A", "results": {}}))
    with pytest.raises(InvalidInput, match="checkpoint: .* not an rhi design checkpoint"):
        EvalCache(path, tag="problem-A")
    _cache(path)
    blob = json.loads(path.read_text())
    path.write_text(json.dumps({**blob, "version": 99}))
    with pytest.raises(InvalidInput, match="schema version 99"):
        EvalCache(path, tag="problem-A")
    _cache(path)
    with pytest.raises(InvalidInput, match="another problem"):
        EvalCache(path, tag="problem-B")


def _rewrite(path: Path, edit) -> None:
    """Apply `edit` to the checkpoint's results and store it with a valid checksum (a deliberate edit)."""
    from rhi.design.checkpoint import _digest

    blob = json.loads(path.read_text())
    edit(blob["results"])
    blob["sha256"] = _digest(blob["tag"], blob["results"])
    path.write_text(json.dumps(blob))


def test_checkpoint_values_are_checked_not_only_its_checksum(tmp_path):
    path = tmp_path / "ck.json"
    serial = lambda f, xs: [f(x) for x in xs]  # noqa: E731
    fn = lambda x: {"C2": float(x[0]) * 2.0, "coverage": 1.0}  # noqa: E731
    _cache(path)
    _rewrite(path, lambda r: r[next(iter(r))].__setitem__("C2", 99.0))  # a wrong value, checksum recomputed
    c = EvalCache(path, tag="problem-A")  # 3 entries, 3 spot checks: the edited one is recomputed
    with pytest.raises(InvalidInput, match="checkpoint: .* recomputes to"):
        c.map(fn, [[0.5]], serial)
    for edit, match in [(lambda r: r[next(iter(r))].pop("C2"), "has fields"),
                        (lambda r: r.__setitem__("zz", {"C2": 1.0, "coverage": 1.0}), "not a design vector"),
                        (lambda r: r.__setitem__(next(iter(r)), [1, 2]), "not a record of numbers"),
                        (lambda r: r.__setitem__("0x1p-1,0x1p-1", {"C2": 1.0, "coverage": 1.0}), "of 1 values")]:
        _cache(path)
        _rewrite(path, edit)
        with pytest.raises(InvalidInput, match=f"checkpoint: .*{match}"):
            EvalCache(path, tag="problem-A")
    _cache(path)  # an honest file replays (its spot checks pass)
    c = EvalCache(path, tag="problem-A")
    assert c.map(fn, [[0.1], [0.2]], serial) == [fn([0.1]), fn([0.2])] and c.hits == 2


WRITER = """
import sys
import numpy as np
from rhi.design import EvalCache
path, me = sys.argv[1], int(sys.argv[2])
serial = lambda f, xs: [f(x) for x in xs]
for i in range(40):
    c = EvalCache(path, tag="shared", spot_checks=0)
    c.map(lambda x: {"v": float(x[0])}, [[me * 1000.0 + i]], serial)
"""


def test_two_writers_of_one_checkpoint_both_finish_and_leave_a_valid_file(tmp_path):
    """The first-run crash: two experiments saving one checkpoint at once (the fixed `.tmp` name raced)."""
    path = tmp_path / "shared.json"
    env = child_env()
    procs = [subprocess.Popen([sys.executable, "-c", WRITER, str(path), str(k)], env=env, stderr=subprocess.PIPE,
                              text=True) for k in (1, 2)]
    errs = [p.communicate(timeout=120)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], errs
    data = EvalCache(path, tag="shared").data  # loads: schema, checksum and entries valid
    values = {r["v"] for r in data.values()}
    assert values <= {k * 1000.0 + i for k in (1, 2) for i in range(40)}
    assert {1039.0, 2039.0} & values and len(values) >= 40  # each save merges what the other wrote
    assert not list(tmp_path.glob("*.tmp"))  # no temporary file left behind


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")


SCRIPT = """
import sys, time
from rhi.design.executors import PoolExecutor
ex = PoolExecutor(2)
it = ex.imap(time.sleep, [60.0] * 4)
while len(ex._pool._processes) < 2:
    time.sleep(0.05)
time.sleep(0.3)  # the workers run their initializer
print(" ".join(map(str, ex._pool._processes)), flush=True)
list(it)
"""


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to inspect processes")
def test_killing_a_pooled_run_leaves_no_orphan_workers(tmp_path):
    env = child_env()
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], stdout=subprocess.PIPE, text=True, env=env)
    try:
        workers = [int(p) for p in proc.stdout.readline().split()]
        assert len(workers) == 2 and all(_alive(p) for p in workers)
        server = {int(Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()[1]) for p in workers}
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and any(_alive(p) for p in workers + sorted(server)):
            time.sleep(0.1)
        left = [p for p in workers + sorted(server) if _alive(p)]
        assert not left, f"orphan processes left alive: {left}"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.fixture(scope="module")
def problem():
    from rhi.experiments import ch4

    return ch4.setup.problem("theta_z", density=20)


def test_design_refuses_bad_vectors_names_and_settings(problem):
    import dataclasses

    from rhi.design import evaluate, optimize

    with pytest.raises(InvalidInput, match="x: contains NaN"):
        evaluate(problem, [np.nan])
    with pytest.raises(InvalidInput, match="bounds: unknown design parameter.*'theta_zz'"):
        dataclasses.replace(problem, bounds={"theta_zz": (-1.0, 1.0)})
    with pytest.raises(InvalidInput, match="fixed: unknown design parameter.*'l22'"):
        dataclasses.replace(problem, fixed={**problem.fixed, "l22": 0.2})
    for kw, name in [({"popsize": 0}, "popsize"), ({"maxiter": -1}, "maxiter"), ({"tol": float("nan")}, "tol"),
                     ({"strategy": "best"}, "strategy"), ({"seed": 1.5}, "seed"), ({"separation": 0.0}, "separation")]:
        with pytest.raises(InvalidInput, match=name):
            optimize(problem, **kw)
