"""The controller's compiled kernels (Numba): the per-tick step and the allocation within the torque box.

`step.tick` is the whole tick after the primary law; `allocation` holds ASCM in projector form,
simple scaling, the safety room and the tertiary scaling, `lp` the active-set method on the LP, also used
on their own by `rhi.control.saturation` and the strategies of `rhi.control.allocation` (each names
the code of its branch in `step.tick`: NONE, SCALING, ASCM, ACTIVE_SET).
"""

from rhi.control._compiled.allocation import ascm, tertiary
from rhi.control._compiled.lp import active_set, active_set_result, active_set_start
from rhi.control._compiled.step import (
    ACTIVE_SET,
    ASCM,
    FALLBACK,
    N_PARAMS,
    NONE,
    OK,
    P_ASO_S,
    P_CLIPPED,
    P_DAMPING,
    P_DYNAMIC,
    P_GRAVITY,
    P_SAFE,
    P_SATURATION,
    SCALING,
    SINGULAR,
    ascm_ref,
    aso_volume,
    flags,
    schedule_vector,
    tick,
)

__all__ = [
    "ACTIVE_SET", "ASCM", "FALLBACK", "N_PARAMS", "NONE", "OK", "P_ASO_S", "P_CLIPPED", "P_DAMPING", "P_DYNAMIC",
    "P_GRAVITY", "P_SAFE", "P_SATURATION", "SCALING", "SINGULAR", "active_set", "active_set_result", "active_set_start",
    "ascm", "ascm_ref", "aso_volume", "flags", "schedule_vector", "tertiary", "tick",
]
