"""`rhi reproduce`: run every thesis experiment that exists and write the report.

With ``jobs`` > 1 the work runs in worker processes as tasks: a whole experiment with its figures,
or one part of an experiment that splits into independent parts (`Step.plan`), then the merge of
its parts with the figures. The longest tasks start first (by the times of the previous run in
`out`, else by the packaged ones, `timings.json`), so the workers stay busy until the end.
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import platform
import resource
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
from matplotlib.figure import Figure
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from rhi._lifetime import die_with_parent
from rhi.design.executors import DEFAULTS, configure, shared
from rhi.errors import InvalidInput, RhiError
from rhi.experiments.parts import Part, Plan
from rhi.experiments.result import Result
from rhi.report import headline, write_report
from rhi.report.claims import CLAIMS
from rhi.report.steps import STEPS, Step, chapters, experiments, step_names
from rhi.report.warmup import GROUPS, warm

__all__ = ["STEPS", "TIMINGS", "Step", "chapters", "experiments", "reproduce", "step_names"]

#: Wall times [s] of a reference run's tasks, by mode (the queue's order when `out` has no previous run).
TIMINGS = Path(__file__).with_name("timings.json")


def _report_progress(i: int, total: int, name: str, t_step: float, t0: float) -> None:
    """One line per finished step when stdout is not a terminal (rich draws nothing there)."""
    elapsed = time.perf_counter() - t0
    eta = elapsed / i * (total - i)
    print(f"[{i}/{total}] {name} done in {t_step:.1f} s; elapsed {elapsed:.0f} s, ETA {eta:.0f} s", flush=True)


def _descendants_cpu() -> float:
    """CPU time [s] of this process's live descendants, with the children they reaped (Linux /proc; else 0).

    The design pool's workers are forked by a fork server that lives as long as this process, so
    their time reaches `RUSAGE_CHILDREN` only at the end: counted here through the fork server.
    """
    try:
        stats = {}
        for entry in os.scandir("/proc"):
            if entry.name.isdigit():
                try:
                    with open(f"/proc/{entry.name}/stat", "rb") as f:
                        fields = f.read().rsplit(b")", 1)[1].split()
                except OSError:  # gone meanwhile
                    continue
                stats[int(entry.name)] = (int(fields[1]), sum(int(x) for x in fields[11:15]))
    except OSError:
        return 0.0
    total, frontier = 0, [os.getpid()]
    while frontier:
        parent = frontier.pop()
        for pid, (ppid, ticks) in stats.items():
            if ppid == parent:
                total += ticks
                frontier.append(pid)
    return total / os.sysconf("SC_CLK_TCK")


def _cpu() -> float:
    """CPU time [s] of this process, its finished children and its live descendants (the design pool's workers)."""
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + c.ru_utime + c.ru_stime + _descendants_cpu()


def _draw(s: Step, res: Result, out: Path) -> tuple[dict[str, Path], float]:
    """Draw the step's figures into out/figures (one open at a time): ({figure name: PNG path}, wall time [s])."""
    t = time.perf_counter()
    (out / "figures").mkdir(parents=True, exist_ok=True)
    paths = {}
    for name, draw in s.figures.items():
        path = out / "figures" / f"{res.name}.{name}.png"
        fig = draw(res)
        if not isinstance(fig, Figure):
            raise RhiError(f"figures: {s.name}'s {name!r} drew {type(fig).__name__}, not a matplotlib Figure")
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        paths[name] = path
    return paths, time.perf_counter() - t


def _worker_init(defaults: dict[str, Any], main_pid: int) -> None:
    """A reproduction worker: dies with the main process (no orphan after a kill), the main process's executor."""
    die_with_parent(main_pid)
    configure(**defaults)


def _step(name: str) -> Step:
    return next(s for s in STEPS if s.name == name)


def _task(kind: str, name: str, quick: bool, out: str, payload: Any = None) -> tuple[Any, float, float]:
    """One task of a parallel reproduction, in a worker process: (output, wall time [s], CPU time [s]).

    kind "step": run the experiment `name` and draw its figures, output (result, `_draw`'s output);
    "part": run `payload` (a `Part`), output its output; "merge": ``payload = (merge, outputs)``,
    output (the merged result, `_draw`'s output).
    """
    t, c = time.perf_counter(), _cpu()
    with shared():  # closed before the worker exits (an open pool's processes would keep it alive)
        if kind == "part":
            output = payload.run(progress=None)
        else:
            s = _step(name)
            res = s.run(**(s.quick if quick else s.full)) if kind == "step" else payload[0](payload[1])
            output = (res, _draw(s, res, Path(out)))
    return output, time.perf_counter() - t, _cpu() - c


def _previous_times(out: Path, mode: str) -> dict[str, float]:
    """Wall time per task of the previous run in `out` in the same mode, else of the packaged reference run."""
    try:
        meta = json.loads((out / "results.json").read_text())["meta"]
        if meta.get("mode") == mode:
            return {k: float(v) for k, v in {**meta["seconds_per_experiment"], **meta.get("seconds_per_task", {})}.items()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        pass
    try:
        return {k: float(v) for k, v in json.loads(TIMINGS.read_text())[mode].items()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return {}


def _part_key(name: str, label: str) -> str:
    return f"{name}[{label}]"


def _writable(out: Path) -> None:
    """Create `out` and check that files can be written there, before any experiment runs."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        raise InvalidInput(f"out: cannot write into {out} ({exc.strerror or exc})") from None


def _failed(task: str, exc: BaseException, out: Path) -> RhiError:
    """The one-line error of a failed task; its traceback goes to out/reproduce-error.log."""
    log = out / "reproduce-error.log"
    try:
        log.write_text("".join(traceback.format_exception(exc)))
        where = f"traceback in {log}"
    except OSError:
        where = "no traceback written"
    what = (str(exc).strip().splitlines() or [""])[0][:300]
    return RhiError(f"reproduce: {task} failed ({type(exc).__name__}: {what}; {where}); re-running the same "
                    f"command resumes from the finished design evaluations in {out / 'checkpoints'}")


def reproduce(out: str | Path = "out", *, only: str | None = None, quick: bool = False,
              experiment: str | None = None, jobs: int | None = None) -> tuple[Path, list[Result]]:
    """Run the experiments (all, one chapter or one experiment) and write out/report.html + out/results.json.

    Args:
        out: output directory.
        only: chapter id such as "ch3".
        quick: reduced resolution (seconds instead of minutes).
        experiment: one experiment id such as "ch7.example_3dof" (or its function name).
        jobs: tasks run at once, each in its own process (None: one per CPU; 1: in this process, one experiment
            after the other). A task is an experiment, or one part of an experiment that splits into parts
            (`Step.plan`). The results do not depend on it; the previous run's times in `out` order the queue
            longest first. With the Ray executor (`rhi.design.executors.configure`) the experiments run one at a time.

    Raises:
        InvalidInput: an unknown chapter or experiment, `jobs` not a positive integer, or `out` not writable.
        RhiError: an experiment failed: one line naming it (its traceback in out/reproduce-error.log).
    """
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise InvalidInput(f"jobs: must be a positive integer or None, got {jobs!r}")
    steps = [s for s in STEPS if only is None or s.chapter == only]
    if not steps:
        raise InvalidInput(f"only: unknown chapter {only!r}; available: {', '.join(chapters())}")
    if experiment is not None:
        steps = [s for s in steps if experiment in step_names(s)]
        if not steps:
            raise InvalidInput(f"experiment: unknown experiment {experiment!r}; available: {', '.join(experiments())}")
    out = Path(out)
    _writable(out)
    if DEFAULTS["executor"] == "ray":  # the cluster parallelises the maps; one driver runs the experiments
        jobs = 1
    mode = "quick" if quick else "full"
    jobs = jobs or os.cpu_count() or 1
    plans: dict[str, Plan] = {}  # the split experiments' plans: made here to size the pool when it has few tasks
    if 1 < jobs and len(steps) < jobs:
        plans = {s.name: s.plan(**(s.quick if quick else s.full)) for s in steps if s.plan is not None}
        jobs = min(jobs, sum(len(plans[s.name].parts) if s.name in plans else 1 for s in steps))
    results: dict[str, Result] = {}
    figures: dict[str, dict[str, Path]] = {}
    seconds: dict[str, float] = {}  # wall time of each experiment (its tasks' sum), for results.json
    cpu: dict[str, float] = {}  # its CPU time (with its pools' processes)
    drawing: dict[str, float] = {}  # the part of its wall time spent drawing its figures
    task_seconds: dict[str, float] = {}  # wall time of each part and merge of a split experiment
    warmup: dict[str, float] = {}  # wall time of the kernels' warm-up before the tasks, per group
    t0 = time.perf_counter()
    cols = (TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
            TimeElapsedColumn())

    def finished(s: Step, res: Result, drawn: tuple[dict[str, Path], float], t_step: float, c_step: float) -> None:
        if res.name != s.name:  # the registry's invariant: an experiment's id is its result's name
            raise RhiError(f"experiment: {s.name} returned a result named {res.name!r}")
        results[s.name], figures[s.name] = res, drawn[0]
        seconds[s.name], cpu[s.name], drawing[s.name] = round(t_step, 2), round(c_step, 2), round(drawn[1], 2)
        bar.advance(overall)
        if not sys.stdout.isatty():
            _report_progress(len(results), len(steps), s.name, t_step, t0)

    with Progress(*cols) as bar:
        overall = bar.add_task("reproduction", total=len(steps))
        if jobs == 1:
            with shared():
                for s in steps:
                    t_step, c_step = time.perf_counter(), _cpu()
                    kwargs = dict(s.quick if quick else s.full)
                    if s.progress:
                        sub = bar.add_task(f"  {s.chapter} {s.run.__name__}", total=None)
                        kwargs["progress"] = lambda k, n, sub=sub: bar.update(sub, completed=k, total=n)
                    try:
                        res = s.run(**kwargs)
                        drawn = _draw(s, res, out)
                    except Exception as exc:
                        raise _failed(s.name, exc, out) from exc
                    finished(s, res, drawn, time.perf_counter() - t_step, _cpu() - c_step)
        else:
            _parallel(steps, plans, quick, out, jobs, _previous_times(out, mode), finished, task_seconds, warmup)
    done: list[tuple[str, Result, dict]] = [(s.chapter, results[s.name], dict(figures[s.name])) for s in steps]
    meta = {"mode": mode, "chapters": only or ", ".join(chapters()), "seconds": round(time.perf_counter() - t0, 1),
            "cpu_seconds": round(sum(cpu.values()), 1),  # with every pool's processes (time(1) misses orphaned ones)
            "python": platform.python_version(), "jobs": jobs,
            "seconds_per_experiment": seconds, "cpu_seconds_per_experiment": cpu,
            "figure_seconds_per_experiment": drawing, "seconds_per_task": task_seconds,
            "warmup_seconds": warmup}
    path = write_report(done, out, meta=meta)
    print("\nHeadline claims of the thesis (details in report.html):")
    print(headline.to_text(headline.evaluate(CLAIMS, [r for _, r, _ in done])))
    return path, [r for _, r, _ in done]


def _queue(steps: list[Step], plans: dict[str, Plan], previous: dict[str, float]) -> list[tuple[float, str, Step, int]]:
    """The tasks, longest first: (estimated seconds, kind "step" or "part", step, part index or -1)."""
    queue: list[tuple[float, str, Step, int]] = []
    for s in steps:
        if s.name in plans:  # a part's own time, else its share (by work) of its experiment's
            parts = plans[s.name].parts
            share = previous.get(s.name, 0.0) / sum(p.work for p in parts)
            queue += [(previous.get(_part_key(s.name, p.label), share * p.work), "part", s, i)
                      for i, p in enumerate(parts)]
        else:
            queue.append((previous.get(s.name, 0.0), "step", s, -1))
    queue.sort(key=lambda e: -e[0])  # stable: the listed order among equal (unknown) times
    return queue  # a merge goes first once its parts are done


def _parallel(steps: list[Step], plans: dict[str, Plan], quick: bool, out: Path, jobs: int, previous: dict[str, float],
              finished: Callable[..., None], task_seconds: dict[str, float], warmup: dict[str, float]) -> None:
    """Run the steps' tasks in `jobs` worker processes, longest first, keeping every worker busy.

    The workers first compile (or load) the kernels, one `rhi.report.warmup` group each, so that no two
    processes compile the same kernel at once; `warmup` receives each group's wall time [s]. The split
    experiments' plans missing from `plans` are made here meanwhile.
    """
    running: dict[Future, tuple[str, Step, int]] = {}
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(jobs, mp_context=ctx, initializer=_worker_init,
                             initargs=(dict(DEFAULTS), os.getpid())) as pool:
        try:
            warming = {pool.submit(warm, group): group for group in GROUPS}  # the kernels, once, before any task
            plans = {s.name: plans.get(s.name) or s.plan(**(s.quick if quick else s.full))
                     for s in steps if s.plan is not None}
            queue = _queue(steps, plans, previous)
            outputs: dict[str, dict[int, Any]] = {name: {} for name in plans}
            spent: dict[str, list[float]] = {name: [0.0, 0.0] for name in plans}  # wall and CPU of the parts so far
            for warmed in wait(warming).done:
                try:
                    warmup[warming[warmed]] = round(warmed.result(), 2)
                except Exception as exc:
                    raise _failed(f"the warm-up of {warming[warmed]}", exc, out) from exc
            while queue or running:
                while queue and len(running) < jobs:  # one task per free worker: the order decides late
                    _, kind, s, i = queue.pop(0)
                    payload: Any = None
                    if kind == "part":
                        payload = plans[s.name].parts[i]
                    elif kind == "merge":
                        payload = (plans[s.name].merge, [outputs[s.name][k] for k in range(len(plans[s.name].parts))])
                    running[pool.submit(_task, kind, s.name, quick, str(out), payload)] = (kind, s, i)
                done_now, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in done_now:
                    kind, s, i = running.pop(fut)
                    try:
                        output, t_task, c_task = fut.result()
                    except Exception as exc:
                        label = "merge" if kind == "merge" else plans[s.name].parts[i].label if kind == "part" else ""
                        task = f"{s.name} ({label})" if label else s.name
                        raise _failed(task, exc, out) from exc
                    if kind == "step":
                        finished(s, *output, t_task, c_task)
                        continue
                    part: Part | None = plans[s.name].parts[i] if kind == "part" else None
                    task_seconds[_part_key(s.name, part.label if part else "merge")] = round(t_task, 2)
                    spent[s.name][0] += t_task
                    spent[s.name][1] += c_task
                    if kind == "part":
                        outputs[s.name][i] = output
                        if len(outputs[s.name]) == len(plans[s.name].parts):
                            queue.insert(0, (0.0, "merge", s, -1))
                    else:
                        finished(s, *output, *spent[s.name])
        except BaseException:  # a task failed (or Ctrl-C, SIGTERM): the queued ones do not run, the running ones stop
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in dict(getattr(pool, "_processes", None) or {}).values():  # CPython's {pid: Process}
                with contextlib.suppress(OSError):
                    proc.terminate()  # else leaving the pool would wait for the running tasks to end
            raise

