"""Omnidirectional (Mecanum) mobile base of the wheeled mobile manipulator (thesis App. A, B).

The base pose q_b = [x_b, y_b, θ_b] (world frame, [m, m, rad]) moves with the wheel
speeds v_b = (ω_fl, ω_fr, ω_bl, ω_br) [rad/s] as q̇_b = P(q_b) v_b (eq. A.3), with
P = J_I(θ_b) J_V (eq. A.21 / B.21). The WMM Jacobian maps wheel speeds and arm joint
rates to the end-effector velocity: ẋ = [J_b P, J_m] · (v_b; q̇_m) (eq. A.5 / B.2).

Wheel order is front-left, front-right, back-left, back-right (eq. B.21); positive wheel
speed drives the base forward (+x_b). The geometry (R, l1 = d1, l2 = d2) is not given
numerically in the thesis: `wheel_geometry("wmm")` returns the documented estimates
of models/wmm/device.toml.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rhi._validate import as_array, scalar
from rhi.devices.spec import bundled_spec
from rhi.errors import InvalidInput, ModelError

if TYPE_CHECKING:
    from rhi.devices.model import Device

BASE_JOINTS = ("x_b", "y_b", "theta_b")


def body_map(*, wheel_radius: float, half_length: float, half_width: float) -> np.ndarray:
    """Wheel speeds to base twist in the base frame, J_V of eq. A.21 / B.21.

    Args:
        wheel_radius: R [m].
        half_length: l1 (A.21) = d1 (B.21), base centre to wheel axle along x_b [m].
        half_width: l2 (A.21) = d2 (B.21), base centre to wheel mid-plane along y_b [m].

    Returns:
        (3, 4) matrix: [v_x, v_y, ω] (base frame) [m/s, m/s, rad/s] per wheel speed [rad/s].
    """
    R = scalar("wheel_radius", wheel_radius, positive=True)
    L = scalar("half_length", half_length, positive=True) + scalar("half_width", half_width, positive=True)
    return (R / 4.0) * np.array(
        [
            [1.0, 1.0, 1.0, 1.0],
            [-1.0, 1.0, 1.0, -1.0],
            [-1.0 / L, 1.0 / L, -1.0 / L, 1.0 / L],
        ]
    )


def mecanum_map(theta_b, *, wheel_radius: float, half_length: float, half_width: float) -> np.ndarray:
    """Base velocity map P(q_b) = J_I(θ_b) J_V (thesis eq. A.21 / B.21), with q̇_b = P v_b (eq. A.3).

    Args:
        theta_b: (...,) base heading [rad].
        wheel_radius: wheel radius R [m] (see `body_map`).
        half_length: half the wheelbase l1 [m] (see `body_map`).
        half_width: half the track l2 [m] (see `body_map`).

    Returns:
        P: (..., 3, 4) mapping wheel speeds [rad/s] to [ẋ_b, ẏ_b, θ̇_b] (world frame) [m/s, m/s, rad/s].
    """
    th = as_array("theta_b", theta_b)
    JV = body_map(wheel_radius=wheel_radius, half_length=half_length, half_width=half_width)
    c, s = np.cos(th), np.sin(th)
    JI = np.zeros(th.shape + (3, 3))
    JI[..., 0, 0], JI[..., 0, 1] = c, -s
    JI[..., 1, 0], JI[..., 1, 1] = s, c
    JI[..., 2, 2] = 1.0
    return JI @ JV


def wheel_geometry(device: Device | str = "wmm") -> dict[str, float]:
    """The Mecanum geometry a device declares (its `[mobile_base]` table): {wheel_radius, half_length, half_width} [m].

    Args:
        device: a `Device` loaded from a bundled description (its `Device.spec`), or a bundled device's name.

    Raises:
        UnknownDevice: no bundled device has that name.
        ModelError: the device declares no mobile base.
    """
    spec = bundled_spec(device) if isinstance(device, str) else device.spec
    name = device if isinstance(device, str) else device.name
    if spec is None or spec.mobile_base is None:
        raise ModelError(f"device: {name} declares no [mobile_base] table in its device.toml")
    return dict(spec.mobile_base)


def check_mobile_manipulator(device: Device) -> None:
    """Require coordinates [x_b, y_b, θ_b, arm...]: a base pose then at least one arm joint.

    Raises:
        InvalidInput: naming `device`, if its coordinates are not those.
    """
    if tuple(device.joint_names[:3]) != BASE_JOINTS or device.n < 4:
        raise InvalidInput(
            f"device: expected coordinates starting with {list(BASE_JOINTS)} and an arm, got {device.joint_names}"
        )


def wheel_jacobian(Jq: np.ndarray, P: np.ndarray) -> np.ndarray:
    """J = [J_b P, J_m] from the generalized Jacobian J_q = [J_b, J_m] (thesis eq. A.5 / B.2).

    Args:
        Jq: (..., m, n) Jacobian of the coordinates [x_b, y_b, θ_b, q_m].
        P: (..., 3, 4) base velocity map of `mecanum_map`.

    Returns:
        (..., m, 4 + n − 3) Jacobian of [wheel speeds; arm rates].
    """
    return np.concatenate([Jq[..., :3] @ P, Jq[..., 3:]], axis=-1)


def wmm_jacobian(device: Device, q, *, wheel_radius: float, half_length: float, half_width: float) -> np.ndarray:
    """WMM Jacobian J = [J_b P(q_b), J_m] (thesis eq. A.5 / B.2).

    Args:
        device: a mobile manipulator whose first three coordinates are
            [x_b, y_b, θ_b] (e.g. `rhi.device("wmm")`).
        q: (..., n) configuration (x_b, y_b, θ_b, q_m) [m, m, rad, rad].
        wheel_radius: wheel radius R [m] (`body_map`; `**wheel_geometry("wmm")` gives the bundled estimates).
        half_length: half the wheelbase l1 [m] (`body_map`).
        half_width: half the track l2 [m] (`body_map`).

    Returns:
        J: (..., m, 4 + n - 3) mapping [v_b; q̇_m] (wheel speeds [rad/s], arm rates [rad/s])
        to the end-effector velocity [m/s] in the world frame.
    """
    check_mobile_manipulator(device)
    Jq = device.jacobian(q)
    q = np.asarray(q, dtype=float)
    P = mecanum_map(q[..., 2], wheel_radius=wheel_radius, half_length=half_length, half_width=half_width)
    return wheel_jacobian(Jq, P)
