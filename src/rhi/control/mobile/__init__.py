"""Kinematic control of the wheeled mobile manipulator (thesis App. A and App. B).

Two families of controllers for a mobile base carrying a redundant arm, both written for
the bundled ``wmm`` (Kinova Gen3 on a Mecanum base, ``rhi.device("wmm")``) but valid for
any device whose first three coordinates are the base pose and whose chain is serial:

* `weighted` (App. A, velocity level): `WeightedDistributionController`, the weighted
  pseudoinverse with the adaptive motion-distribution weight γ (A.11–A.15) and the
  directional-manipulability enhancement (A.17–A.20).
* `amd` (App. B, acceleration level): `AMDController`, adaptive motion distribution by
  saturation in the null space (B.6–B.9), the tertiary singularity-avoidance objective
  (B.10–B.18) and the base stopping transition (B.20); `baselines`: the "traditional"
  `PinvAccelController` (§B.4.3).

Below them: `bounds` (joint bounds, local velocity/acceleration bounds, scalings),
`kinematics` (Jacobians and their derivatives, the O(m²) det-manipulability kernel),
`measures` (DM and det(J Jᵀ) with their derivatives, the readable references) and
`protocol` (`MobileController`, what `rhi.sim.mobile.simulate_mobile` drives).
"""

from rhi.control.mobile.amd import (
    AccelCommand,
    AccelControllerBase,
    AMDConfig,
    AMDController,
    AMDState,
    SNSResult,
    auxiliary_projection,
    auxiliary_projector,
    sns_acceleration,
    tertiary_acceleration,
)
from rhi.control.mobile.baselines import PinvAccelConfig, PinvAccelController
from rhi.control.mobile.bounds import (
    JointBounds,
    acceleration_bounds,
    base_stop_acceleration,
    joint_bounds,
    scale_factor,
    velocity_bounds,
)
from rhi.control.mobile.kinematics import (
    WMMKinematics,
    chain_jacobian_derivatives,
    det_terms,
)
from rhi.control.mobile.measures import (
    dm_cartesian_gradient,
    dm_gradient,
    dm_value,
    manipulability_det,
    manipulability_det_gradient,
    manipulability_det_hessian,
)
from rhi.control.mobile.protocol import MobileController, MobileStep
from rhi.control.mobile.weighted import (
    W_TAU_LIMITS,
    DMConfig,
    VelocityCommand,
    WeightedConfig,
    WeightedDistributionController,
    distribution_gamma,
    distribution_ratio,
    motion_weights,
    weighted_pinv_psd,
)

__all__ = [
    "W_TAU_LIMITS",
    "AMDConfig",
    "AMDController",
    "AMDState",
    "AccelCommand",
    "AccelControllerBase",
    "DMConfig",
    "JointBounds",
    "MobileController",
    "MobileStep",
    "PinvAccelConfig",
    "PinvAccelController",
    "SNSResult",
    "VelocityCommand",
    "WMMKinematics",
    "WeightedConfig",
    "WeightedDistributionController",
    "acceleration_bounds",
    "auxiliary_projection", "auxiliary_projector",
    "base_stop_acceleration",
    "chain_jacobian_derivatives",
    "det_terms",
    "distribution_gamma",
    "distribution_ratio",
    "dm_cartesian_gradient",
    "dm_gradient",
    "dm_value",
    "joint_bounds",
    "manipulability_det",
    "manipulability_det_gradient",
    "manipulability_det_hessian",
    "motion_weights",
    "scale_factor",
    "sns_acceleration",
    "tertiary_acceleration",
    "velocity_bounds",
    "weighted_pinv_psd",
]
