"""One full rhi4 controller tick: primary law + FME matching (ASO, transition) + ASCM + tertiary objective.

Also the same stack with the LP optimum, its reference solved by the active set (`LPOptimum(solver="active_set")`,
the compiled tick's method) and by HiGHS (`saturation="lp"`), and on gen3 as a spatial RHI (7 joints, 3 task rows).

The controller is the thesis's rhi4 setup: force rendering with B^d = 0.01 N s/m and the
C_x ẋ + G_x compensation of eq. 7.2, ASO-switched FME matching (μ = 5, β = 20, eqs.
6.10–6.19), ASCM (Algorithm 1) and the VME-matching tertiary objective (eq. 7.18, β = 0.01).
The ticks follow a seeded path near q = [0.3, 0.5, 0.2, 0.4] rad with a force ramp that
drives the joints into saturation and back.

Baseline, measured in the same run and interleaved tick by tick with the fast path (so both
see the same machine load): ``implementation="reference"``, the per-call composition of the
equations (per-call Device methods, SVD null-space basis, `ascm`/`tertiary` on the basis,
`rhi.metrics` projectors). The fast path must give the same torques (checked to 1e-10 N m).

Prints median and p99 per tick, wall clock (perf_counter) and this thread's CPU time
(thread_time, which excludes time the OS gave to other processes on a shared machine), the
speed-up over the reference and the ratio to the 100 µs target (a 1 kHz haptic loop should
leave most of its millisecond free). Also times `Device.terms` against the per-call Device
methods it replaces, and the LP allocation.

    PYTHONPATH=src python benchmarks/bench_control.py [--ticks 5000]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import rhi
from rhi.control import (
    AllocationMethod,
    ControllerConfig,
    FMESchedule,
    ForceRendering,
    NullSpaceController,
    ObjectiveTerm,
    VMEMatching,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.control.allocation import LPOptimum

TARGET_US = 100.0
Q0 = np.array([0.3, 0.5, 0.2, 0.4])


def make(dev: rhi.Device, saturation: str | AllocationMethod = "ascm", implementation: str = "fast") -> NullSpaceController:
    u = np.zeros(dev.m)
    u[1] = 1.0
    K, z = fme_shape(dev.jacobian(np.full(dev.n, 0.3) if dev.m == 3 else np.zeros(dev.n)), dev.torque_max, 5.0)
    cfg = ControllerConfig(
        ForceRendering(damping=0.01, passivity=None),  # the thesis's law (the passivity layer integrates energy,
        # which carries rounding differences between the two paths beyond 1e-10 N m over hundreds of ticks)
        objectives=(ObjectiveTerm(VMEMatching(tuple(u), 0.01), 0.5),
                    ObjectiveTerm(FMESchedule(desired_fme_free(u, K, z), desired_fme_stiff(u, K, z)), 20.0)),
        damping=0.1,
        saturation=saturation,
        implementation=implementation,
    )
    return NullSpaceController(dev, cfg)


def ticks(count: int, seed: int = 0, dev: rhi.Device | None = None,
          ) -> list[tuple[float, np.ndarray, np.ndarray, dict[str, np.ndarray]]]:
    """Seeded ticks for rhi4 (default) or, with `dev`, a spatial device (m = 3) near q = 0.3 rad."""
    rng = np.random.default_rng(seed)
    n, m = (4, 2) if dev is None else (dev.n, dev.m)
    q0 = Q0 if dev is None else np.full(n, 0.3)
    peak = 12.0 if dev is None else 400.0  # gen3's torque limits are 13-32 N m
    out = []
    for k in range(count):
        q = q0 + 0.05 * np.sin(0.01 * k + np.arange(n))
        dq = 0.1 * rng.normal(size=n)
        F = np.zeros(m)
        F[1] = -peak * np.sin(0.005 * k) ** 2  # drives joints into saturation and back
        out.append((k * 1e-3, q, dq, {"force": F}))
    return out


def _run(c: NullSpaceController, path) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Wall and CPU µs per tick, the torques, and how many ticks hold a joint at a limit."""
    wall, cpu, taus = np.empty(len(path)), np.empty(len(path)), np.empty((len(path), c.device.n))
    held = 0
    for k, args in enumerate(path):
        w0, c0 = time.perf_counter(), time.thread_time()
        taus[k] = c.step(*args)
        c1, w1 = time.thread_time(), time.perf_counter()
        wall[k], cpu[k] = (w1 - w0) * 1e6, (c1 - c0) * 1e6
        held += bool(c.state.saturated.any())
    return wall, cpu, taus, held


