"""The `rhi warmup` command: compile, or load from Numba's disk cache, every kernel rhi runs, with a progress bar.

On a cold cache (a fresh install, or after an update of any kernel module, `rhi.jit`) the first
call of each kernel compiles it (about two minutes of CPU in all); afterwards every process loads
them from the cache in seconds. `./run` runs this once after installing. The steps run on a pool of
processes (``--workers``, default the CPU count), one step per task, the heaviest first: each process saves
what it compiles into the shared cache, and a kernel two steps share is compiled by both only if both reach it
before either has saved it (the saves are serialised, `rhi.jit`); the pool's processes end with this one.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

import numpy as np

EXAMPLE = "example:\n  rhi warmup            # once after installing or updating rhi\n"


def _mid(dev) -> np.ndarray:
    lo, hi = dev.joint_limits
    finite = np.isfinite(lo) & np.isfinite(hi)
    return np.where(finite, 0.5 * (np.where(finite, lo, 0.0) + np.where(finite, hi, 0.0)), 0.3)


def _terms() -> None:
    from rhi.devices.model import available_devices, device

    for name in available_devices():
        dev = device(name)
        dev.terms(_mid(dev), np.full(dev.n, 1e-3), check=False)


def _batch() -> None:
    from rhi import metrics
    from rhi.devices.batch import terms
    from rhi.devices.model import device

    dev = device("rhi4")
    terms(dev, _mid(dev) + np.random.default_rng(0).uniform(-0.1, 0.1, (64, dev.n)), ("x", "J", "dJ", "M", "g"))
    dev = device("gen3")  # a spatial task: the compiled measures of rhi.metrics._small
    t = terms(dev, _mid(dev) + np.random.default_rng(0).uniform(-0.1, 0.1, (64, dev.n)), ("J", "M"))
    metrics.effective_manipulability(t["J"], [0.0, 0.0, 1.0])
    metrics.effective_inertia(t["J"], t["M"], [0.0, 0.0, 1.0])
    metrics.apparent_inertia(t["J"], t["M"])  # the Cholesky whitening and the Jacobi SVD


def _controllers() -> None:
    from rhi.runtime.config import load_config, shipped_configs
    from rhi.runtime.safety import Safety
    from rhi.runtime.step import make_step
    from rhi.sim.loop import Kinematics

    for name in shipped_configs():
        cfg = load_config(name)
        ctrl = cfg.controller()
        ctrl.warmup()
        make_step(Safety(cfg.device, cfg.safety), Kinematics(cfg.device, cfg.virtual), ctrl)  # `rhi run`'s step


def _simulation() -> None:
    from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
    from rhi.control.sources import TickSources
    from rhi.devices.model import device
    from rhi.sim import Hand, HandPath, Plant, Wall, simulate, stop

    dev = device("rhi4")
    q0 = np.array([-0.63, 0.25, 0.28, 0.09])
    plant = Plant(dev)
    plant.reset(q0)
    x0 = dev.fk(q0)
    ctrl = NullSpaceController(dev, ControllerConfig(primary=ForceRendering(), saturation="ascm"))
    up = np.array([0.0, 1.0])
    simulate(plant, ctrl, duration=0.05, hand=Hand(HandPath(np.array([x0, x0 + 0.05 * up]), speed=0.02)),
             virtual=Wall(x0 + 0.01 * up, normal=up, stiffness=1000.0), physical=stop(x0 + 0.03 * up, up))
    TickSources(ctrl)(plant.q, plant.dq)  # the last tick's torque by source (beyond.passivity's energy books)


def _mobile() -> None:
    from rhi.control.mobile import AMDConfig, AMDController, DMConfig, WeightedConfig, WeightedDistributionController
    from rhi.devices.model import device
    from rhi.experiments.appa import Q0
    from rhi.sim.mobile import MobilePlant, hold, simulate_mobile

    dev = device("wmm")  # App. B's compiled loop (`rhi.sim._compiled.mobile_loop`), its controllers' tick
    simulate_mobile(AMDController(dev, AMDConfig(dt=0.01)), hold(dev.fk(Q0), duration=0.02, dt=0.01), Q0,
                    plant=MobilePlant(dev, visual=False))
    app_a = WeightedDistributionController(dev, WeightedConfig(dt=0.01, dm=DMConfig()))  # `velocity_loop`
    simulate_mobile(app_a, hold(dev.fk(Q0), duration=0.02, dt=0.01), Q0, plant=MobilePlant(dev, visual=False),
                    stage="dm_null")


def _bilateral() -> None:
    from rhi.experiments.beyond.bilateral import scenario

    scenario(0.01, True, duration=0.02)  # the compiled bilateral loop (`rhi.runtime._compiled.bilateral_loop`)


def _design() -> None:
    from rhi.design.planar import planar_indices

    rng = np.random.default_rng(0)
    planar_indices(rng.normal(size=(8, 2, 4)), rng.normal(size=(8, 2, 3)), np.ones(8, dtype=bool), np.ones(8))


STEPS: list[tuple[str, Callable[[], None]]] = [
    ("controllers (every shipped configuration)", _controllers),
    ("simulation loop", _simulation),
    ("mobile manipulator loop", _mobile),
    ("bilateral teleoperation loop", _bilateral),
    ("device terms (every bundled device)", _terms),
    ("batch terms and measures", _batch),
    ("design indices", _design),
]
"""What `warmup` runs, the heaviest first (cold: 41, 29, 15, 6, 8 and 1 % of the CPU of the other steps; the bilateral
loop's own kernels about 30 s of CPU, as much as the mobile loop's): each calls the kernels of its part once."""


def _step(k: int) -> float:
    """Run `STEPS` [k] in this process; returns its wall time [s]."""
    from rhi import jit

    jit.announced(True)  # the parent's bar says it; no "compiling ..." line besides
    jit.ASIDE[0] = False  # the steps are this pool's parallel work: no child compiles besides
    t0 = time.perf_counter()
    STEPS[k][1]()
    return time.perf_counter() - t0


def warmup(progress: bool = True, workers: int | None = None) -> list[tuple[str, float]]:
    """Run every `STEPS` entry on `workers` processes (None: the CPU count; 1: in this process).

    In `STEPS` order, one step per task (a free process takes the next); a rich progress bar when `progress`.
    Returns [(step, seconds)].
    """
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from rhi.design.executors import PoolExecutor, SerialExecutor

    if workers is None:
        workers = min(os.cpu_count() or 1, len(STEPS))
    ex = SerialExecutor() if workers == 1 else PoolExecutor(workers)
    out = []
    with ex, Progress(TextColumn("{task.description:<44}"), BarColumn(), TextColumn("{task.completed}/{task.total}"),
                      TimeElapsedColumn(), disable=not progress) as bar:
        task = bar.add_task(f"rhi warmup ({ex.workers} process{'es' if ex.workers > 1 else ''})", total=len(STEPS))
        for (name, _), s in zip(STEPS, ex.imap(_step, range(len(STEPS))), strict=True):
            out.append((name, s))
            bar.advance(task)
    return out


def _command(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    for name, s in warmup(progress=not args.quiet, workers=args.workers):
        print(f"{name:<44} {s:7.1f} s")
    print(f"{'kernels ready (cached for every later process)':<44} {time.perf_counter() - t0:7.1f} s")
    return 0


def add_commands(sub) -> None:
    """Add `warmup` to the `rhi` argument parser's subcommands."""
    w = sub.add_parser("warmup", help="compile (or load) every kernel now, with a progress bar",
                       description=__doc__, epilog=EXAMPLE, formatter_class=argparse.RawDescriptionHelpFormatter)
    w.add_argument("--quiet", action="store_true", help="no progress bar")
    w.add_argument("--workers", type=int, default=None, help="processes (default: the CPU count; 1: this one)")
    w.set_defaults(func=_command)
