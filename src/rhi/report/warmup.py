"""Compile (or load) rhi's Numba kernels once, before `rhi reproduce`'s workers run experiments.

The kernels are cached on disk (``cache=True``), but a process that needs a kernel before the
cache holds it compiles it itself: on a fresh install every reproduction worker, and every
design-pool worker under it, compiled the same controller tick (half a minute of CPU or more each). The
warm-up runs each kernel family once on a small input of the kind the experiments give it, in
two groups that share no kernel, one per worker, before any experiment starts; on a warm cache
it only loads them (a second or two per group), as the workers would anyway.

A kernel an experiment reaches with other argument types than these still compiles in the
worker that first needs it: the warm-up only saves time, the results never depend on it.
"""

from __future__ import annotations

import time

import numpy as np


def _middle(dev) -> np.ndarray:
    """The middle of the joint range (±1 rad where a joint is unlimited): (n,) [rad]."""
    return 0.5 * (np.where(np.isfinite(dev.q_min), dev.q_min, -1.0) + np.where(np.isfinite(dev.q_max), dev.q_max, 1.0))


def _terms_control_and_loop() -> None:
    """`Device.terms`, the whole controller tick, then the compiled simulation loop around it.

    The kernels: rhi.devices._compiled.chain, rhi.control._compiled.whole, rhi.sim._compiled.fast_loop.
    The whole tick's compilation also caches the steps 2–6 tick it calls, which a controller with an
    objective computed in Python runs after `Device.terms` (the same argument types: loaded, not compiled).
    The loop's comes last: by then the other group has cached the simulation kernels it calls.
    """
    from rhi.control import (
        ControllerConfig,
        ForceRendering,
        JointLimitBarrier,
        NullSpaceController,
        ObjectiveTerm,
        VMEMatching,
    )
    from rhi.devices.model import device

    dev = device("rhi4")
    q0 = _middle(dev)
    dev.terms(q0, np.full(dev.n, 0.1))
    terms = (ObjectiveTerm(VMEMatching((1.0, 0.0)), 1.0), ObjectiveTerm(JointLimitBarrier(0.1, 0.01, kind="inverse"), 1.0))
    cfg = ControllerConfig(primary=ForceRendering(damping=0.0, passivity=None), objectives=terms, damping=1.0,
                           saturation="none")
    ctrl = NullSpaceController(dev, cfg)
    ctrl.warmup()
    _simulate(dev, q0, ctrl)


def _simulate(dev, q0: np.ndarray, controller) -> None:
    """Three ticks of `controller` with a hand holding the handle at q0 (the simulation's kernels)."""
    from rhi.sim import Hand, HandPath, Plant, simulate

    plant = Plant(dev)
    plant.reset(q0)
    hand = Hand(HandPath(dev.fk(q0)[None]), stiffness=3000.0, damping=40.0, max_force=None)
    simulate(plant, controller, duration=0.003, hand=hand)


def _batch_design_and_simulation() -> None:
    """The batch kernel (rhi.devices._compiled.batch), the planar design indices and the simulation's kernels."""
    from rhi.control import ZeroTorque
    from rhi.design.planar import planar_indices
    from rhi.devices.model import BATCH_MIN, device

    for name in ("rhi4", "gen3"):  # a planar RHI and a spatial one (3 task rows)
        dev = device(name)
        dev.jacobian(np.repeat(_middle(dev)[None], BATCH_MIN, axis=0))
    rng = np.random.default_rng(0)
    planar_indices(rng.normal(size=(4, 2, 3)), rng.normal(size=(4, 2, 3)), np.ones(4, dtype=bool), np.ones(4))
    dev = device("rhi4")
    _simulate(dev, _middle(dev), ZeroTorque(dev.n))  # the motors-off loop and the kernels the Python loop shares


#: The warm-up's groups, each run by one process; no kernel is in two groups (no compile twice at once).
GROUPS = {"terms_control_and_loop": _terms_control_and_loop,
          "batch_design_and_simulation": _batch_design_and_simulation}


def warm(group: str) -> float:
    """Compile or load the kernels of one of `GROUPS` in this process; returns its wall time [s]."""
    t = time.perf_counter()
    GROUPS[group]()
    return time.perf_counter() - t


__all__ = ["GROUPS", "warm"]
