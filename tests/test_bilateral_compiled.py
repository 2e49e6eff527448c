"""The bilateral teleoperation runs on the compiled loop (`rhi.runtime._compiled.bilateral`), equal to the Python loop.

The reference is `simulate_bilateral`'s Python loop (`Master`, `Slave`, the `DelayLine` channel, the TDPA's Python
`damp` and `correct`). The compiled loop's channel is the run's `schedule` (arrivals drawn up front), its TDPA the
kernels of `rhi.runtime._compiled.tdpa`; its logs equal the Python loop's to rounding, every array of the run.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rhi.experiments.beyond.bilateral import scenario
from rhi.runtime._compiled import bilateral as cb, bilateral_loop as bl, tdpa as ktdpa
from rhi.runtime.bilateral import Slave
from rhi.runtime.channel import ChannelConfig, local_pair, schedule
from rhi.runtime.tdpa import TDPA, PortEnergy, correct, damp


def python_loop(monkeypatch) -> None:
    """The reference: every run on the Python loop."""
    monkeypatch.setattr(cb.BilateralLoop, "why_not", staticmethod(lambda *a, **k: "switched off"))


def same_logs(a, b) -> None:
    """Every array of two `BilateralLog`s equal to 1e-9 of its scale (NaN where the other is NaN), the same fault."""
    assert a.fault == b.fault
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x.shape == y.shape, f.name
            np.testing.assert_array_equal(np.isnan(x), np.isnan(y), err_msg=f.name)
            scale = max(1.0, float(np.nanmax(np.abs(y)))) if y.size else 1.0
            np.testing.assert_allclose(np.nan_to_num(x), np.nan_to_num(y), rtol=0, atol=1e-9 * scale, err_msg=f.name)


@pytest.mark.parametrize("config", [ChannelConfig(), ChannelConfig(0.1, 0.01, 0.1, seed=3),
                                    ChannelConfig(0.05, 0.02, 0.0, seed=4), ChannelConfig(0.0, 0.0, 0.3, seed=5),
                                    ChannelConfig(0.0, 0.003, 0.2, seed=6), ChannelConfig(0.0021, 0.0, 0.0, seed=7)])
def test_the_schedule_is_the_delay_lines(config):
    """`schedule` sees at every tick the packet `LocalEnd` keeps, both directions (the master ticks first)."""
    N, dt = 2000, 1e-3
    back = dataclasses.replace(config, seed=config.seed + 10)
    me, se = local_pair(config, back, dt)
    seen_f, seen_b = schedule(config, dt, N), schedule(back, dt, N, lag=1)
    got_f, got_b = [], []
    for k in range(N):
        me.tick()
        p = me.latest()
        got_b.append(-1 if p is None else int(p[0]))
        me.send(np.array([k]))
        se.tick()
        p = se.latest()
        got_f.append(-1 if p is None else int(p[0]))
        se.send(np.array([k]))
    assert got_f == seen_f.tolist() and got_b == seen_b.tolist()


def test_the_tdpa_kernels_are_the_python_functions():
    """`damp` and `correct` compiled equal the Python ones on every branch (random ports, forces, velocities)."""
    rng = np.random.default_rng(0)
    cfg = TDPA(max_force=2.0, max_damping=50.0, drift_rate=2.0, max_drift_speed=0.02, max_correction_speed=0.5)
    c = ktdpa.settings(cfg)
    branches = set()
    for i in range(400):
        small = i % 5 == 0
        F, v, drift = rng.normal(size=2), rng.normal(size=2) * (1e-7 if small else 0.1), rng.normal(size=2) * 1e-3
        if i % 7 == 0:
            drift[:] = 0.0
        E_out, E_other = rng.uniform(0, 1e-3, size=2)
        port = PortEnergy(E_in=1e-4, E_out=E_out, dissipated=1e-5)
        p = np.array([port.E_in, port.E_out, port.dissipated, 0.0, 0.0])
        mass = rng.uniform(0.05, 1.0)
        want = damp(port, F, v, mass, E_other, 1e-3, cfg)
        Fk = F.copy()
        ktdpa.damp(p, Fk, v, mass, E_other, 1e-3, c)
        np.testing.assert_allclose(Fk, want, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(p, [port.E_in, port.E_out, port.dissipated, port.gain, port.deficit], rtol=1e-12,
                                   atol=1e-18)
        port = PortEnergy(E_in=1e-4, E_out=E_out)
        p = np.array([port.E_in, port.E_out, 0.0, 0.0, 0.0])
        F_e = F * (1e-7 if i % 11 == 0 else 1.0)
        want = correct(port, v, F_e, E_other, drift, 1e-3, cfg)
        vk = v.copy()
        ktdpa.correct(p, vk, F_e, E_other, drift, 1e-3, c)
        np.testing.assert_allclose(vk, want, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(p, [port.E_in, port.E_out, port.dissipated, port.gain, port.deficit], rtol=1e-12,
                                   atol=1e-18)
        branches.add((port.gain > 0, port.deficit > 0, bool(np.any(want != v))))
    assert len(branches) >= 4, branches  # corrected, bounded, idle with a deficit, drift compensation


@pytest.mark.parametrize("delay, tdpa, duration", [(0.1, True, 3.0), (0.0, True, 2.0), (0.05, True, 1.0), (0.05, False, 1.5)])
def test_the_compiled_run_equals_the_python_loop(delay, tdpa, duration, monkeypatch):
    """The experiment's run (hand into the tissue and along it; jitter and loss where delayed) on both loops.

    With the TDPA at 0 and 50 ms its decisions meet ties (W ≥ 0 to rounding): equal only with the same
    arithmetic on both loops (`rhi.runtime.tdpa.dot`, not BLAS's fused products).
    """
    kw = {"jitter": 0.01, "loss": 0.1} if delay else {}
    fast = scenario(delay, tdpa, duration=duration, **kw)
    assert fast.route == cb.BilateralLoop.route
    python_loop(monkeypatch)
    ref = scenario(delay, tdpa, duration=duration, **kw)
    assert ref.route == "python loop (switched off)"
    same_logs(fast, ref)
    assert np.count_nonzero(~np.isnan(fast.tmi)) == len(fast.t) // 20


def short_calls(seed: int, handed: list):
    """A stand-in for `bl.ticks` whose calls end after a random 0–299 ticks and hand the next tick to Python."""
    kernel = bl.ticks
    rng = np.random.default_rng(seed)

    def short(count, k0, *args):
        lay = args[10]  # ticks(count, k0, dt, mst, slv, chan, cfg, wargs, cs, whole, st, vec, lay, rows)
        kernel(min(count, int(rng.integers(0, 300))), k0, *args)
        if lay[bl.L_OUT] == bl.DONE and lay[bl.L_DONE] < count:
            lay[bl.L_OUT] = bl.PYTHON
            handed.append(k0 + int(lay[bl.L_DONE]))

    return short


def test_ticks_handed_to_python_resume(monkeypatch):
    """Compiled calls that end early hand ticks to the Python loop, which continues on the same state, and back."""
    handed: list[int] = []
    monkeypatch.setattr(bl, "ticks", short_calls(1, handed))
    fast = scenario(0.1, True, duration=2.0, jitter=0.01, loss=0.1)
    assert fast.route == cb.BilateralLoop.route and len(handed) > 5
    monkeypatch.undo()
    python_loop(monkeypatch)
    same_logs(fast, scenario(0.1, True, duration=2.0, jitter=0.01, loss=0.1))


class _Quiet(Slave):
    """A slave subclass (its step could be anything): the compiled loop does not know it."""


def test_a_run_the_kernels_do_not_know_stays_on_the_python_loop():
    """A subclass of the slave runs on the Python loop, and its route says why."""
    log = scenario(0.0, True, duration=0.05, slave=_Quiet)
    assert log.route == "python loop (the master or the slave is a subclass)"


def test_a_plant_fault_ends_both_loops_at_the_same_tick(monkeypatch):
    """A tissue too stiff for the slave's physics step: the same fault, at the same tick, the logs cut there."""
    fast = scenario(0.0, True, stiffness=1e12, duration=1.0)
    assert fast.route == cb.BilateralLoop.route and fast.fault is not None and "unstable" in fast.fault
    python_loop(monkeypatch)
    ref = scenario(0.0, True, stiffness=1e12, duration=1.0)
    assert len(fast.t) == len(ref.t) < 1000
    same_logs(fast, ref)
