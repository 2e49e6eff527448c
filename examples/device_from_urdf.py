"""Your own robot: a planar 3R arm from a URDF (written here), measured like a bundled device.

The URDF text could as well be a file path, a xacro file (``device_from_urdf``), an MJCF file
(``rhi.device_from_mjcf``) or an installed description package (``rhi.device_from_description``).
The Jacobian agrees with the closed form of a planar 3R arm with links 0.3, 0.25 and 0.15 m.

Run: ``python examples/device_from_urdf.py``. Needs only the core install.

Expected output (tests/test_examples.py checks every value to the tolerance given)::

    n = 3 +- 0
    m = 2 +- 0
    jacobian_error = 0.0 +- 1e-12
    manipulability = 0.0755 +- 0.0001
    max_force_x_N = 13.9024 +- 0.0001
"""

import numpy as np

import rhi
from rhi import metrics

L = (0.3, 0.25, 0.15)  # link lengths [m]


def link(name: str, length: float) -> str:
    """A thin rod of 0.5 kg along x with its centre of mass halfway."""
    return f"""
  <link name="{name}">
    <inertial><origin xyz="{length / 2} 0 0"/><mass value="0.5"/>
      <inertia ixx="1e-5" iyy="{0.5 * length**2 / 12}" izz="{0.5 * length**2 / 12}" ixy="0" ixz="0" iyz="0"/>
    </inertial>
  </link>"""


def joint(i: int, parent: str, child: str, x: float) -> str:
    """A revolute joint about z at distance x along the parent, ±150°, 2 N m."""
    return f"""
  <joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{x} 0 0"/><axis xyz="0 0 1"/><limit lower="-2.6" upper="2.6" effort="2.0" velocity="5"/>
  </joint>"""


urdf = ('<robot name="arm3r"><link name="base"/>' + link("l1", L[0]) + link("l2", L[1]) + link("l3", L[2])
        + '<link name="tip"/>' + joint(1, "base", "l1", 0.0) + joint(2, "l1", "l2", L[0]) + joint(3, "l2", "l3", L[1])
        + '<joint name="tip_joint" type="fixed"><parent link="l3"/><child link="tip"/><origin xyz="0.15 0 0"/></joint>'
        + "</robot>")

arm = rhi.device_from_urdf(urdf, ee_frame="tip", task="xy", name="arm3r")
q = np.array([0.3, 0.9, -0.6])  # [rad]
J = arm.jacobian(q)

# closed form: x = Σ L_i cos(θ_1 + ... + θ_i), y = Σ L_i sin(...)
phi = np.cumsum(q)
J_ref = np.array([[-sum(L[k] * np.sin(phi[k]) for k in range(i, 3)) for i in range(3)],
                  [sum(L[k] * np.cos(phi[k]) for k in range(i, 3)) for i in range(3)]])
print(f"n = {arm.n}")
print(f"m = {J.shape[0]}")
print(f"jacobian_error = {np.abs(J - J_ref).max():.2e}")
print(f"manipulability = {metrics.manipulability(J):.4f}")
lo, hi, M = arm.torque_min, arm.torque_max, arm.mass_matrix(q)
print(f"max_force_x_N = {metrics.max_force(J, [1, 0], torque_min=lo, torque_max=hi, projector='dynamic', M=M):.4f}")
