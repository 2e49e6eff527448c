"""Regenerate `gen3.urdf` and `../wmm/wmm.urdf` from the published Kinova Gen3 data.

Not imported by `rhi`; run `python make_urdf.py` in this folder after changing a number.
Sources of every number: README.md in this folder and in ../wmm.

Kinematics: the classic Denavit-Hartenberg table of the Kinova Gen3 7-DoF user guide
(frame i+1 = frame i · Rz(q_i + θ_offset_i) · Tz(d_i) · Rx(α_i), with the leading row
"base → frame 1" = Rx(π)). URDF link i is the DH frame whose z axis is joint i's axis,
attached to the body that joint i moves, so joint i's <origin> is
Tz(d_{i-1}) · Rx(α_{i-1}) · Rz(θ_offset_i) (the first one is the base row Rx(π)).

Inertia: masses, centres of mass and inertia tensors of Kinova's kortex_description URDF
(GEN3-7DOF-VISION_ARM_URDF_V12.urdf), re-expressed from Kinova's URDF link frames into
these DH link frames (the two chains share joint axes and zero configuration; the
constant transform between the link frames is computed at q = 0 below).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

HERE = Path(__file__).parent
PI = np.pi

# Kinova Gen3 7-DoF user guide, classic DH table (lengths in m):
# rows (alpha_i, a_i, d_i, theta_offset_i) for i = 1..7; the last one is "7 → interface".
BASE_ROW_ALPHA = PI
DH = [
    (PI / 2, 0.0, -(0.1564 + 0.1284), 0.0),
    (PI / 2, 0.0, -(0.0054 + 0.0064), PI),
    (PI / 2, 0.0, -(0.2104 + 0.2104), PI),
    (PI / 2, 0.0, -(0.0064 + 0.0064), PI),
    (PI / 2, 0.0, -(0.2084 + 0.1059), PI),
    (PI / 2, 0.0, 0.0, PI),
    (PI, 0.0, -(0.1059 + 0.0615), PI),
]
LINKS = [
    "base_link",
    "shoulder_link",
    "half_arm_1_link",
    "half_arm_2_link",
    "forearm_link",
    "spherical_wrist_1_link",
    "spherical_wrist_2_link",
    "bracelet_link",
]

# kortex_description/arms/gen3/7dof/urdf/GEN3-7DOF-VISION_ARM_URDF_V12.urdf (Kinova Robotics):
# per link (mass [kg], com [m], (ixx, ixy, ixz, iyy, iyz, izz) [kg m^2]) in Kinova's link frames,
# and Kinova's joint origins (xyz, rpy) used only to find the frame change.
KORTEX_INERTIA = [
    (1.697, (-0.000648, -0.000166, 0.084487), (0.004622, 9e-06, 6e-05, 0.004495, 9e-06, 0.002079)),
    (1.3773, (-2.3e-05, -0.010364, -0.07336), (0.00457, 1e-06, 2e-06, 0.004831, 0.000448, 0.001409)),
    (1.1636, (-4.4e-05, -0.09958, -0.013278), (0.011088, 5e-06, 0.0, 0.001072, -0.000691, 0.011255)),
    (1.1636, (-4.4e-05, -0.006641, -0.117892), (0.010932, 0.0, -7e-06, 0.011127, 0.000606, 0.001043)),
    (0.9302, (-1.8e-05, -0.075478, -0.015006), (0.008147, -1e-06, 0.0, 0.000631, -0.0005, 0.008316)),
    (0.6781, (1e-06, -0.009432, -0.063883), (0.001596, 0.0, 0.0, 0.001607, 0.000256, 0.000399)),
    (0.6781, (1e-06, -0.045483, -0.00965), (0.001641, 0.0, 0.0, 0.00041, -0.000278, 0.001641)),
    (0.5006, (-0.000281, -0.011402, -0.029798), (0.000587, 3e-06, 3e-06, 0.000369, 0.000118, 0.000609)),
]
KORTEX_JOINTS = [
    ((0, 0, 0.15643), (PI, 0, 0)),
    ((0, 0.005375, -0.12838), (PI / 2, 0, 0)),
    ((0, -0.21038, -0.006375), (-PI / 2, 0, 0)),
    ((0, 0.006375, -0.21038), (PI / 2, 0, 0)),
    ((0, -0.20843, -0.006375), (-PI / 2, 0, 0)),
    ((0, 0.00017505, -0.10593), (PI / 2, 0, 0)),
    ((0, -0.10593, -0.00017505), (-PI / 2, 0, 0)),
]

# Table B.1 (rad) and §A.4.3 (N m); inf = unbounded (continuous joint)
URDF_LIMIT = 6.2832  # bounded revolute in the URDF so that nq == nv; true limits in device.toml

# Mobile base (thesis Fig. A.4 / B.6; custom-built, no inertial data published): FLAGGED ESTIMATES
BASE_MASS = 40.0  # kg
BASE_BOX = (0.60, 0.50, 0.20)  # m, length x width x height
BASE_COM_Z = -0.10  # m, below the arm mount (the arm base sits on the top plate)
MOUNT_Z = 0.0  # m: Σ_m coincides with Σ_b (thesis §A.4.1), and Σ_b with Σ_w at q_b = 0


def _origin(M: pin.SE3) -> str:
    t = np.where(np.abs(M.translation) < 1e-15, 0.0, M.translation)
    r = pin.rpy.matrixToRpy(M.rotation)
    r = np.where(np.abs(r) < 1e-15, 0.0, r)
    return f'<origin xyz="{t[0]:.10g} {t[1]:.10g} {t[2]:.10g}" rpy="{r[0]:.17g} {r[1]:.17g} {r[2]:.17g}"/>'


def _dh_tail(alpha: float, a: float, d: float) -> pin.SE3:
    """Tz(d) · Tx(a) · Rx(α)."""
    return pin.SE3(np.eye(3), np.array([a, 0.0, d])) * pin.SE3(pin.utils.rotate("x", alpha), np.zeros(3))


def joint_origins() -> list[pin.SE3]:
    """Placements of joints 1..7 in their parent DH link frame, and of the interface frame (8 entries)."""
    out = [pin.SE3(pin.utils.rotate("x", BASE_ROW_ALPHA), np.zeros(3))]  # base row
    for i in range(1, 7):
        alpha, a, d, _ = DH[i - 1]
        out.append(_dh_tail(alpha, a, d) * pin.SE3(pin.utils.rotate("z", DH[i][3]), np.zeros(3)))
    alpha, a, d, _ = DH[6]
    out.append(_dh_tail(alpha, a, d))  # interface (tool flange) frame
    return out


def _snap(R: np.ndarray) -> np.ndarray:
    """Round a rotation that Kinova wrote with 1.5708/3.1416 to the exact multiple of π/2."""
    Rs = np.round(R)
    assert np.allclose(R, Rs, atol=1e-4), R
    return Rs


def dh_inertias() -> list[pin.Inertia]:
    """Kinova's link inertias expressed in the DH link frames (base_link: same frame)."""
    dh_frames = [pin.SE3.Identity()]
    M = pin.SE3.Identity()
    for J in joint_origins()[:7]:
        M = M * J
        dh_frames.append(M)
    k_frames = [pin.SE3.Identity()]
    M = pin.SE3.Identity()
    for xyz, rpy in KORTEX_JOINTS:
        M = M * pin.SE3(pin.rpy.rpyToMatrix(*rpy), np.array(xyz, dtype=float))
        k_frames.append(M)
    out = []
    for (mass, com, (ixx, ixy, ixz, iyy, iyz, izz)), F, K in zip(KORTEX_INERTIA, dh_frames, k_frames):
        X = F.inverse() * K  # Kinova link frame in the DH link frame (constant: both rotate with the joint)
        X.rotation = _snap(X.rotation)
        I_k = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        out.append(X.act(pin.Inertia(mass, np.array(com), I_k)))
    return out


