"""The energy books of `beyond.passivity` (the work of each torque source): compiled twin vs reference twin.

A §6.4 palpation of `beyond.passivity`'s case (default "objectives_tank_damper": objectives, the null-space
energy tank and a series damper) is simulated once; then `rhi.experiments.beyond.sources.source_work` replays
its log through the controller's own compiled tick split by `rhi.control.sources.TickSources`, and through a
reference twin (``implementation="reference"``, every tick in Python: the way the books were kept before).
Prints the time per replayed tick of each (CPU time of the process, best of `--repeat`), their ratio and the
largest difference of the books [J]. Baseline and candidate are measured in the same run.

    PYTHONPATH=src python benchmarks/bench_sources.py [seconds] [--case NAME] [--repeat K]
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Callable

import numpy as np

from rhi.control import WeightedSum
from rhi.devices.model import device
from rhi.experiments.beyond import passivity as P
from rhi.experiments.beyond.sources import source_work
from rhi.experiments.ch6 import setup as ch6
from rhi.sim import Hand, HandPath, Plant, Wall, simulate


def _log(dev, case: str, seconds: float):
    x0, u = np.array(ch6.X0), np.array(ch6.U)
    _, _, _, Ms = ch6.desired_fmes(dev, u, ch6.Q_HOME)
    q0 = ch6.best_match(dev, x0, WeightedSum(ch6.controller_terms(Ms, dev.torque_max)), starts=1)
    objectives, port, saturation, method, tank = P.CASES[case]
    ctrl = P.controller(dev, objectives=objectives, port=port, saturation=saturation, method=method, tank=tank)
    strokes = int(np.ceil(seconds * P.SPEED / (P.OUT + P.DEPTH))) + 1
    hand = Hand(HandPath(np.array([x0] + [x0 - P.OUT * u, x0 + P.DEPTH * u] * strokes), speed=P.SPEED, start=0.2),
                stiffness=P.HAND[0], damping=P.HAND[1], max_force=P.HAND[2])
    plant = Plant(dev)
    plant.reset(q0)
    return ctrl.config, simulate(plant, ctrl, duration=seconds, hand=hand, virtual=Wall(x0, u, P.K_E))


def _best(fn: Callable[[], tuple[dict[str, float], float]], repeat: int) -> tuple[float, tuple[dict[str, float], float]]:
    best = float("inf")
    out: tuple[dict[str, float], float] = ({}, 0.0)
    for _ in range(repeat):
        t = time.process_time()
        out = fn()
        best = min(best, time.process_time() - t)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seconds", nargs="?", type=float, default=3.0, help="simulated palpation [s]")
    ap.add_argument("--case", default="objectives_tank_damper", choices=P.SPLIT_CASES)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    dev = device("rhi4")
    config, log = _log(dev, args.case, args.seconds)
    ticks = len(log.t) - 1
    ref_cfg = dataclasses.replace(config, implementation="reference")
    t_fast, (fast, err) = _best(lambda: source_work(dev, config, log), args.repeat)
    t_ref, (ref, err_ref) = _best(lambda: source_work(dev, ref_cfg, log), args.repeat)
    diff = max(abs(fast[k] - ref[k]) for k in ref)
    print(f"{args.case}, {args.seconds:g} s palpation, {ticks} ticks replayed (CPU time, best of {args.repeat})")
    print(f"  reference twin (baseline): {1e6 * t_ref / ticks:8.1f} µs/tick   replay error {err_ref:.1e} N m")
    print(f"  compiled twin:             {1e6 * t_fast / ticks:8.1f} µs/tick   replay error {err:.1e} N m")
    print(f"  ratio reference / compiled: {t_ref / t_fast:.1f}×   largest difference of the books: {diff:.1e} J")


if __name__ == "__main__":
    main()
