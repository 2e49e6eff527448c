"""First-use compile time of the controller's Numba kernels (a fresh clone, CI, a new user's first run).

The kernels are compiled once per machine and cached on disk (`cache=True`); this times that
once, stage by stage, in a fresh temporary ``NUMBA_CACHE_DIR`` in a new process:

1. ``Device.terms`` on rhi4 (`rhi.chain_kernel.chain_terms`: chain dynamics + `rhi.terms_kernel.task_terms`);
2. the composed tick (`rhi.control.kernels.step.tick` with the allocation kernels), `bench_control.make`'s
   controller with the whole-tick kernel switched off;
3. the whole tick in one call (`rhi.control.kernels.whole.whole`, which links stages 1 and 2 and the
   passivity kernel).

Baseline measured in the same run: the package at git revision PREVIOUS (extracted with `git archive`,
run the same way; skipped outside a git checkout). Times are the child process's CPU seconds
(steadier than wall clock on a shared machine); the stages run in order in one process, so Numba's
own helpers compiled by an earlier stage are not paid again by a later one.

    PYTHONPATH=src python benchmarks/bench_compile.py [--previous REV] [--repeat K]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from revision import source_at

#: main before the compile-time work of issue 14
PREVIOUS = "e9a3029"
STAGES = ("Device.terms (chain_terms)", "composed tick (step.tick)", "whole tick (whole.whole)")


def stages() -> list[float]:
    """CPU seconds of the three stages' first calls in this process (the child's work)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_control as bc

    import rhi

    dev = rhi.device("rhi4")
    a = bc.ticks(3)[1]
    out = []
    t0 = time.process_time()
    dev.terms(a[1], a[2])
    out.append(time.process_time() - t0)
    c = bc.make(dev)
    c._kernel.whole_ok = False
    t0 = time.process_time()
    c.step(*a)
    out.append(time.process_time() - t0)
    c = bc.make(dev)
    t0 = time.process_time()
    c.step(*a)
    out.append(time.process_time() - t0)
    return out


def measure(src: Path) -> list[float] | str:
    """The stages' CPU seconds for the package in `src`, in a new process with an empty Numba cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "PYTHONPATH": str(src), "NUMBA_CACHE_DIR": cache}
        out = subprocess.run([sys.executable, __file__, "--stages-only"], capture_output=True, text=True, env=env)
    if out.returncode != 0:
        return f"failed: {out.stderr.strip().splitlines()[-1] if out.stderr.strip() else out.returncode}"
    return [float(v) for v in out.stdout.split()]


def previous(rev: str) -> list[float] | str:
    """The stages' CPU seconds for the package at git revision `rev`, or why it could not run."""
    try:
        with source_at(rev) as src:
            return measure(src)
    except LookupError as exc:
        return f"skipped ({exc})"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--previous", default=PREVIOUS, help="git revision of the baseline")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each (best kept), alternating")
    ap.add_argument("--stages-only", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.stages_only:  # a child run (fresh NUMBA_CACHE_DIR set by the parent)
        print(*stages())
        return
    load = os.getloadavg()[0]
    now: list[list[float]] = []
    before: list[list[float]] = []
    why = ""
    for i in range(a.repeat):
        print(f"run {i + 1}/{a.repeat}: this tree ...", file=sys.stderr, flush=True)
        m = measure(Path(__file__).resolve().parents[1] / "src")
        if isinstance(m, str):
            sys.exit(f"this tree {m}")
        now.append(m)
        print(f"run {i + 1}/{a.repeat}: @{a.previous} ...", file=sys.stderr, flush=True)
        p = previous(a.previous)
        if isinstance(p, str):
            why = p
        else:
            before.append(p)
    best = [min(r[k] for r in now) for k in range(3)]
    base = [min(r[k] for r in before) for k in range(3)] if before else None
    print(f"first-use Numba compile, CPU s, fresh NUMBA_CACHE_DIR, best of {a.repeat}; load average "
          f"{load:.2f} -> {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    print(f"  {'stage':30s} {'this tree':>10s} {'@' + a.previous:>10s} {'ratio':>7s}")
    for k, name in enumerate(STAGES):
        b = f"{base[k]:10.1f} {base[k] / best[k]:6.2f}x" if base else f"{'-':>10s} {'-':>7s}"
        print(f"  {name:30s} {best[k]:10.1f} {b}")
    total = sum(best)
    b = f"{sum(base):10.1f} {sum(base) / total:6.2f}x" if base else f"{'-':>10s} {'-':>7s}"
    print(f"  {'total':30s} {total:10.1f} {b}")
    if not base:
        print(f"  previous implementation: {why}")


if __name__ == "__main__":
    main()
