"""Allocation within the torque box: ASCM (thesis Algorithm 1) vs the active set vs the LP (HiGHS).

For each device (rhi4, planar3r) and projector (dynamic J#, pseudoinverse J⁺), seeded random
non-singular configurations and force directions, a request a = Jᵀ(100 u) far beyond the
capability and a small unscaled torque b: the fraction of cases where each method reaches the
LP optimum (α within 1e-6 relative of `allocate_lp`; "in-tick" is the active set as the controller's
compiled tick runs it, from the projector P = Z Zᵀ, without the Python call around it), the worst gap [N along u, per 100 N
request], whether any torque left the box, and the median / p99 CPU time per call (thread_time,
so a shared machine's load counts less), with the ratio of each to the LP measured in the same run
(issue 13, item 6: >= 99.9 % at <= 50 µs median).

    PYTHONPATH=src python benchmarks/bench_allocation.py [--cases 10000]
"""

from __future__ import annotations

import argparse
import time
from types import SimpleNamespace

import numpy as np

from rhi.control._compiled import allocation, lp
from rhi.control.allocation import allocate_active_set, allocate_lp, ascm
from rhi.control.saturation import null_basis
from rhi.devices.model import device


def _cases(dev, rng, count):
    out = []
    while len(out) < count:
        q = rng.uniform(dev.q_min, dev.q_max)
        J = dev.jacobian(q)
        if np.linalg.svd(J, compute_uv=False)[-1] < 1e-3:
            continue
        u = rng.normal(size=dev.m)
        out.append((J, dev.mass_matrix(q), u / np.linalg.norm(u), rng.normal(size=dev.m)))
    return out


def _timed(fn, *args):
    """Result and this thread's CPU time [s] (thread_time: not the time the OS gave other processes)."""
    t0 = time.thread_time()
    res = fn(*args)
    return res, time.thread_time() - t0


def _in_tick(a, b, P, lo, hi, r):
    """The active-set allocation as the controller's compiled tick runs it (start, basis of P, iteration)."""
    sat = np.zeros(a.shape[0], bool)
    tau, alpha, clipped = lp.active_set_start(a, b, P, lo, hi, r, sat)
    if clipped:
        return allocate_active_set(a, b, allocation.basis(P, r), torque_min=lo, torque_max=hi)
    Z = allocation.basis(P, r)
    ok, alpha, y = lp.active_set(a, b, Z, lo, hi, alpha, tau, sat, 50)
    if not ok:
        return allocate_active_set(a, b, Z, torque_min=lo, torque_max=hi)
    tau, alpha = lp.active_set_result(alpha, y, a, b, Z, lo, hi, sat)
    return SimpleNamespace(tau=tau, alpha=alpha)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=10_000)
    ap.add_argument("--seed", type=int, default=13)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    print(f"{'device':9s} {'projector':13s} {'method':10s} {'reached':>9s} {'worst gap [N]':>14s} "
          f"{'outside box':>11s} {'median CPU µs':>13s} {'p99 CPU µs':>10s} {'median vs LP':>12s}")
    for name in ("rhi4", "planar3r"):
        dev = device(name)
        lo, hi = dev.torque_limits
        cases = _cases(dev, rng, args.cases)
        for proj in ("dynamic", "pseudoinverse"):
            stats = {m: {"alpha": [], "t": [], "out": 0} for m in ("ascm", "active_set", "lp", "in-tick")}
            inputs = []
            for J, M, u, w in cases:
                Z = null_basis(J, M if proj == "dynamic" else None)
                inputs.append((J.T @ (100.0 * u), J.T @ (0.05 * w), Z))
            methods = {
                "ascm": ascm,
                "active_set": allocate_active_set,  # includes its own ASCM start
                "lp": allocate_lp,
                "in-tick": lambda a, b, Z, lo, hi: _in_tick(a, b, Z @ Z.T, lo, hi, Z.shape[1]),
            }
            for m, fn in methods.items():  # one pass per method: warm caches, as in a control loop
                for a, b, Z in inputs:
                    al, t = _timed(fn, a, b, Z, lo, hi)
                    stats[m]["alpha"].append(al.alpha)
                    stats[m]["t"].append(t)
                    stats[m]["out"] += bool(np.any(al.tau > hi + 1e-12) or np.any(al.tau < lo - 1e-12))
            ref = np.array(stats["lp"]["alpha"])
            t_lp = np.median(stats["lp"]["t"])
            for m, st in stats.items():
                al = np.array(st["alpha"])
                reached = np.mean(al >= ref * (1 - 1e-6))
                gap = float(np.max(100.0 * (ref - al)))
                t = np.array(st["t"]) * 1e6
                print(f"{name:9s} {proj:13s} {m:10s} {reached:9.4%} {gap:14.3g} {st['out']:11d} "
                      f"{np.median(t):13.1f} {np.percentile(t, 99):10.1f} {np.median(t) / (t_lp * 1e6):11.3f}x")


if __name__ == "__main__":
    main()
