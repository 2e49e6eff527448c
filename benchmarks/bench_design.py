"""Design-evaluation throughput, the Table 4.1 optimisation's wall time, and the workspace maps.

The throughput is of GM_T of phantom3–rehab_slave; the maps run on the same executor layer.

Run: PYTHONPATH=src python benchmarks/bench_design.py [--workers 2] [--maps]
Prints, all measured in this run (ratios, not absolute pass/fail numbers):

* evaluations per second on one process and on the local pool, and their ratio, for the closed-form HI
  model and for the generic Device-IK model;
* the wall time of the full D = {l2, θz, Z_PH} optimisation (C1 and C2, Table 4.1) at the report's
  resolution, on the pool and on one process (target: ≤ 60 s on 2 cores);
* with --maps, the Fig. 3.7–3.8 and Fig. 7.5 maps at reduced resolution, serial vs pool (same numbers).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import os
import time

import numpy as np

from rhi.design import DeviceMaster, PoolExecutor, SerialExecutor, evaluate, optimize
from rhi.experiments import ch4


def rate(executor, prob, xs) -> float:
    fn = functools.partial(evaluate, prob)
    executor.map(fn, xs[: 2 * executor.workers])  # start and warm every worker
    t = time.perf_counter()
    executor.map(fn, xs)
    return len(xs) / (time.perf_counter() - t)


def table_4_1(executor) -> float:
    prob = ch4.setup.problem("full", density=100)
    t = time.perf_counter()
    for which in ("C1", "C2"):
        o = optimize(prob, which, executor=executor, seed=0)
        p = {k: round(v, 4) for k, v in o.params.items()}
        print(f"    {which}: {p} GM_T {o.values['GM_T']:.4f} GM_M {o.values['GM_M']:.4f} "
              f"GC_M {o.values['GC_M']:.4f} ({o.evaluations} evaluations)")
    return time.perf_counter() - t


def maps(workers: int) -> None:
    from rhi.experiments import ch3, ch7

    for name, run, res in (("Fig. 7.5 deficiency map", ch7.deficiency_map, 9), ("Figs 3.7–3.8 ratio maps",
                                                                                ch3.ratio_maps, 9)):
        out = {}
        for w in (1, workers):
            t = time.perf_counter()
            r = run(resolution=res, workers=w)
            out[w] = (time.perf_counter() - t, r)
        key = "pd" if "pd" in out[1][1].arrays else "rho_ratio"
        same = np.array_equal(out[1][1].arrays[key], out[workers][1].arrays[key], equal_nan=True)
        print(f"{name}, {res}×{res}: 1 process {out[1][0]:.1f} s, pool({workers}) {out[workers][0]:.1f} s "
              f"(incl. pool start), ratio {out[1][0] / out[workers][0]:.2f}, identical: {same}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--maps", action="store_true", help="also time the ch3/ch7 workspace maps")
    args = ap.parse_args()
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f} at start")
    rng = np.random.default_rng(0)
    prob = ch4.setup.problem("full", density=100)
    lo = np.array([b[0] for b in prob.bounds.values()])
    hi = np.array([b[1] for b in prob.bounds.values()])
    xs = list(rng.uniform(lo, hi, size=(800, 3)))
    slow = dataclasses.replace(ch4.setup.problem("full", density=25), master=DeviceMaster("phantom3"), r0=0.3)
    with PoolExecutor(args.workers) as pool:
        for name, p, x in (("closed-form phantom3, 400 samples", prob, xs),
                           ("Device.ik phantom3, 25 samples", slow, xs[:32])):
            r1 = rate(SerialExecutor(), p, x)
            rp = rate(pool, p, x)
            print(f"GM_T evaluations/s, {name}: 1 process {r1:8.1f}, pool({args.workers}) {rp:8.1f}, "
                  f"ratio {rp / r1:.2f}")
        print(f"Table 4.1 optimisation (C1 + C2, D = {{l2, θz, Z_PH}}, 400 samples), pool({args.workers}):")
        tp = table_4_1(pool)
    print("  one process:")
    ts = table_4_1(SerialExecutor())
    print(f"Table 4.1 wall time: pool({args.workers}) {tp:.1f} s, one process {ts:.1f} s, ratio {ts / tp:.2f} "
          f"(target ≤ 60 s)")
    if args.maps:
        maps(args.workers)
    print(f"load average {os.getloadavg()[0]:.2f} at end")


if __name__ == "__main__":
    main()
