"""Performance measures of manipulators and haptic interfaces as pure functions on arrays.

Every function takes Jacobians ``J`` of shape ``(..., m, n)`` (and inertia matrices,
directions and limits with matching leading axes) and broadcasts over the leading
axes. Bad input raises an `rhi.errors` error naming the argument; no function returns
NaN. A symmetric PSD matrix ``A`` stands for the ellipsoid ``xᵀA⁻¹x <= 1`` (semi-axes
``sqrt(eig(A))``).
"""

from rhi.metrics._common import SINGULAR_RTOL
from rhi.metrics.ellipsoids import (
    directional_manipulability,
    effective_manipulability,
    ellipsoid_axes,
    force_ellipsoid,
    isotropy,
    log_det_gradient,
    manipulability,
    reflected_friction,
    velocity_ellipsoid,
    velocity_transmission,
)
from rhi.metrics.force import max_force, max_force_scaling
from rhi.metrics.global_index import global_index
from rhi.metrics.inertia import apparent_inertia, effective_inertia
from rhi.metrics.inverses import dynamic_pinv, nullspace_projector, velocity_nullspace_projector, weighted_pinv
from rhi.metrics.limits import joint_limit_penalty, penalized_jacobian
from rhi.metrics.spd import desired_fme, desired_vme, jbld
from rhi.metrics.summary import Measures, measure_all
from rhi.metrics.teleop import joint_energy, teleoperation_ellipsoid, tmi

__all__ = [
    "Measures",
    "SINGULAR_RTOL",
    "apparent_inertia",
    "desired_fme",
    "desired_vme",
    "directional_manipulability",
    "dynamic_pinv",
    "effective_inertia",
    "effective_manipulability",
    "ellipsoid_axes",
    "force_ellipsoid",
    "global_index",
    "isotropy",
    "jbld",
    "joint_energy",
    "joint_limit_penalty",
    "log_det_gradient",
    "manipulability",
    "max_force",
    "max_force_scaling",
    "measure_all",
    "nullspace_projector",
    "penalized_jacobian",
    "reflected_friction",
    "teleoperation_ellipsoid",
    "tmi",
    "velocity_ellipsoid",
    "velocity_nullspace_projector",
    "velocity_transmission",
    "weighted_pinv",
]
