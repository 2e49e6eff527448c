"""The device link: what a controller loop reads from and writes to a haptic device.

A `DeviceLink` is anything with `open()`, `read() -> Reading`, `write(tau, *, enable)` and
`close()`: the simulated device (`SimLink`), a device process over UDP (`UDPLink`, protocol
in docs/protocol.md), or a lab's own driver wrapped in four methods.
"""

from __future__ import annotations

import dataclasses
import enum
from typing import Protocol

import numpy as np

from rhi.errors import LinkError

__all__ = ["DeviceLink", "LinkError", "Reading", "Status"]


class Status(enum.IntFlag):
    """Device status flags carried by every reading (bit values are the protocol's)."""

    ENABLED = 1  # motors powered, the last command's torque is applied
    ESTOP = 2  # the device's emergency stop is active (zero torque)
    WATCHDOG = 4  # no valid command within the watchdog time: zero torque until the next valid one
    FAULT = 8  # the device faulted (driver error, unstable simulation): zero torque, latched
    SIMULATED = 16  # the device is a simulation: sensors carry ground truth (x, xdot, F_hand, work)


@dataclasses.dataclass
class Reading:
    """One sample of the device.

    Attributes:
        t: device timestamp [s] (the device's monotonic clock).
        seq: sequence number, +1 per sample the device produces.
        q: (n,) motor angles [rad].
        dq: (n,) motor velocities [rad/s].
        sensors: named readings, e.g. "ft": (6,) force [N] and torque [N m] in world axes.
        status: `Status` flags.
        cmd_seq: sequence number of the last command the device applied (-1: none yet).
        detail: the device's reason for a FAULT/ESTOP flag, if it gave one.
        arrival: host monotonic time [s] the reading arrived (None: a local link, read when asked).
        age: round-trip age [s]: `arrival` minus the host time the command echoed in `cmd_seq` was sent
            (NaN: not measured, e.g. a local link or no command sent yet).
    """

    t: float
    seq: int
    q: np.ndarray
    dq: np.ndarray
    sensors: dict[str, np.ndarray]
    status: int = 0
    cmd_seq: int = -1
    detail: str = ""
    arrival: float | None = None
    age: float = float("nan")


class DeviceLink(Protocol):
    """A haptic device as the control loop sees it."""

    n: int  # number of motors

    def open(self) -> None:
        """Connect (and, for a remote device, check the protocol version)."""

    def read(self) -> Reading:
        """The newest reading (it may repeat the previous one if the device sent nothing new)."""

    def write(self, tau: np.ndarray, *, enable: bool) -> None:
        """Command torques τ: (n,) [N m]; `enable=False` commands zero torque with the motors disabled."""

    def close(self) -> None:
        """Command zero torque and disconnect."""
