"""The "traditional" acceleration-level baseline of thesis §B.4.3: the plain pseudoinverse with the tertiary objective."""

from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np

from rhi.control.mobile.amd import AccelCommand, AccelControllerBase
from rhi.control.mobile.bounds import (
    JointBounds,
    acceleration_bounds_unchecked,
    check_dt,
)
from rhi.devices.model import Device
from rhi.errors import InvalidInput


@dataclasses.dataclass(frozen=True)
class PinvAccelConfig:
    """The "traditional" acceleration-level controller of §B.4.3.

    Attributes:
        dt, kp, kd, gamma1, gamma2: as in `AMDConfig`.
        manipulability: add (I − J⁺J) q̈_A with q̈_A of eq. B.13 (thesis: yes).
        limit: what keeps the command within the joint acceleration bounds (B.6–B.8),
            which the thesis's baseline does not consider: "clip" each joint (what a robot
            driver does) or "none".
        bounds: joint bounds; None: the device's.
    """

    dt: float = 0.005
    kp: float = 20.0
    kd: float = 10.0
    gamma1: float = 5.0
    gamma2: float = 0.5
    manipulability: bool = True
    limit: Literal["clip", "none"] = "clip"
    bounds: JointBounds | None = None

    def __post_init__(self) -> None:
        check_dt(self.dt)
        if self.limit not in ("clip", "none"):
            raise InvalidInput(f"limit: expected 'clip' or 'none', got {self.limit!r}")


class PinvAccelController(AccelControllerBase):
    """q̈ = J⁺(ẍ − J̇q̇) + (I − J⁺J) q̈_A with the plain pseudoinverse J⁺ = Jᵀ(JJᵀ)⁻¹ (thesis §B.4.3).

    Args:
        device: the mobile manipulator.
        config: parameters.
    """

    def __init__(self, device: Device, config: PinvAccelConfig | None = None) -> None:
        super().__init__(device, config or PinvAccelConfig())
        self.clipped = 0

    def reset(self) -> None:
        """Fresh state (clip counter)."""
        self.clipped = 0

    def step(self, t: float, q, dq, x_des, dx_des, ddx_des) -> AccelCommand:
        """One control step (arguments as `AMDController.step`)."""
        q, dq, x_des, dx_des, ddx_des = self._inputs(q, dq, x_des, dx_des, ddx_des)
        c, n = self.config, self.device.n
        x, J6, J, b, ddx = self._task(q, dq, x_des, dx_des, ddx_des)
        Jp = np.linalg.pinv(J)
        ddq = Jp @ (ddx - b)
        if c.manipulability:
            ddq = ddq + (np.eye(n) - Jp @ J) @ self._tertiary(J6, dq)[0]
        lo, hi = acceleration_bounds_unchecked(q, dq, self.bounds, c.dt)
        if c.limit == "clip":
            out = np.clip(ddq, lo, hi)
            self.clipped += int(np.any(out != ddq))
            ddq = out
        Jm = J[:, self.n_base:]
        sigma = float(np.sqrt(max(np.linalg.eigvalsh(Jm @ Jm.T)[0], 0.0)))
        return AccelCommand(ddq, ddx, x, 1.0, 1.0, np.ones(n, bool), True, sigma, lo, hi)
