"""No process outlives its parent, and signals stop a run safely (issue 24).

Each command runs as the leader of a new session; after SIGKILL of the leader no process of that session may
be left after 5 s (pool workers, their fork servers and pools, the browser view's process). SIGTERM to `rhi run`
is an e-stop like Ctrl-C: zero torque, the reason in the log and the summary, both complete on disk.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import child_env

from rhi.cli import main
from rhi.errors import RhiError
from rhi.sim import Log

pytestmark = [pytest.mark.realtime,
              pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to inspect processes")]


def _session(sid: int) -> list[tuple[int, str]]:
    """(pid, command line) of the live processes of session `sid`."""
    out = []
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                fields = Path(f"/proc/{entry.name}/stat").read_text().rsplit(")", 1)[1].split()
                cmd = Path(f"/proc/{entry.name}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if int(fields[3]) == sid and fields[0] not in ("Z", "X"):
                out.append((int(entry.name), cmd[:120]))
    return out


def _start(*args: str, stdout=subprocess.DEVNULL) -> subprocess.Popen:
    env = {**child_env(), "MPLBACKEND": "Agg"}
    return subprocess.Popen([sys.executable, "-m", "rhi", *args], start_new_session=True, env=env,
                            stdout=stdout, stderr=subprocess.PIPE, text=True)


def _wait_for(cond, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.2)
    return False


def _kill_leader_and_check(proc: subprocess.Popen, sig: int = signal.SIGKILL, wait: float = 30.0) -> None:
    sid = proc.pid
    try:
        proc.send_signal(sig)
        proc.wait(timeout=wait)
        _wait_for(lambda: not _session(sid), 5.0)
        left = _session(sid)
        assert not left, f"processes left 5 s after {signal.Signals(sig).name} of the leader: {left}"
    finally:
        for pid, _ in _session(sid):  # a failed test leaves nothing behind either
            os.kill(pid, signal.SIGKILL)


def test_sigkill_of_reproduce_leaves_no_worker(tmp_path):
    """`rhi reproduce --jobs 2`: two spawned workers, each with a fork server and a design pool."""
    proc = _start("reproduce", "--jobs", "2", "--quick", "--only", "ch4", "--out", str(tmp_path / "out"))
    # wait until the workers' design pools run (leader, resource tracker, 2 workers, 2 fork servers, pools)
    assert _wait_for(lambda: len(_session(proc.pid)) >= 8, 240.0), _session(proc.pid)
    _kill_leader_and_check(proc)


def _view_child(sid: int) -> bool:
    return any("spawn_main" in cmd for _, cmd in _session(sid))


def _logging(path: Path) -> bool:
    """Whether the run streams its log (its view, if any, serves: the loop starts after it)."""
    try:
        return len(Log.load(path)) > 0
    except (OSError, RhiError):
        return False


def test_sigkill_of_run_with_view_leaves_no_view(tmp_path):
    proc = _start("run", "rhi4", "--config", "ch7_full", "--view", "--view-port", "0", "--duration", "120",
                  "--log", str(tmp_path / "run.rhilog"))
    assert _wait_for(lambda: _view_child(proc.pid) and _logging(tmp_path / "run.rhilog"), 180.0), _session(proc.pid)
    _kill_leader_and_check(proc)


def test_sigterm_of_view_ends_its_child():
    proc = _start("view", "--port", "0", "--duration", "120", stdout=subprocess.PIPE)
    assert any("simulated live" in line for line in iter(proc.stdout.readline, ""))  # printed once the view serves
    assert _view_child(proc.pid), _session(proc.pid)
    time.sleep(1.0)  # the live loop runs
    _kill_leader_and_check(proc, signal.SIGTERM)
    assert proc.returncode == 128 + signal.SIGTERM, proc.stderr.read() if proc.stderr else ""


def test_sigterm_of_a_log_view_is_the_shells_code(tmp_path):
    """`rhi view LOG` ends on SIGTERM as a live view does: 143, its page's server closed."""
    log = tmp_path / "r.rhilog"
    assert main(["run", "rhi4", "--config", "ch7_full", "--duration", "0.05", "--fast", "--log", str(log),
                 "--summary", str(tmp_path / "s.json")]) == 0
    proc = _start("view", str(log), "--port", "0", stdout=subprocess.PIPE)
    assert any("paused at its start" in line for line in iter(proc.stdout.readline, ""))  # printed once it serves
    _kill_leader_and_check(proc, signal.SIGTERM)
    assert proc.returncode == 128 + signal.SIGTERM, proc.stderr.read() if proc.stderr else ""


