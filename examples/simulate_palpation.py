"""Palpation on the MuJoCo plant: a simulated hand pushes the 4-DoF RHI into a rendered wall (thesis ch. 7).

The hand moves 5 cm along +y at 2 cm/s; a 1000 N/m virtual wall starts 1 cm ahead and a rigid stop
3 cm ahead. The controller renders the wall with ASCM saturation handling; the log (time, joints,
torques, handle position, hand force, F/T sensor, work...) is written as CSV.

Run: ``python examples/simulate_palpation.py [OUT_DIR]``. Needs the ``sim`` extra (MuJoCo).

Expected output (tests/test_examples.py checks every value to the tolerance given)::

    ticks = 1000 +- 0
    penetration_mm = 2.40 +- 0.02
    wall_force_N = 2.397 +- 0.02
    max_abs_tau_Nm = 0.6570 +- 0.002
    csv_rows = 1000 +- 0
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import rhi
from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
from rhi.sim import Hand, HandPath, Plant, Wall, simulate, stop

dev = rhi.device("rhi4")
q0 = np.array([-0.63, 0.25, 0.28, 0.09])  # [rad]
plant = Plant(dev)                         # MuJoCo model generated from the device description
plant.reset(q0)
x0 = dev.fk(q0)                            # handle position [m]
ctrl = NullSpaceController(dev, ControllerConfig(primary=ForceRendering(passivity=None), saturation="ascm"))
log = simulate(
    plant, ctrl, duration=1.0,
    hand=Hand(HandPath([x0, x0 + [0, 0.05]], speed=0.02)),                 # the user pushes in at 2 cm/s
    virtual=Wall(x0 + [0, 0.01], normal=[0, 1], stiffness=1000.0),       # rendered tissue, 1000 N/m
    physical=stop(x0 + [0, 0.03], [0, 1]),                                # a rigid stop in the plant
)
out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp())
log.to_csv(out / "palpation.csv")

depth = log.x[-1, 1] - (x0[1] + 0.01)       # how far the handle went past the wall [m]
print(f"ticks = {len(log.t)}")
print(f"penetration_mm = {1e3 * depth:.2f}")
print(f"wall_force_N = {1000.0 * max(depth, 0.0):.3f}")
print(f"max_abs_tau_Nm = {np.abs(log.tau).max():.4f}")
print(f"csv_rows = {sum(1 for _ in open(out / 'palpation.csv')) - 1}")
