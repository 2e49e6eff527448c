"""Measures of the 4-DoF RHI at the thesis's optimised configuration (thesis §3.5, Table 3.1).

Run: ``python examples/measures_rhi4.py``. Needs only the core install (NumPy, Pinocchio, SciPy).

Expected output (tests/test_examples.py checks every value to the tolerance given)::

    rho = 0.3752 +- 0.0001
    Lambda = 0.0539 +- 0.0001
    rho_phantom = 0.1879 +- 0.0001
    max_force_lp = 5.5458 +- 0.0001
    max_force_scaling = 5.0166 +- 0.0001
    map_points = 2926 +- 0
    map_mean_rho = 0.324 +- 0.001
"""

import numpy as np

import rhi
from rhi import metrics

dev = rhi.device("rhi4")                     # planar 4-DoF RHI: rehab base + PHANToM half
q = np.array([0.125, 0.022, 0.298, 0.175])   # [rad] the thesis's optimised configuration
u = np.array([0.0, 1.0])                     # direction of motion / force
J, M = dev.jacobian(q), dev.mass_matrix(q)   # (2, 4) [m/rad], (4, 4) [kg m²]

# effective manipulability ρ (eq. 3.6) and apparent inertia Λ along u (eq. 3.9)
print(f"rho = {metrics.effective_manipulability(J, u):.4f}")
print(f"Lambda = {metrics.effective_inertia(J, M, u):.4f}")

# the same end-effector point reached by the non-redundant PHANToM half alone
phantom = dev.lock(q1=0, q2=0)
qp = phantom.ik(dev.fk(q), q0=[0.3, 0.3])
print(f"rho_phantom = {metrics.effective_manipulability(phantom.jacobian(qp), u):.4f}")

# the largest force along u under the torque limits (§7.3): LP with null-space torques vs simple scaling Jᵀ(f u)
lo, hi = dev.torque_min, dev.torque_max
print(f"max_force_lp = {metrics.max_force(J, u, torque_min=lo, torque_max=hi, projector='dynamic', M=M):.4f}")
print(f"max_force_scaling = {metrics.max_force_scaling(J, u, torque_min=lo, torque_max=hi):.4f}")

# batch-first: one call over 10,000 random configurations (those within the device's linear limits)
Q = np.random.default_rng(0).uniform(dev.q_min, dev.q_max, (10_000, 4))
Q = Q[dev.within_limits(Q)]
print(f"map_points = {len(Q)}")
print(f"map_mean_rho = {metrics.effective_manipulability(dev.jacobian(Q), u).mean():.3f}")
