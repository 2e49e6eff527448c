"""`Teleoperated`: any device link as the master of a simulated slave robot (unilateral teleoperation, thesis §5.3).

The master is a `SimLink`, a `UDPLink` or a lab's driver. Each reading's encoders give the master's handle
x_m = FK(q) on the controller's model; each command (one control period) then advances the slave
(`rhi.sim.Teleoperation`: a Cartesian PD toward s R x_m + p in its own MuJoCo plant) by that period. Readings
carry the slave's end effector as ``sensors["slave_x"]`` [m], which `rhi.runtime.run` logs (the ``slave_x``
columns) and publishes to its telemetry. The slave starts where its plant was reset; place the master where the
map sends it there.
"""

from __future__ import annotations

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput
from rhi.runtime.link import Reading


class Teleoperated:
    """A device link whose handle drives a teleoperated slave (see the module docstring).

    Args:
        link: the master's link (not yet opened).
        device: the master's model (its FK gives x_m from the encoders).
        teleop: the slave, a `rhi.sim.Teleoperation` (its plant already reset to its start).
        rate: control rate [Hz]: the slave advances 1/rate per command.

    Attributes:
        slave_m: the slave's task dimension (the width of the logged ``slave_x``).
        slave_x: (slave_m,) the slave's end effector after the last command [m].
    """

    def __init__(self, link, device, teleop, *, rate: float) -> None:
        if not callable(getattr(teleop, "follow", None)):
            raise InvalidInput(f"teleop: expected an rhi.sim.Teleoperation, got {type(teleop).__name__}")
        if teleop.R.shape[1] != device.m:
            raise InvalidInput(f"teleop: its map takes {teleop.R.shape[1]} master axes, the device has {device.m}")
        self.link, self.device, self.teleop = link, device, teleop
        self.dt = 1.0 / scalar("rate", rate, positive=True)
        self.slave_m = int(teleop.slave.m)
        self.slave_x = np.array(teleop.slave.x, dtype=float)
        self._q: np.ndarray | None = None

    @property
    def n(self):
        """The master's motors (None or 0 before a device process connects)."""
        return getattr(self.link, "n", None)

    @property
    def rate(self):
        """The master link's rate [Hz], if it has one."""
        return getattr(self.link, "rate", None)

    @property
    def sensors(self):
        """The master device's sensors, if it reports them (`rhi.runtime.run` checks them at connect)."""
        return getattr(self.link, "sensors", None)

    @property
    def stats(self) -> dict:
        """The master link's counters."""
        return getattr(self.link, "stats", {})

    def open(self) -> None:
        """Open the master's link."""
        self.link.open()

    def read(self) -> Reading:
        """The master's reading with the slave's end effector added as ``sensors["slave_x"]``."""
        r = self.link.read()
        self._q = r.q
        r.sensors = {**r.sensors, "slave_x": self.slave_x}
        return r

    def write(self, tau, *, enable: bool) -> None:
        """Command the master for one period, then advance the slave toward the master's last read position."""
        self.link.write(tau, enable=enable)
        if self._q is not None:
            self.slave_x = self.teleop.follow(self.device.fk(self._q), self.dt)

    def close(self) -> None:
        """Close the master's link (the simulated slave needs nothing)."""
        self.link.close()


__all__ = ["Teleoperated"]
