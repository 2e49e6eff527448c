"""Fig. 6.10: F_max along u with the M_Stiff^des configuration over that with the M_Free^des one, over rhi4's workspace."""

from __future__ import annotations

import functools

import numpy as np

from rhi.control import WeightedSum
from rhi.design.executors import parallel_map
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput, Unreachable
from rhi.experiments.arguments import checked
from rhi.experiments.ch6.setup import (
    MAP_X,
    MAP_Y,
    Q_HOME,
    U,
    best_match,
    controller_terms,
    desired_fmes,
    start_configurations,
)
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress
from rhi.metrics import effective_inertia, max_force, max_force_scaling

_DEV: dict[str, Device] = {}


def _rhi4() -> Device:
    if "rhi4" not in _DEV:
        _DEV["rhi4"] = device("rhi4")
    return _DEV["rhi4"]


def _ratio_row(y: float, xs: np.ndarray, starts: int, limits: bool) -> np.ndarray:
    """(8, len(xs)): F_max by scaling and LP, Λ and the matched cost ν (free, stiff) along the grid row at height y [m].

    Every point is matched independently from the same deterministic starts (`best_match`),
    so a row's values do not depend on which process computes it. NaN where unreachable.
    """
    dev = _rhi4()
    lo, hi = dev.torque_limits
    u = np.array(U)
    _, _, Mf, Ms = _desired_rhi4()
    objs = [WeightedSum(controller_terms(D, hi, limits=limits)) for D in (Mf, Ms)]
    out = np.full((8, len(xs)), np.nan)
    for i, x in enumerate(xs):
        try:
            qs = start_configurations(dev, (x, y), starts)
        except Unreachable:
            continue
        for c, obj in enumerate(objs):
            try:
                q = best_match(dev, (x, y), obj, starts=qs)
            except Unreachable:
                break
            J, M = dev.jacobian(q), dev.mass_matrix(q)
            if np.linalg.svd(J, compute_uv=False)[-1] < 1e-3:
                break
            out[c, i] = max_force_scaling(J, u, torque_min=lo, torque_max=hi)
            out[2 + c, i] = max_force(J, u, torque_min=lo, torque_max=hi, M=M)
            out[4 + c, i] = effective_inertia(J, M, u)
            out[6 + c, i] = obj.value(dev, q)
        else:
            continue
        out[:, i] = np.nan
    return out


@functools.lru_cache(maxsize=1)
def _desired_rhi4() -> tuple[float, float, np.ndarray, np.ndarray]:
    """`desired_fmes` of rhi4 for u = [0, 1] from the home configuration, once per process."""
    return desired_fmes(_rhi4(), np.array(U), Q_HOME)


@checked
def fmax_ratio_map(
    resolution: int = 25,
    progress: Progress | None = None,
    *,
    starts: int = 2,
    limits: bool = True,
    executor=None,
    workers: int | None = None,
) -> Result:
    """Fig. 6.10: F_max along u = [0, 1] with the M_Stiff^des configuration over that with the M_Free^des one.

    At each grid point of x ∈ [0.25, 0.75] m, y ∈ [−0.5, 0.3] m, rhi4's configuration is
    FME-matched (`best_match`, the palpation controller's cost) to M_Free^des and to
    M_Stiff^des, and F_max along u is evaluated at both by force scaling (the ch. 6
    controller) and by the LP with null-space torques. Rows go through
    `rhi.design.executors.parallel_map` (one row per task), so the map is bit-identical on
    every executor.

    Args:
        resolution: grid points per axis.
        progress: callback(done, total) in grid points, after each finished row.
        starts: starts per matching (`best_match`).
        limits: include the joint-limit barrier in the matched cost.
        executor: where to run (`rhi.design.executors.using`).
        workers: processes of the local pool.
    """
    if not isinstance(resolution, int) or resolution < 2:
        raise InvalidInput(f"resolution: must be an integer >= 2, got {resolution!r}")
    if not isinstance(starts, int) or starts < 1:
        raise InvalidInput(f"starts: must be an integer >= 1, got {starts!r}")
    xs = np.linspace(*MAP_X, resolution)
    ys = np.linspace(*MAP_Y, resolution)
    fn = functools.partial(_ratio_row, xs=xs, starts=starts, limits=limits)
    rows = parallel_map(fn, list(ys), executor=executor, workers=workers, progress=progress,
                        units=[resolution] * resolution)
    data = np.stack(rows, axis=1)  # (8, ny, nx)
    fs_free, fs_stiff, lp_free, lp_stiff, lam_free, lam_stiff, nu_free, nu_stiff = data
    ratio = fs_stiff / fs_free
    ratio_lp = lp_stiff / lp_free
    ok = np.isfinite(ratio)

    def stat(fn_, a):
        return float(fn_(a)) if a.size else np.nan

    r, rl = ratio[ok], ratio_lp[ok]
    rows_out = [
        Row("grid points reached", None, float(ok.sum())),
        Row("fraction of points with F_max(M_Stiff) > F_max(M_Free), force scaling", None,
            stat(np.mean, r > 1.0), "", "thesis: larger 'over the entire workspace'"),
        Row("min ratio F_Stiff/F_Free, force scaling", None, stat(np.min, r)),
        Row("median ratio, force scaling", None, stat(np.median, r)),
        Row("max ratio, force scaling", None, stat(np.max, r)),
        Row("fraction of points with ratio > 1, LP with null-space torques", None, stat(np.mean, rl > 1.0)),
        Row("median ratio, LP", None, stat(np.median, rl)),
        Row("median Λ ratio Λ_Stiff/Λ_Free", None, stat(np.median, (lam_stiff / lam_free)[ok])),
        Row("median matched cost ν of M_Stiff^des (eq. 6.10 + barrier) over the points", None,
            stat(np.median, nu_stiff[ok])),
        Row("smallest matched cost ν of M_Stiff^des at the points where F_max(M_Stiff) ≤ F_max(M_Free)", None,
            stat(np.min, nu_stiff[ok][r <= 1.0]), "", "compare with the median: how well M_Stiff^des is matched there"),
    ]
    return Result(
        "ch6.fmax_ratio_map",
        "Fig. 6.10: F_max ratio M_Stiff^des vs M_Free^des configurations over rhi4's workspace, u = [0, 1]",
        [Table("Fig. 6.10 F_max ratio", rows_out)],
        {"x": xs, "y": ys, "ratio": ratio, "ratio_lp": ratio_lp, "fs_free": fs_free, "fs_stiff": fs_stiff,
         "lp_free": lp_free, "lp_stiff": lp_stiff, "lam_free": lam_free, "lam_stiff": lam_stiff,
         "nu_free": nu_free, "nu_stiff": nu_stiff},
        ["The thesis shows Fig. 6.10 as a map only; we report its extremes and the fraction of points "
         "where M_Stiff^des gives more force.",
         f"Configurations: `best_match` with {starts} start(s) per point, joint limits respected"
         + (", joint-limit barrier in the cost." if limits else ".")],
    )
