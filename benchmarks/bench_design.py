"""Design-evaluation throughput (GM_T of phantom3–rehab_slave) and the Table 4.1 optimisation's wall time.

Run: PYTHONPATH=src python benchmarks/bench_design.py [--workers 2]
Prints evaluations per second on one process and on the local pool (their ratio, measured in
this run), for the closed-form HI model and for the generic Device-IK model, and the wall time
of the full D = {l2, θz, Z_PH} optimisation (C1 and C2) at the report's resolution.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import time

import numpy as np

from rhi.design import DeviceMaster, PoolExecutor, SerialExecutor, evaluate, optimize
from rhi.experiments import ch4


def rate(executor, prob, xs) -> float:
    fn = functools.partial(evaluate, prob)
    executor.map(fn, xs[:4])  # warm the workers
    t = time.perf_counter()
    executor.map(fn, xs)
    return len(xs) / (time.perf_counter() - t)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    prob = ch4.problem("full", density=100)
    lo = np.array([b[0] for b in prob.bounds.values()])
    hi = np.array([b[1] for b in prob.bounds.values()])
    xs = list(rng.uniform(lo, hi, size=(400, 3)))
    slow = dataclasses.replace(ch4.problem("full", density=25), master=DeviceMaster("phantom3"), r0=0.3)
    with PoolExecutor(args.workers) as pool:
        for name, p, x in (("closed-form phantom3, 400 samples", prob, xs), ("Device.ik phantom3, 25 samples",
                                                                             slow, xs[:24])):
            r1 = rate(SerialExecutor(), p, x)
            rp = rate(pool, p, x)
            print(f"GM_T evaluations/s, {name}: 1 process {r1:8.1f}, pool({args.workers}) {rp:8.1f}, "
                  f"ratio {rp / r1:.2f}")
        t = time.perf_counter()
        for which in ("C1", "C2"):
            o = optimize(prob, which, executor=pool, seed=0)
            print(f"  {which}: {o.params} GM_T {o.values['GM_T']:.4f} ({o.evaluations} designs)")
        print(f"Table 4.1 optimisation (C1 + C2, D = {{l2, θz, Z_PH}}, 400 samples) on {args.workers} workers: "
              f"{time.perf_counter() - t:.1f} s")


if __name__ == "__main__":
    main()