def _inertial(I: pin.Inertia) -> str:
    c, m = I.lever, I.mass
    T = I.inertia
    T = np.where(np.abs(T) < 1e-12, 0.0, T)
    c = np.where(np.abs(c) < 1e-12, 0.0, c)
    return (
        f'<inertial><origin xyz="{c[0]:.6g} {c[1]:.6g} {c[2]:.6g}" rpy="0 0 0"/><mass value="{m:.6g}"/>'
        f'<inertia ixx="{T[0, 0]:.6g}" ixy="{T[0, 1]:.6g}" ixz="{T[0, 2]:.6g}" iyy="{T[1, 1]:.6g}" '
        f'iyz="{T[1, 2]:.6g}" izz="{T[2, 2]:.6g}"/></inertial>'
    )


def arm_xml(mount: str | None = None, mount_origin: str = "") -> list[str]:
    """URDF lines of the arm; `mount` is the parent link of `base_link` (None for the bare arm)."""
    J = joint_origins()
    Iner = dh_inertias()
    lines = []
    if mount is not None:
        lines += [
            '  <joint name="arm_mount" type="fixed">',
            f'    <parent link="{mount}"/><child link="base_link"/>{mount_origin}',
            "  </joint>",
        ]
    lines.append(f'  <link name="base_link">{_inertial(Iner[0])}</link>')
    for i in range(7):
        lines += [
            f'  <joint name="joint_{i + 1}" type="revolute">',
            f'    <parent link="{LINKS[i]}"/><child link="{LINKS[i + 1]}"/>',
            f"    {_origin(J[i])}",
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="-{URDF_LIMIT}" upper="{URDF_LIMIT}" effort="{32.0 if i < 4 else 13.0}" '
            f'velocity="{1.75 if i < 4 else 3.14}"/>',
            "  </joint>",
            f'  <link name="{LINKS[i + 1]}">{_inertial(Iner[i + 1])}</link>',
        ]
    lines += [
        '  <joint name="interface" type="fixed">',
        f'    <parent link="bracelet_link"/><child link="end_effector"/>{_origin(J[7])}',
        "  </joint>",
        '  <link name="end_effector"/>',
    ]
    return lines


