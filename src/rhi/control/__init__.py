"""Control: objectives (cost + analytic gradient), primary laws, saturation handling, the null-space controller."""

from rhi.control.allocation import (
    Allocation,
    AllocationMethod,
    Allocator,
    allocate_active_set,
    allocate_lp,
    allocate_none,
    allocate_scaling,
    allocation_method,
    ascm,
    ascm_projector,
    force_capability,
)
from rhi.control.barrier import JointLimitBarrier
from rhi.control.controller import (
    ControllerConfig,
    ControllerState,
    NullSpaceController,
    ZeroTorque,
    output_force,
)
from rhi.control.manipulability import Manipulability, TMIMatching
from rhi.control.objectives import (
    EllipsoidMatching,
    FMEMatching,
    Objective,
    ObjectiveTerm,
    VMEMatching,
    WeightedSum,
    desired_fme_free,
    desired_fme_stiff,
    fme_shape,
    gradient_function,
)
from rhi.control.passivity import Passivity, PassivityController, PassivityState
from rhi.control.primary import (
    ForceRendering,
    ImpedanceControl,
    JointFriction,
    PrimaryLaw,
    SpringPalpation,
    task_compensation,
)
from rhi.control.safety import held_part, safety_room
from rhi.control.saturation import (
    basis_from_projector,
    null_basis,
    null_projector,
    tertiary,
    tertiary_projector,
)
from rhi.control.schedule import FMESchedule, ScheduledObjective
from rhi.control.tank import NullSpaceTank, TankState
from rhi.control.transition import (
    TransitionConfig,
    TransitionState,
    aso_volume,
    hysteresis,
    transition_step,
)

__all__ = [
    "Allocation",
    "AllocationMethod",
    "Allocator",
    "ControllerConfig",
    "ControllerState",
    "EllipsoidMatching",
    "FMEMatching",
    "FMESchedule",
    "ForceRendering",
    "ImpedanceControl",
    "JointFriction",
    "JointLimitBarrier",
    "Manipulability",
    "NullSpaceController",
    "NullSpaceTank",
    "Objective",
    "ObjectiveTerm",
    "Passivity",
    "PassivityController",
    "PassivityState",
    "PrimaryLaw",
    "ScheduledObjective",
    "SpringPalpation",
    "TMIMatching",
    "TankState",
    "TransitionConfig",
    "TransitionState",
    "VMEMatching",
    "WeightedSum",
    "ZeroTorque",
    "allocate_active_set",
    "allocate_lp",
    "allocate_none",
    "allocate_scaling",
    "allocation_method",
    "ascm",
    "ascm_projector",
    "aso_volume",
    "basis_from_projector",
    "desired_fme_free",
    "desired_fme_stiff",
    "fme_shape",
    "force_capability",
    "gradient_function",
    "held_part",
    "hysteresis",
    "null_basis",
    "null_projector",
    "output_force",
    "safety_room",
    "task_compensation",
    "tertiary",
    "tertiary_projector",
    "transition_step",
]
