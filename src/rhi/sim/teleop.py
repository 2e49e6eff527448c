"""Unilateral master–slave teleoperation (thesis §5.3, Fig. 5.2).

The slave (e.g. `rehab_slave`) is a second MuJoCo plant that PD-tracks the master's
end-effector position mapped into the slave frame, x_s,des = s R x_m + p, with a Cartesian
PD plus gravity compensation computed from its own encoders and model:
τ_s = J_sᵀ (K_p (x_s,des − x_s) − K_d ẋ_s) + g_s(q_s).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from rhi._validate import as_array, scalar
from rhi.errors import InvalidInput
from rhi.sim.plant import Plant


class Teleoperation:
    """A slave plant that follows the master.

    Args:
        slave: the slave plant (already reset to its start).
        kp: Cartesian stiffness K_p [N/m].
        kd: Cartesian damping K_d [N s/m].
        scale: motion scaling s.
        rotation: (m, m) master→slave rotation R (default identity).
        offset: (m,) p [m].
    """

    def __init__(self, slave: Plant, *, kp: float = 2000.0, kd: float = 60.0, scale: float = 1.0,
                 rotation=None, offset=None) -> None:
        m = slave.m
        for name, v in (("kp", kp), ("kd", kd), ("scale", scale)):
            if not np.isfinite(v) or v < 0:
                raise InvalidInput(f"{name}: must be finite and >= 0, got {v!r}")
        self.slave, self.kp, self.kd, self.scale = slave, float(kp), float(kd), float(scale)
        self.R = np.eye(m) if rotation is None else as_array("rotation", rotation, shape_tail=(m, m))
        self.p = np.zeros(m) if offset is None else as_array("offset", offset, shape_tail=(m,))

    def target(self, x_master) -> np.ndarray:
        """Slave set-point s R x_m + p: (m,) [m]."""
        return self.scale * self.R @ np.asarray(x_master) + self.p

    def follow(self, x_master, dt: float) -> np.ndarray:
        """Track the master's position x_m (m,) [m] for one control period dt [s].

        Returns the slave's true position (m,) [m].

        Raises:
            InvalidInput: a non-finite or misshapen x_master, or dt not > 0 (named).
        """
        x_master = as_array("x_master", x_master, shape_tail=(self.R.shape[1],))
        scalar("dt", dt, positive=True)
        s, dev = self.slave, self.slave.device
        q, dq = s.q, s.dq
        # what dev.jacobian(q), dev.fk(q) and dev.gravity(q) compute, without their checks (q is the plant's
        # own finite state) and with θ = A q + b formed once: this runs at every tick of a teleoperated run
        model, data = dev.model, dev.data
        th = q @ dev.A.T + dev.b
        J = dev.jacobian_theta(th)  # its forward pass placed the end-effector's joint: no second one for x
        x = pin.updateFramePlacement(model, data, dev.ee_frame_id).translation[dev.task_rows]
        F = self.kp * (self.target(x_master) - x) - self.kd * (J @ dq)
        s.apply(J.T @ F + dev.A.T @ pin.computeGeneralizedGravity(model, data, th))
        s.step(max(1, round(dt / s.timestep)))
        return s.x
