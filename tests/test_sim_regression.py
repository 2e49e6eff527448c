"""The optimised simulation loop against the previous one: same log to 1e-9 on a seeded palpation scenario.

tests/data/sim_palpation_rhi4.npz was written by `scenario()` below with the loop, plant, hand and
Device of main at 941fa50 (before the speed work of issue 14: one `Device.terms` per tick, bisected
path segments, cheaper plant stepping). The hand follows a two-segment path into a rendered wall
while the full ch7 controller (force rendering, FME schedule, ASO, ASCM) runs at 1 kHz.
"""

from __future__ import annotations

from pathlib import Path as FilePath

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

REFERENCE = FilePath(__file__).parent / "data" / "sim_palpation_rhi4.npz"
FIELDS = ["t", "q", "dq", "tau", "x", "xdot", "F_hand", "F_env", "ft", "work", "V", "omega", "alpha", "beta"]
Q0 = np.array([-0.63, 0.25, 0.28, 0.09])


def scenario(duration: float = 0.9):
    dev = rhi.device("rhi4")
    K, z = fme_shape(dev.jacobian(np.zeros(4)), dev.torque_max, 5.0)
    cfg = ControllerConfig(ForceRendering(damping=0.01, passivity=None),
                           fme=FMESchedule(desired_fme_free([0, 1], K, z), desired_fme_stiff([0, 1], K, z)),
                           saturation="ascm")
    plant = Plant(dev)
    plant.reset(Q0)
    x0 = dev.fk(Q0)
    hand = Hand(Path([x0, x0 + [0.01, 0.0], x0 + [0.01, 0.03]], speed=0.02), stiffness=300.0)
    return simulate(plant, NullSpaceController(dev, cfg), duration=duration, hand=hand,
                    virtual=Wall(x0 + [0.0, 0.005], [0, 1], 1000.0))


def test_log_equals_previous_loop():
    log = scenario()
    ref = np.load(REFERENCE)
    assert log.fault is None
    assert float(np.max(np.abs(ref["F_env"]))) > 0.1  # the wall is reached: contact is part of the check
    for f in FIELDS:
        np.testing.assert_allclose(getattr(log, f), ref[f], rtol=0, atol=1e-9, err_msg=f)


def test_path_segment_lookup_matches_linear_scan():
    P = np.array([[0.0, 0.0], [0.01, 0.0], [0.01, 0.0], [0.01, 0.02], [-0.01, 0.02]])  # a zero-length segment
    path = Path(P, speed=0.05, start=0.1)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    for t in np.linspace(0.0, 1.2, 241):
        d = (t - 0.1) * 0.05
        x, v = path(t)
        if t <= 0.1 or d >= s[-1]:
            assert np.array_equal(v, np.zeros(2))
            continue
        i = 0
        while s[i + 1] <= d:
            i += 1
        u = (P[i + 1] - P[i]) / (s[i + 1] - s[i])
        np.testing.assert_allclose(x, P[i] + (d - s[i]) * u, atol=1e-15)
        np.testing.assert_allclose(v, 0.05 * u, atol=1e-15)