def test_sigkill_of_compare_view_leaves_no_page():
    """`rhi view --compare rhi4 phantom`: its page's process (`RemoteCompare`) goes with it."""
    proc = _start("view", "--compare", "rhi4", "phantom", "--port", "0", "--duration", "120", stdout=subprocess.PIPE)
    assert any("side by side" in line for line in iter(proc.stdout.readline, ""))  # printed once the page serves
    assert _view_child(proc.pid), _session(proc.pid)
    _kill_leader_and_check(proc)


@pytest.mark.parametrize("when", ["warming up", "live"])
def test_sigterm_of_compare_view_stops_every_loop_and_its_page(when):
    """`rhi view --compare`: SIGTERM, while it warms up or runs, ends every device's loop and the page's process.

    The exit code is the shell's for SIGTERM (143, as `rhi run` and `rhi view`, docs/runtime.md).
    """
    proc = _start("view", "--compare", "rhi4", "phantom", "--port", "0", "--duration", "120", stdout=subprocess.PIPE)
    seen = []
    for line in iter(proc.stdout.readline, ""):
        seen.append(line)
        if f"rhi view: {when}" in line:
            break
    assert _view_child(proc.pid), (seen, _session(proc.pid))
    if when == "live":
        time.sleep(1.0)  # the loops start (with a cold kernel cache they may still compile: they end after that)
    _kill_leader_and_check(proc, signal.SIGTERM, wait=60.0)
    out = "".join(seen) + proc.stdout.read()
    assert proc.returncode == 128 + signal.SIGTERM, out + (proc.stderr.read() if proc.stderr else "")
    if when == "live" and "fault (" not in out:  # each loop ended and said how it ran (unless one faulted on a
        # loaded machine: then the signal came while the page waited for a reset, outside the loops, and ends it too)
        assert "rhi view: rhi4: 1 run(s)" in out and "rhi view: phantom: 1 run(s)" in out, out


def test_sigterm_of_run_is_an_estop_with_log_and_summary_on_disk(tmp_path):
    log, summary = tmp_path / "run.rhilog", tmp_path / "summary.json"
    proc = _start("run", "rhi4", "--config", "ch7_full", "--duration", "120", "--log", str(log),
                  "--summary", str(summary))
    try:
        assert _wait_for(lambda: _logging(log), 180.0)
        assert json.loads(summary.read_text())["running"]  # written before the run started
        proc.send_signal(signal.SIGTERM)
        err = proc.communicate(timeout=60)[1]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signal.SIGTERM, err
    s = json.loads(summary.read_text())
    assert "running" not in s and s["fault_kind"] == "estop" and s["fault"].endswith("SIGTERM") and s["ticks"] > 0
    full = Log.load(log)
    assert full.fault == s["fault"] and len(full) == s["ticks"] and (full.tau[-1] == 0).all()
    assert "fault (estop): emergency stop: SIGTERM" in err.strip().splitlines()[-1]


def test_a_view_process_that_dies_before_serving_is_an_error_at_once():
    """RemoteView waits for its child's port only while the child lives (a child that cannot serve: no 120 s hang)."""
    import multiprocessing as mp

    from rhi.viz.remote import _port_when_ready

    ctx = mp.get_context("fork")
    ready = ctx.Queue()
    child = ctx.Process(target=sys.exit, args=(3,))
    child.start()
    child.join()
    with pytest.raises(RhiError, match=r"view: its process ended before serving \(exit code 3\)"):
        _port_when_ready(ready, child, 60.0)
    ready.put(8080)
    assert _port_when_ready(ready, child, 60.0) == 8080  # a port already put is taken whatever the process's state
