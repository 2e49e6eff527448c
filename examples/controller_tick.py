"""One tick of the null-space controller on the 4-DoF RHI (thesis ch. 3 and 7).

The primary law renders a 2 N force along +y (eq. 7.2); the null space matches the velocity
ellipsoid to the direction of motion u = y (VME, eqs. 3.22-3.23). Null-space torques do not change
the force at the handle: J#ᵀ τ equals the rendered force.

Run: ``python examples/controller_tick.py``. Needs only the core install.

Expected output (tests/test_examples.py checks every value to the tolerance given)::

    output_force_x = 0.0 +- 1e-9
    output_force_y = 2.0 +- 1e-9
    null_space_torque_norm = 0.0290 +- 0.0001
    null_space_force = 0.0 +- 1e-9
    tau_within_limits = 1 +- 0
"""

import numpy as np

import rhi
from rhi.control import ControllerConfig, ForceRendering, NullSpaceController, ObjectiveTerm, VMEMatching, output_force

dev = rhi.device("rhi4")
q = np.array([-0.63, 0.25, 0.28, 0.09])  # [rad]
dq = np.zeros(4)                         # [rad/s]

config = ControllerConfig(
    primary=ForceRendering(passivity=None),                       # the thesis's law (eq. 7.2)
    objectives=[ObjectiveTerm(VMEMatching(u=(0.0, 1.0)), gain=0.5)],
    saturation="ascm",                                            # actuator-saturation compensation (ch. 7)
)
ctrl = NullSpaceController(dev, config)
tau = ctrl.step(0.0, q, dq, {"force": np.array([0.0, 2.0])})      # sensors["force"]: the force to render [N]

J, M = dev.jacobian(q), dev.mass_matrix(q)
F = output_force(J, tau - dev.gravity(q), M)                     # the force the torques put at the handle [N]
print(f"output_force_x = {F[0]:.9f}")
print(f"output_force_y = {F[1]:.9f}")
Jd = np.linalg.solve(M, J.T) @ np.linalg.inv(J @ np.linalg.solve(M, J.T))  # dynamically consistent J# (n, m)
tau_null = tau - dev.gravity(q) - J.T @ F                                   # the null-space part (I − Jᵀ J#ᵀ)(τ − g)
print(f"null_space_torque_norm = {np.linalg.norm(tau_null):.4f}")             # the VME objective acts ...
print(f"null_space_force = {np.linalg.norm(Jd.T @ tau_null):.9f}")            # ... without a force at the handle
print(f"tau_within_limits = {int(np.all((tau >= dev.torque_min) & (tau <= dev.torque_max)))}")