def bench_ticks(saturation: str | AllocationMethod, count: int, rounds: int = 2, name: str = "rhi4") -> dict[str, np.ndarray]:
    """Fast and reference passes over the same ticks, alternated `rounds` times (both see the same machine load).

    Returns wall and CPU µs per tick (first 10% of each pass dropped as warm-up).
    """
    dev = rhi.device(name)
    path = ticks(count, dev=None if name == "rhi4" else dev)
    skip = count // 10
    res: dict[str, list[np.ndarray]] = {k: [] for k in ("fast_wall", "fast_cpu", "ref_wall", "ref_cpu")}
    worst, held = 0.0, 0
    for _ in range(rounds):
        out = {}
        for name, impl in (("fast", "fast"), ("ref", "reference")):
            wall, cpu, taus, h = _run(make(dev, saturation, impl), path)
            res[f"{name}_wall"].append(wall[skip:])
            res[f"{name}_cpu"].append(cpu[skip:])
            out[name] = taus
            held = h
        worst = max(worst, float(np.abs(out["fast"] - out["ref"]).max()))
    if worst > 1e-10:
        raise AssertionError(f"fast and reference ticks differ by {worst:.3g} N m")
    joined = {k: np.concatenate(v) for k, v in res.items()}
    joined["worst"], joined["held"] = worst, held / count
    return joined


def bench_terms(count: int) -> tuple[float, float]:
    """Median CPU µs of Device.terms(q, dq) vs the per-call fk/jacobian/jacobian_derivative/mass_matrix/gravity."""
    dev = rhi.device("rhi4")
    qs = [a[1] for a in ticks(count)]
    one, calls = np.empty(count), np.empty(count)
    for k, q in enumerate(qs):
        c0 = time.thread_time()
        dev.terms(q, q, check=False)
        c1 = time.thread_time()
        dev.fk(q), dev.jacobian(q), dev.jacobian_derivative(q), dev.mass_matrix(q), dev.gravity(q)
        c2 = time.thread_time()
        one[k], calls[k] = (c1 - c0) * 1e6, (c2 - c1) * 1e6
    return float(np.median(one)), float(np.median(calls))


def _row(label: str, us: np.ndarray) -> str:
    med, p99 = np.median(us), np.percentile(us, 99)
    return f"  {label:22s} median {med:8.1f} µs   p99 {p99:8.1f} µs   median / {TARGET_US:.0f} µs target = {med / TARGET_US:5.2f}"


def main(count: int = 5000) -> None:
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"rhi4 controller tick, {count} ticks (first 10% dropped); load average {load:.1f} on {os.cpu_count()} CPUs")
    cases: tuple[tuple[str, str | AllocationMethod, int], ...] = (
        ("rhi4", "ascm", count), ("rhi4", LPOptimum(solver="active_set"), count), ("rhi4", "lp", max(count // 10, 200)),
        ("gen3", "ascm", max(count // 2, 200)))
    for name, sat, n in cases:
        r = bench_ticks(sat, n, name=name)
        print(f"{name} (m = {rhi.device(name).m}), saturation={sat!r}: {100 * r['held']:.0f}% of ticks hold a joint "
              "at its limit; "
              f"fast == reference to {r['worst']:.1e} N m")
        for clock in ("wall", "cpu"):
            print(_row(f"reference ({clock})", r[f"ref_{clock}"]))
            print(_row(f"fast ({clock})", r[f"fast_{clock}"]))
            print(f"  speed-up ({clock}): median {np.median(r[f'ref_{clock}']) / np.median(r[f'fast_{clock}']):.1f}x, "
                  f"p99 {np.percentile(r[f'ref_{clock}'], 99) / np.percentile(r[f'fast_{clock}'], 99):.1f}x")
    one, calls = bench_terms(min(count, 2000))
    print(f"Device.terms(q, dq): median {one:.1f} µs CPU vs per-call fk+jacobian+jacobian_derivative+"
          f"mass_matrix+gravity {calls:.1f} µs: {calls / one:.1f}x")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=5000)
    main(parser.parse_args().ticks)