def gen3_urdf() -> str:
    """The Gen3 URDF text (7 DoF, no gripper) from the DH table and the kortex inertias."""
    head = [
        '<?xml version="1.0"?>',
        "<!-- Kinova Gen3 7-DoF (no gripper), generated by make_urdf.py from the classic DH table of the",
        "     Kinova Gen3 user guide and the inertial data of Kinova's kortex_description URDF. Link frames are",
        "     the DH frames; end_effector = tool interface (flange). Sources: README.md. -->",
        '<robot name="gen3">',
    ]
    return "\n".join(head + arm_xml() + ["</robot>", ""])


def wmm_urdf() -> str:
    """The WMM URDF text: the Gen3 on a planar (x, y, θ) Mecanum base."""
    a, b, h = BASE_BOX
    izz = BASE_MASS * (a * a + b * b) / 12
    ixx = BASE_MASS * (b * b + h * h) / 12
    iyy = BASE_MASS * (a * a + h * h) / 12
    lim = 'lower="-1000" upper="1000" effort="1e6" velocity="1"'
    head = [
        '<?xml version="1.0"?>',
        "<!-- Wheeled mobile manipulator of thesis App. A/B: Kinova Gen3 7-DoF on an omnidirectional (Mecanum)",
        "     base, generated by make_urdf.py in ../gen3. Base pose q_b = [x_b, y_b, theta_b] as a chain",
        "     world -> x slider -> y slider -> yaw. Base inertia: FLAGGED ESTIMATE. Sources: README.md. -->",
        '<robot name="wmm">',
        '  <link name="world"/>',
        '  <joint name="base_x" type="prismatic">',
        '    <parent link="world"/><child link="base_x_link"/><origin xyz="0 0 0" rpy="0 0 0"/>',
        f'    <axis xyz="1 0 0"/><limit {lim}/>',
        "  </joint>",
        '  <link name="base_x_link"/>',
        '  <joint name="base_y" type="prismatic">',
        '    <parent link="base_x_link"/><child link="base_y_link"/><origin xyz="0 0 0" rpy="0 0 0"/>',
        f'    <axis xyz="0 1 0"/><limit {lim}/>',
        "  </joint>",
        '  <link name="base_y_link"/>',
        '  <joint name="base_yaw" type="revolute">',
        '    <parent link="base_y_link"/><child link="mobile_base"/><origin xyz="0 0 0" rpy="0 0 0"/>',
        f'    <axis xyz="0 0 1"/><limit lower="-{URDF_LIMIT}" upper="{URDF_LIMIT}" effort="1e6" velocity="1"/>',
        "  </joint>",
        f'  <link name="mobile_base"><inertial><origin xyz="0 0 {BASE_COM_Z}" rpy="0 0 0"/><mass value="{BASE_MASS}"/>'
        f'<inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/></inertial></link>',
    ]
    mount = f'<origin xyz="0 0 {MOUNT_Z}" rpy="0 0 0"/>'
    return "\n".join(head + arm_xml("mobile_base", mount) + ["</robot>", ""])


if __name__ == "__main__":
    (HERE / "gen3.urdf").write_text(gen3_urdf())
    (HERE.parent / "wmm" / "wmm.urdf").write_text(wmm_urdf())
