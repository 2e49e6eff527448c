"""rhi.runtime.teleoperated: any device link as the master of a simulated slave robot, its path in the log."""

from __future__ import annotations

import numpy as np
import pytest

from rhi.devices.model import device
from rhi.errors import InvalidInput
from rhi.experiments.ch5.setup import controller
from rhi.runtime import SimLink, Telemetry, run
from rhi.runtime.teleoperated import Teleoperated
from rhi.sim import Hand, HandPath, Plant, Teleoperation

SCALE, OFFSET = 1.25, np.array([-0.05, 0.0])


def master_and_slave():
    dev, slave = device("rehab", d2=0.1405), device("rehab_slave")
    x0 = np.array([0.46, 0.0])
    plant = Plant(dev)
    plant.reset(dev.ik(x0, np.array([0.3, 0.9])))
    sp = Plant(slave)
    sp.reset(slave.ik(SCALE * x0 + OFFSET, np.full(2, 0.3)))
    return dev, plant, Teleoperation(sp, scale=SCALE, offset=OFFSET), x0


def test_the_slave_follows_the_mapped_master_and_the_log_holds_its_path():
    dev, plant, tele, x0 = master_and_slave()
    hand = Hand(HandPath(np.array([x0, x0 + [0.02, 0.03]]), 0.05))  # 3.6 cm in 0.72 s, then held
    telemetry = Telemetry(every=1)
    res = run(Teleoperated(SimLink(plant, hand=hand), dev, tele, rate=1000.0), controller(dev, None, 1.0, 0.05),
              duration=1.5, realtime=False, telemetry=telemetry)
    log = res.log
    assert res.summary["fault"] is None and log.slave_x.shape == log.x.shape
    np.testing.assert_allclose(log.x[-1], x0 + [0.02, 0.03], atol=2e-3)
    # the slave is where the map sends the master (a PD's lag while moving), not where the master is
    np.testing.assert_allclose(log.slave_x[-1], SCALE * log.x[-1] + OFFSET, atol=1e-3)
    assert np.median(np.linalg.norm(log.slave_x - (SCALE * log.x + OFFSET), axis=1)) < 2e-3
    np.testing.assert_allclose(np.ptp(log.slave_x, axis=0) / np.ptp(log.x, axis=0), SCALE, rtol=0.05)
    np.testing.assert_allclose(telemetry.latest().slave_x, log.slave_x[-1])


def test_a_bad_slave_is_refused_naming_it():
    dev, plant, tele, _ = master_and_slave()
    with pytest.raises(InvalidInput, match="^teleop: expected"):
        Teleoperated(SimLink(plant), dev, object(), rate=1000.0)
    with pytest.raises(InvalidInput, match="^teleop: its map takes 2 master axes, the device has 3"):
        Teleoperated(SimLink(plant), device("phantom3"), tele, rate=1000.0)
    with pytest.raises(InvalidInput, match="^rate"):
        Teleoperated(SimLink(plant), dev, tele, rate=0.0)
