"""10 s of simulated palpation at 1 kHz on the MuJoCo rhi4 plant: how much faster than real time?

The hand pushes into a rendered 1000 N/m wall (§6.4 set-up) while the full controller runs
(force rendering + FME matching with ASO/transition + ASCM + tertiary). Baselines measured in
the same run: the same loop with a zero-torque controller (plant + hand + loop cost alone) and
bare MuJoCo stepping. Target: simulated/wall ≥ 5.

    PYTHONPATH=src python benchmarks/bench_sim.py [seconds]
"""

from __future__ import annotations

import sys
import time

import mujoco
import numpy as np

import rhi
from rhi.control import (
    ControllerConfig,
    FMESchedule,
    ForceRendering,
    NullSpaceController,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
)
from rhi.sim import Hand, Path, Plant, Wall, simulate

Q0 = np.array([-0.63, 0.25, 0.28, 0.09])
TARGET = 5.0


class Zero:
    def step(self, t, q, dq, sensors):
        return np.zeros(4)


def run(controller, seconds: float) -> tuple[float, str | None]:
    dev = rhi.device("rhi4")
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    hand = Hand(Path([x0, x0 + [0.0, 0.03]], speed=0.01), stiffness=300.0)
    t0 = time.perf_counter()
    log = simulate(plant, controller, duration=seconds, hand=hand, virtual=Wall(x0 + [0.0, 0.005], [0, 1], 1000.0))
    return time.perf_counter() - t0, log.fault


def full_controller() -> NullSpaceController:
    dev = rhi.device("rhi4")
    K, z = fme_shape(dev.jacobian(np.zeros(4)), dev.torque_max, 5.0)
    cfg = ControllerConfig(ForceRendering(damping=0.01),
                           fme=FMESchedule(desired_fme_free([0, 1], K, z), desired_fme_stiff([0, 1], K, z)),
                           saturation="ascm")
    return NullSpaceController(dev, cfg)


def main(seconds: float = 10.0) -> None:
    plant = Plant(rhi.device("rhi4"))
    plant.reset(Q0)
    steps = int(seconds / plant.timestep)
    t0 = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(plant.model, plant.data)
    bare = time.perf_counter() - t0
    zero, _ = run(Zero(), seconds)
    full, fault = run(full_controller(), seconds)
    print(f"{seconds:g} s simulated at 1 kHz (plant step {plant.timestep * 1e3:g} ms), rhi4 palpation")
    print(f"  bare MuJoCo stepping        {bare:7.2f} s wall   {seconds / bare:8.1f}x real time")
    print(f"  loop + zero controller      {zero:7.2f} s wall   {seconds / zero:8.1f}x real time")
    print(f"  loop + full controller      {full:7.2f} s wall   {seconds / full:8.1f}x real time "
          f"(target >= {TARGET:g}x: {'met' if seconds / full >= TARGET else 'NOT met'})")
    print(f"  controller share of the loop: {(full - zero) / full:.0%}; fault: {fault}")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 10.0)
