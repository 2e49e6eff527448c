"""MuJoCo's physics step callable from compiled code: `mj_step1` and `mj_step2` of the loaded MuJoCo.

The Python bindings' `mujoco.MjModel` / `mujoco.MjData` expose their C structs' addresses
(``model._address``, ``data._address``); compiled kernels pass those to `step1` / `step2`, the C
functions of the same ``libmujoco`` the bindings use, so a control period's physics steps run
without returning to Python. The arrays of a `MjData` (``sensordata``, ``xfrc_applied``,
``warning.number``, ...) are views of the same memory and read the new state after each step.
The library is made visible to Numba's linker once, at import, by its symbol names, which keeps
the kernels that call it in Numba's disk cache.

MuJoCo reports a diverging simulation through the warning counters (read them after a step, as
`rhi.sim.Plant.step` does); its fatal errors (e.g. an arena too small for the model) are C++
exceptions that cannot cross compiled code, so use these kernels with models whose arena
suffices (rhi's plants; a first step from Python shows it).
"""

from __future__ import annotations

import glob
import os

import mujoco
from llvmlite import binding
from numba import types

from rhi.errors import ModelError


def _library() -> str:
    """The path of the libmujoco shared library the Python bindings load."""
    here = os.path.dirname(mujoco.__file__)
    found = sorted(f for pattern in ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll")
                   for f in glob.glob(os.path.join(here, pattern)))
    if not found:  # pragma: no cover - a wheel without its library
        raise ModelError(f"mujoco: no libmujoco shared library beside {mujoco.__file__}")
    return found[0]


binding.load_library_permanently(_library())

#: mj_step1(const mjModel* m, mjData* d): positions and velocities of the new state (call after `step2`).
step1 = types.ExternalFunction("mj_step1", types.void(types.uintp, types.uintp))
#: mj_step2(const mjModel* m, mjData* d): accelerations, sensors and the integration of one timestep.
step2 = types.ExternalFunction("mj_step2", types.void(types.uintp, types.uintp))

__all__ = ["step1", "step2"]
