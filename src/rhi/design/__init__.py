"""Design optimisation of a haptic interface against a slave robot (thesis chapter 4).

* `workspace`: explicit samplings of the slave workspace (grid / Sobol', density).
* `indices`: GM, GC (eqs. 4.8, 4.10) and GM_T (eq. 4.18) with the penalized Jacobian (4.19–4.20).
* `kinematics`: HI models (closed-form phantom3, any bundled device), the slave's IK, declared bounds.
* `cost`: `DesignProblem`, `evaluate`, C1 and C2 (eqs. 4.23, 4.24), bound checks.
* `planar`: the compiled one-pass GM, GC, GM_T of a planar pair (what `evaluate` runs).
* `optimize`: seeded differential evolution + Nelder–Mead refinement, `sweep`.
* `executors`: serial, local process pool, Ray — one ``map``/``imap`` interface; `parallel_map` for maps.
* `checkpoint`: resumable evaluation cache.
"""

from rhi.design.checkpoint import EvalCache
from rhi.design.cost import DesignProblem, check_bounds, cost, evaluate, evaluate_strict
from rhi.design.executors import PoolExecutor, RayExecutor, SerialExecutor, make_executor, parallel_map, using
from rhi.design.indices import device_indices, penalize, teleoperation_index
from rhi.design.kinematics import DeviceMaster, Phantom3Master, Solution, declared_bounds, slave_solution
from rhi.design.optimize import Optimum, optimize, sweep
from rhi.design.workspace import Workspace, annulus, rectangle

__all__ = [
    "DesignProblem", "DeviceMaster", "EvalCache", "Optimum", "Phantom3Master", "PoolExecutor", "RayExecutor",
    "SerialExecutor", "Solution", "Workspace", "annulus", "check_bounds", "cost", "declared_bounds",
    "device_indices", "evaluate", "evaluate_strict", "make_executor", "optimize", "parallel_map", "penalize",
    "rectangle", "slave_solution", "sweep", "teleoperation_index", "using",
]
