"""What `rhi.sim.mobile.simulate_mobile` needs of a mobile-manipulator controller: one sample at a time."""

from __future__ import annotations

import dataclasses
from typing import Any, Protocol

import numpy as np

from rhi.control.mobile.bounds import JointBounds
from rhi.devices.model import Device


@dataclasses.dataclass(frozen=True)
class MobileStep:
    """What a controller commands over one sample.

    Attributes:
        dq: (n,) generalized velocity [ẋ_b, ẏ_b, θ̇_b, q̇_m] at the end of the sample [m/s, rad/s].
        ddq: (n,) constant acceleration over the sample [m/s², rad/s²] (acceleration-level
            controllers, integrated as q⁺ = q + q̇T + q̈T²/2), or None (velocity-level: dq holds
            over the sample).
        x: (3,) end-effector position from the controller's kinematics [m].
        record: {log column: value} scalars the log keeps (`rhi.sim.mobile.MobileLog`:
            base_active, alpha, beta, sigma, gamma, eta, dm).
    """

    dq: np.ndarray
    ddq: np.ndarray | None
    x: np.ndarray
    record: dict[str, float]


class MobileController(Protocol):
    """A mobile-manipulator controller (App. A velocity level or App. B acceleration level).

    Attributes:
        device: the mobile manipulator; q = [x_b, y_b, θ_b, q_m].
        config: parameters, with the sampling time ``dt`` [s].
        bounds: the joint bounds it keeps.
    """

    device: Device
    config: Any
    bounds: JointBounds

    def reset(self) -> None:
        """Fresh state before a run."""

    def advance(self, t: float, q, dq, x_des, dx_des, ddx_des, *, stage: str = "track") -> MobileStep:
        """One sample at time t [s] from the measured q, the commanded q̇ and the desired motion (3,) each.

        ``stage`` selects a phase of App. A's DM enhancement ("track", "dm_cartesian", "dm_null");
        controllers without stages ignore it.
        """
