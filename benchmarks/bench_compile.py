"""First use of the compiled code, cold (a fresh install: Numba compiles) and warm (loaded from Numba's disk cache).

Three stages, in order, in one new process each time (a later stage does not pay again for kernels an
earlier one compiled):

1. ``Device.terms`` on rhi4 (the chain dynamics and task terms);
2. the tick: the first ``NullSpaceController.step`` of `bench_control.make`'s ch7 controller on its
   compiled route (the whole tick in one call);
3. ``simulate``: 50 ms of `bench_sim`'s palpation on the compiled simulation loop (`rhi.sim._compiled.fast_loop`).

Cold: a fresh temporary ``NUMBA_CACHE_DIR``; warm: a second process on the cache the cold one left.
Baseline measured in the same run: the warm process (its ratio cold / warm is printed), and with
``--previous REV`` the package at that git revision run the same way (extracted with `git archive`).
Times are CPU seconds of the stage process (steadier than wall clock on a shared machine) and wall seconds (on a
shared machine they measure its load too); the whole process's CPU with its children is printed too: on a cold cache
a controller starts compiling its whole tick in a child when it is made (`rhi.jit.compile_aside`), whose CPU the
stages' CPU leaves out. Each stage makes its own controller just before it.
Issue 29's target: ≤ 20 s wall from a fresh install to the first compiled tick on 2 cores: stages 1 + 2 cold, and
from the cold process's launch (the interpreter, imports and making the controller too).

``--kernels K`` adds the K kernels whose cold compile took the most CPU, each split into Numba's front end
(typing and lowering to LLVM IR), LLVM's function and module optimisation passes, and machine code
generation (it wraps private methods of Numba's code library; benchmark only). ``--serial``: no child compiles aside
(`rhi.jit.ASIDE` off), so that the kernel profile holds every kernel of the first tick and the stages' CPU all of
their compile.

    PYTHONPATH=src python benchmarks/bench_compile.py [--previous REV] [--repeat K] [--kernels K] [--serial]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path

from revision import source_at

STAGES = ("Device.terms", "tick (controller.step)", "simulate (compiled loop)")


def _profile_kernels() -> dict[str, dict[str, float]]:
    """Per kernel: compiles, CPU seconds of front end, LLVM function passes, module passes and machine code."""
    from numba.core import codegen, event

    rows: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
    stack: list[list] = []  # [start CPU, CPU of nested compiles and LLVM work, name]

    def wrap(name: str, key: str) -> None:
        f = getattr(codegen.CPUCodeLibrary, name)

        def timed(self, *args, **kwargs):
            t0 = time.process_time()
            try:
                return f(self, *args, **kwargs)
            finally:
                dt = time.process_time() - t0
                if stack:
                    rows[stack[-1][2]][key] += dt
                    stack[-1][1] += dt

        setattr(codegen.CPUCodeLibrary, name, timed)

    for name, key in (("_optimize_functions", "function passes"), ("_optimize_final_module", "module passes"),
                      ("_finalize_final_module", "machine code")):
        wrap(name, key)

    class Listener(event.Listener):
        def on_start(self, ev) -> None:
            f = getattr(ev.data.get("dispatcher"), "py_func", None)
            stack.append([time.process_time(), 0.0, f"{f.__module__}.{f.__qualname__}" if f else "?"])

        def on_end(self, ev) -> None:
            t0, inner, name = stack.pop()
            dt = time.process_time() - t0
            if stack:
                stack[-1][1] += dt
            rows[name]["front end"] += dt - inner
            rows[name]["compiles"] += 1

    event.register("numba:compile", Listener())
    return rows


def stages(kernels: bool, serial: bool) -> dict:
    """CPU and wall seconds of the three stages' first calls in this process, and the kernel profile."""
    rows = _profile_kernels() if kernels else {}
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import bench_control as bc
    import bench_sim as bs

    import rhi
    from rhi import jit
    from rhi.sim._compiled import fast_loop

    jit.ASIDE[0] = not serial

    dev = rhi.device("rhi4")
    a = bc.ticks(3)[1]
    ctrl = bc.make(dev)  # on a cold cache its whole tick starts compiling here, in a child (`rhi.jit.compile_aside`)
    cpu, wall, first_tick_at = [], [], 0.0
    for call in (lambda: dev.terms(a[1], a[2]), lambda: ctrl.step(*a), lambda: bs.run(bs.full_controller(), 0.05)):
        c0, w0 = time.process_time(), time.perf_counter()
        call()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
        if len(wall) == 2:
            first_tick_at = time.time()  # (the parent's clock: from the process's launch, `measure`)
    for t in threading.enumerate():  # `rhi.jit.compile_aside`'s children: reaped, so this process counts their CPU
        if t.name == "rhi.jit aside":
            t.join()
    return {"cpu": cpu, "wall": wall, "first_tick_at": first_tick_at, "compiled_loop": fast_loop.last is not None,
            "kernels": {k: dict(v) for k, v in rows.items()}}


