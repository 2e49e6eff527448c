"""10 s of simulated palpation at 1 kHz on the MuJoCo rhi4 plant: how much faster than real time?

The hand pushes into a rendered 1000 N/m wall (§6.4 set-up) while the full controller runs
(force rendering + FME matching with ASO/transition + ASCM + tertiary). Baselines measured in
the same run: bare MuJoCo stepping of the same plant at rest, MuJoCo alone through the loop's
motion (the hand force of every physics step replayed: the floor of any loop; a moving plant
costs MuJoCo more than one at rest), the same loop with a zero-torque controller (plant + hand +
environment + log: the loop's own cost; its hand, wall, handle kinematics, sensor reads and log
rows run in compiled calls, `rhi.sim._compiled.handle` and `rhi.sim._compiled.io`, between MuJoCo's steps
and the controller), and that zero-controller loop as the previous
implementation ran it (the package at git revision PREVIOUS, extracted with `git archive`
and run in a subprocess; skipped outside a git checkout). The full loop runs in blocks of compiled
ticks (`rhi.sim._compiled.fast_loop`: sensors, virtual wall, the controller's whole tick, hand, MuJoCo's steps and
log rows in one call per block); the zero controller is not one it computes, so its rows are the
Python loop's. Targets: the full loop ≥ 25× faster than real time (issue 14) and ≥ 0.5× as fast as bare
MuJoCo stepping of the same plant for the same number of physics steps (issue 29; printed as that ratio).

Times are wall clock and CPU time of the process (the CPU time is steadier on a shared machine);
each loop is timed `--repeat` times, best kept, after a short untimed run of each controller (Numba
kernels are loaded from their on-disk cache, or compiled, on first use: a one-off cost of seconds that
is not the loop's).

    PYTHONPATH=src python benchmarks/bench_sim.py [seconds] [--previous REV] [--repeat K]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

import mujoco
import numpy as np
from revision import source_at

import rhi
from rhi.sim import Hand, Plant, Wall, simulate

try:
    from rhi.sim import HandPath
except ImportError:  # the previous implementation (--previous) predates the name HandPath
    from rhi.sim import Path as HandPath  # type: ignore[attr-defined,no-redef]

Q0 = np.array([-0.63, 0.25, 0.28, 0.09])
TARGET = 25.0
#: the full loop's speed as a fraction of bare MuJoCo stepping's (issue 29)
BARE_TARGET = 0.5
#: main before the loop's speed work of issue 14
PREVIOUS = "2e43554"


class Zero:
    def step(self, t, q, dq, sensors):
        return np.zeros(4)


class Recorder:
    """A hand that records the force of every physics step."""

    def __init__(self, hand) -> None:
        self.hand, self.forces = hand, []

    def force(self, t, x, xdot):
        F = self.hand.force(t, x, xdot)
        self.forces.append(F)
        return F


def run(controller, seconds: float, record: bool = False):
    """(wall [s], CPU [s], fault) of the palpation scenario (record: the hand's force of every step, untimed)."""
    dev = rhi.device("rhi4")
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    hand = Hand(HandPath([x0, x0 + [0.0, 0.03]], speed=0.01), stiffness=300.0)
    if record:
        hand = Recorder(hand)
    w0, c0 = time.perf_counter(), time.process_time()
    log = simulate(plant, controller, duration=seconds, hand=hand, virtual=Wall(x0 + [0.0, 0.005], [0, 1], 1000.0))
    return time.perf_counter() - w0, time.process_time() - c0, (hand.forces if record else log.fault)


def best(fn, repeat: int) -> tuple[float, float]:
    """Smallest wall and CPU time of `repeat` calls of fn() -> (wall, cpu, ...)."""
    runs = [fn()[:2] for _ in range(repeat)]
    return min(r[0] for r in runs), min(r[1] for r in runs)


def full_controller():
    from rhi.control import (
        ControllerConfig,
        FMESchedule,
        ForceRendering,
        NullSpaceController,
        ObjectiveTerm,
        desired_fme_free,
        desired_fme_stiff,
        fme_shape,
    )

    dev = rhi.device("rhi4")
    K, z = fme_shape(dev.jacobian(np.zeros(4)), dev.torque_max, 5.0)
    cfg = ControllerConfig(ForceRendering(damping=0.01),
                           objectives=(ObjectiveTerm(FMESchedule(desired_fme_free([0, 1], K, z),
                                                                 desired_fme_stiff([0, 1], K, z)), 20.0),),
                           saturation="ascm")
    return NullSpaceController(dev, cfg)


def bare(seconds: float) -> tuple[float, float]:
    """MuJoCo stepping the plant at rest, no force."""
    plant = Plant(rhi.device("rhi4"))
    plant.reset(Q0)
    m, d = plant.model, plant.data
    steps = int(round(seconds / plant.timestep))
    w0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        mujoco.mj_step(m, d)
    return time.perf_counter() - w0, time.process_time() - c0


def replay(forces: list[np.ndarray]) -> tuple[float, float]:
    """MuJoCo alone through the loop's motion: the hand force of every physics step replayed, zero torque."""
    plant = Plant(rhi.device("rhi4"))
    plant.reset(Q0)
    m, d = plant.model, plant.data
    xfrc = d.xfrc_applied[m.body("handle").id]
    rows = np.array(plant.device.task_rows)
    w0, c0 = time.perf_counter(), time.process_time()
    for F in forces:
        xfrc[rows] = F
        mujoco.mj_step2(m, d)
        mujoco.mj_step1(m, d)
    return time.perf_counter() - w0, time.process_time() - c0


def previous(rev: str, seconds: float, repeat: int) -> tuple[float, float] | str:
    """Best (wall, CPU) of the zero-controller loop in the package at `rev`, or why it could not run."""
    try:
        with source_at(rev) as src:
            env = {**os.environ, "PYTHONPATH": str(src)}
            out = subprocess.run([sys.executable, __file__, str(seconds), "--zero-only", "--repeat", str(repeat)],
                                 capture_output=True, text=True, env=env, cwd=src.parent)
    except LookupError as exc:
        return f"skipped ({exc})"
    if out.returncode != 0:
        return f"failed: {out.stderr.strip().splitlines()[-1] if out.stderr.strip() else out.returncode}"
    wall, cpu = map(float, out.stdout.split())
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seconds", nargs="?", type=float, default=10.0)
    ap.add_argument("--previous", default=PREVIOUS, help="git revision of the previous implementation")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--zero-only", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    s, r = a.seconds, a.repeat
    if a.zero_only:  # the previous implementation's run (a subprocess of the benchmark)
        run(Zero(), 0.05)
        print(*best(lambda: run(Zero(), s), r))
        return
    load = os.getloadavg()[0]
    for ctrl in (Zero(), full_controller()):  # compiled kernels loaded (or compiled) before any timing
        run(ctrl, 0.05)
    forces = run(Zero(), s, record=True)[2]
    rows = [("bare MuJoCo stepping, at rest", best(lambda: bare(s), r)),
            ("MuJoCo alone, the loop's motion", best(lambda: replay(forces), r))]
    prev = previous(a.previous, s, r)
    if isinstance(prev, tuple):
        rows.append((f"loop + zero controller @{a.previous}", prev))
    rows.append(("loop + zero controller", best(lambda: run(Zero(), s), r)))
    fulls = [run(full_controller(), s) for _ in range(r)]
    from rhi.sim._compiled import fast_loop

    compiled = "none" if fast_loop.last is None else f"{fast_loop.last.ticks} in {fast_loop.last.calls} calls"
    full = min(f[0] for f in fulls), min(f[1] for f in fulls)
    rows.append(("loop + full controller", full))
    ticks = round(s * 1000)
    print(f"{s:g} s simulated at 1 kHz (plant step 0.5 ms), rhi4 palpation; load average "
          f"{load:.2f} -> {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; best of {r}")
    print(f"  {'':36s} {'wall [s]':>9s} {'x real':>7s} {'CPU [s]':>9s} {'x real':>7s}  CPU/tick beyond MuJoCo")
    b_cpu = rows[1][1][1]
    for name, (wall, cpu) in rows:
        extra = "" if name.startswith(("bare", "MuJoCo")) else f"{(cpu - b_cpu) / ticks * 1e6:16.1f} µs"
        print(f"  {name:36s} {wall:9.3f} {s / wall:7.1f} {cpu:9.3f} {s / cpu:7.1f}  {extra}")
    zero = rows[-2][1]
    if isinstance(prev, tuple):
        print(f"  zero-controller loop vs @{a.previous}: {prev[0] / zero[0]:.2f}x faster (wall), "
              f"{prev[1] / zero[1]:.2f}x (CPU); loop overhead beyond MuJoCo "
              f"{(prev[1] - b_cpu) / (zero[1] - b_cpu):.2f}x smaller")
    else:
        print(f"  previous implementation: {prev}")
    print(f"  full loop: {s / full[0]:.1f}x real time (target >= {TARGET:g}x: "
          f"{'met' if s / full[0] >= TARGET else 'NOT met'}); controller share {(full[1] - zero[1]) / full[1]:.0%} "
          f"of its CPU; fault: {fulls[-1][2]}; compiled ticks: {compiled}")
    bare_wall, bare_cpu = rows[0][1]
    print(f"  full loop vs bare MuJoCo stepping (the same plant, the same {round(s / Plant(rhi.device('rhi4')).timestep)} "
          f"physics steps): {bare_wall / full[0]:.2f}x (wall), {bare_cpu / full[1]:.2f}x (CPU) "
          f"(target >= {BARE_TARGET:g}x: {'met' if bare_wall / full[0] >= BARE_TARGET else 'NOT met'})")


if __name__ == "__main__":
    main()