def measure(src: Path, cache: str, kernels: bool = False, serial: bool = False) -> dict | str:
    """`stages` for the package in `src` in a new process on the Numba cache folder `cache`, or why it failed."""
    env = {**os.environ, "PYTHONPATH": str(src), "NUMBA_CACHE_DIR": cache}
    before, launched = resource.getrusage(resource.RUSAGE_CHILDREN), time.time()
    out = subprocess.run([sys.executable, __file__, "--stages-only", *(["--kernels", "1"] if kernels else []),
                          *(["--serial"] if serial else [])],
                         capture_output=True, text=True, env=env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        return f"failed: {out.stderr.strip().splitlines()[-1] if out.stderr.strip() else out.returncode}"
    res = json.loads(out.stdout.strip().splitlines()[-1])
    res["from_launch"] = res["first_tick_at"] - launched  # interpreter start, imports, the controller, stages 1 + 2
    res["process_cpu"] = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime  # with its children
    return res


def cold_warm(src: Path, kernels: bool = False, serial: bool = False) -> tuple[dict, dict] | str:
    """(cold, warm) `stages` of the package in `src`: a fresh cache, then the same cache again."""
    with tempfile.TemporaryDirectory() as cache:
        cold = measure(src, cache, kernels, serial)
        if isinstance(cold, str):
            return cold
        warm = measure(src, cache, serial=serial)
        return (cold, warm) if not isinstance(warm, str) else warm


def _best(runs: list[dict], key: str) -> list[float]:
    return [min(r[key][k] for r in runs) for k in range(len(STAGES))]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--previous", help="git revision of an extra baseline (the package then), run the same way")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each (best kept)")
    ap.add_argument("--kernels", type=int, default=0, help="list the K costliest kernels of the cold compile")
    ap.add_argument("--serial", action="store_true", help="no child compiles aside: one process compiles everything")
    ap.add_argument("--stages-only", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.stages_only:  # a child run (NUMBA_CACHE_DIR set by the parent)
        print(json.dumps(stages(bool(a.kernels), a.serial)))
        return
    load = os.getloadavg()[0]
    trees = {"this tree": Path(__file__).resolve().parents[1] / "src"}
    runs: dict[str, list[tuple[dict, dict]]] = defaultdict(list)
    for i in range(a.repeat):
        for label, src in trees.items():
            print(f"run {i + 1}/{a.repeat}: {label} ...", file=sys.stderr, flush=True)
            m = cold_warm(src, kernels=a.kernels > 0 and i == 0, serial=a.serial)
            if isinstance(m, str):
                sys.exit(f"{label} {m}")
            runs[label].append(m)
        if a.previous:
            print(f"run {i + 1}/{a.repeat}: @{a.previous} ...", file=sys.stderr, flush=True)
            try:
                with source_at(a.previous) as src:
                    m = cold_warm(src, serial=a.serial)
            except LookupError as exc:
                m = f"skipped ({exc})"
            if isinstance(m, str):
                print(f"  @{a.previous}: {m}", file=sys.stderr)
            else:
                runs["@" + a.previous].append(m)
    print(f"first use of the compiled code, best of {a.repeat}; load average {load:.2f} -> "
          f"{os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    for label, rs in runs.items():
        cold_cpu, warm_cpu = _best([c for c, _ in rs], "cpu"), _best([w for _, w in rs], "cpu")
        cold_wall, warm_wall = _best([c for c, _ in rs], "wall"), _best([w for _, w in rs], "wall")
        print(f"\n{label} (compiled simulation loop taken: {rs[0][0]['compiled_loop']})")
        print(f"  {'stage':28s} {'cold CPU s':>10s} {'cold wall s':>11s} {'warm CPU s':>10s} {'warm wall s':>11s} "
              f"{'cold/warm CPU':>13s}")
        for k, name in enumerate(STAGES):
            print(f"  {name:28s} {cold_cpu[k]:10.2f} {cold_wall[k]:11.2f} {warm_cpu[k]:10.3f} {warm_wall[k]:11.3f} "
                  f"{cold_cpu[k] / warm_cpu[k]:12.0f}x")
        first = cold_cpu[0] + cold_cpu[1]
        print(f"  to the first compiled tick (stages 1 + 2): cold {cold_wall[0] + cold_wall[1]:.1f} s wall, {first:.1f} s CPU "
              f"of the process; warm {warm_wall[0] + warm_wall[1]:.3f} s wall, {warm_cpu[0] + warm_cpu[1]:.3f} s CPU; "
              f"target (issue 29) <= 20 s wall on 2 cores")
        print(f"  from the cold process's launch to its first compiled tick (interpreter, imports, the controller, "
              f"stages 1 + 2): {min(c['from_launch'] for c, _ in rs):.1f} s wall; warm "
              f"{min(w['from_launch'] for _, w in rs):.1f} s")
        print(f"  CPU of the whole cold process with its children (imports, the 3 stages, children compiling aside): "
              f"{min(c['process_cpu'] for c, _ in rs):.1f} s")
    first_runs = runs["this tree"][0][0]["kernels"]
    if a.kernels and first_runs:
        cols = ("front end", "function passes", "module passes", "machine code")
        total = {c: sum(r.get(c, 0.0) for r in first_runs.values()) for c in cols}
        print(f"\ncold compile by kernel, CPU s (all {len(first_runs)} kernels: "
              + ", ".join(f"{c} {v:.1f}" for c, v in total.items()) + ")")
        print(f"  {'kernel':58s} {'n':>3s} " + " ".join(f"{c:>15s}" for c in cols))
        for name, r in sorted(first_runs.items(), key=lambda kv: -sum(kv[1].get(c, 0.0) for c in cols))[:a.kernels]:
            print(f"  {name[-58:]:58s} {int(r.get('compiles', 0)):3d} "
                  + " ".join(f"{r.get(c, 0.0):15.2f}" for c in cols))


if __name__ == "__main__":
    main()
