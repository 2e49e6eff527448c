"""Beyond the thesis (§8.2): spatial RHIs — Remarks I and II in 3-D and force capability along 3-D directions.

Two spatial redundant haptic interfaces with a 3-D position task (m = 3):

- ``srhi5``: rhi4's rehabilitation robot carrying the 3-DoF PHANToM upright (n = 5,
  models/srhi5/README.md); its non-redundant sub-chain is ``srhi5_phantom`` (the PHANToM on
  the locked base, q1 = q2 = 0), as rhi4's ``phantom`` is for rhi4 (§3.5).
- ``gen3`` used as a haptic interface (n = 7); its sub-chain is the 3-DoF arm (q1, q2, q4)
  with q3 = q5 = q6 = q7 = 0 locked (a design choice: the anthropomorphic shoulder–elbow arm).

Remarks I and II (§3.4): an RHI configured by VME matching along u (eq. 3.22, β = 0.01)
has an effective manipulability ρ (eq. 3.6) at least, and an effective apparent inertia Λ
(eq. 3.13) at most, that of its non-redundant sub-chain at the same point. The common
workspace is sampled by a grid over the sub-chain's joint box (every point is reached by
the sub-chain, hence by the RHI with its extra joints locked); the RHI starts from that
embedded configuration and SLSQP minimises eq. 3.22 within its joint limits
(`rhi.control.configuration.optimal_configuration`).

Force capability (ch. 7): at seeded configurations and seeded random unit directions, the
largest force along u rendered by simple scaling (§6.3.1), by ASCM (Algorithm 1) and the
LP optimum (`rhi.metrics.max_force`, dynamic J#), all with m = 3
(`rhi.control.allocation.force_capability`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np

from rhi.control import VMEMatching
from rhi.control.configuration import optimal_configuration
from rhi.design.executors import parallel_map
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress, capabilities
from rhi.metrics import effective_inertia, effective_manipulability, force_ellipsoid, velocity_ellipsoid

BETA = 0.01
U = (0.0, 1.0, 0.0)
DEVICES = ("srhi5", "gen3")
#: gen3's sub-chain: locked joints [rad] (design choice, module docstring)
GEN3_LOCK = {"q3": 0.0, "q5": 0.0, "q6": 0.0, "q7": 0.0}
#: sub-chain joint boxes sampled for the common workspace [rad] (finite where the device has none)
GRID_BOX = {"srhi5": ((-1.2, -0.8, -0.2), (1.2, 1.8, 1.2)), "gen3": ((-1.2, -1.4, 0.4), (1.2, 1.4, 2.2))}


def pair(name: str) -> tuple[Device, Device, Callable[[np.ndarray], np.ndarray]]:
    """(RHI, non-redundant sub-chain, embedding q_sub (3,) -> q_RHI (n,)) for "srhi5" or "gen3"."""
    if name == "srhi5":
        return device("srhi5"), device("srhi5_phantom"), lambda q: np.r_[0.0, 0.0, q]
    if name == "gen3":
        g = device("gen3")
        sub = g.lock(GEN3_LOCK, name="gen3_3dof")
        return g, sub, lambda q: np.array([q[0], q[1], 0.0, q[2], 0.0, 0.0, 0.0])
    raise InvalidInput(f"name: expected one of {DEVICES}, got {name!r}")


@functools.lru_cache(maxsize=4)
def _pair_cached(name: str):
    return pair(name)


def chain_points(dev: Device, q: np.ndarray) -> np.ndarray:
    """Joint positions on the path from the base to the end effector, then the end effector: (k, 3) [m].

    `Device.skeleton` without the side branches (srhi5's parallelogram crank and coupler), for drawing.
    """
    model = dev.model
    fr = model.frames[dev.ee_frame_id]
    j = fr.parentJoint if hasattr(fr, "parentJoint") else fr.parent
    path = sorted(set(model.supports[j]) - {0})
    sk = dev.skeleton(q)
    return np.vstack([sk[[i - 1 for i in path]], sk[-1:]])


def measures(dev: Device, q: np.ndarray, u: np.ndarray) -> tuple[float, float]:
    """(ρ [m/s per rad/s], Λ [kg]) of `dev` at q along u (eqs. 3.6, 3.13)."""
    J = dev.jacobian(q)
    return float(effective_manipulability(J, u)), float(effective_inertia(J, dev.mass_matrix(q), u))


def grid_configurations(name: str, resolution: int) -> np.ndarray:
    """(k, 3) sub-chain configurations [rad] on a resolution³ grid of its box, within its limits."""
    _, sub, _ = _pair_cached(name)
    lo, hi = (np.array(v) for v in GRID_BOX[name])
    lo, hi = np.maximum(lo, sub.q_min), np.minimum(hi, sub.q_max)
    axes = [np.linspace(a, b, resolution) for a, b in zip(lo, hi)]
    Q = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return Q[sub.within_limits(Q)]


def _remark_point(q_sub: np.ndarray, *, name: str, u: tuple[float, ...]) -> tuple[float, ...]:
    """(x, y, z, ρ_RHI, ρ_sub, Λ_RHI, Λ_sub, q_RHI…) at the point the sub-chain reaches at q_sub."""
    rhi_dev, sub, embed = _pair_cached(name)
    uu = np.asarray(u, dtype=float)
    x = sub.fk(q_sub)
    q = optimal_configuration(rhi_dev, x, VMEMatching(u, BETA), embed(q_sub))  # the embedded start reaches x
    r1, l1 = measures(rhi_dev, q, uu)
    r0, l0 = measures(sub, q_sub, uu)
    return (*x, r1, r0, l1, l0, *q)


@checked
def spatial_remarks(
    resolution: int = 7,
    u: tuple[float, float, float] = U,
    devices: tuple[str, ...] = DEVICES,
    progress: Progress | None = None,
    *,
    executor=None,
    workers: int | None = None,
) -> Result:
    """Remarks I and II in 3-D: ρ and Λ of each spatial RHI vs its sub-chain over the common workspace.

    Args:
        resolution: grid nodes per sub-chain joint (points = resolution³ within the limits).
        u: (3,) direction of motion (thesis §3.5: [0, 1] in the plane; here [0, 1, 0]).
        devices: any of "srhi5", "gen3".
        progress: callback(done, total) in grid points.
        executor: where the points run (`rhi.design.executors`; identical results).
        workers: processes of the local pool.

    Returns:
        Result with, per device, arrays ``{dev}_points`` (k, 3) [m], ``{dev}_rho_ratio``,
        ``{dev}_lambda_ratio`` (k,), ``{dev}_q`` (k, n) and the fraction of points where each remark holds.
    """
    if not isinstance(resolution, (int, np.integer)) or resolution < 2:
        raise InvalidInput(f"resolution: expected an integer >= 2, got {resolution!r}")
    uu = np.asarray(u, dtype=float)
    if uu.shape != (3,) or not np.all(np.isfinite(uu)) or np.linalg.norm(uu) == 0:
        raise InvalidInput(f"u: expected a non-zero finite (3,) direction, got {u!r}")
    u = tuple((uu / np.linalg.norm(uu)).tolist())
    for d in devices:
        if d not in DEVICES:
            raise InvalidInput(f"devices: unknown {d!r}; expected a subset of {DEVICES}")
    grids = {d: grid_configurations(d, resolution) for d in devices}
    items = [(d, q) for d in devices for q in grids[d]]
    out = parallel_map(_remark_item, [(d, tuple(q), u) for d, q in items], executor=executor, workers=workers,
                       progress=progress)
    arrays: dict[str, np.ndarray] = {"u": np.array(u)}
    rows: list[Row] = []
    k = 0
    for d in devices:
        vals = np.array(out[k:k + len(grids[d])])
        k += len(grids[d])
        pts, rho1, rho0, lam1, lam0, q = vals[:, :3], vals[:, 3], vals[:, 4], vals[:, 5], vals[:, 6], vals[:, 7:]
        rr, lr = rho1 / rho0, lam1 / lam0
        ok = np.isfinite(rr) & np.isfinite(lr)
        arrays.update({f"{d}_points": pts, f"{d}_rho_ratio": rr, f"{d}_lambda_ratio": lr, f"{d}_q": q,
                       f"{d}_q_sub": grids[d]})
        sub_name = _pair_cached(d)[1].name
        rows += [
            Row(f"{d}: points of the common workspace", None, float(ok.sum())),
            Row(f"{d}: fraction with ρ_RHI ≥ ρ_{sub_name} (Remark I)", None, float(np.mean(rr[ok] >= 1 - 1e-9))),
            Row(f"{d}: fraction with Λ_RHI ≤ Λ_{sub_name} (Remark II)", None, float(np.mean(lr[ok] <= 1 + 1e-9))),
            Row(f"{d}: median ρ ratio", None, float(np.median(rr[ok]))),
            Row(f"{d}: min ρ ratio", None, float(np.min(rr[ok]))),
            Row(f"{d}: median Λ ratio", None, float(np.median(lr[ok]))),
            Row(f"{d}: max Λ ratio", None, float(np.max(lr[ok]))),
        ]
    return Result(
        "beyond.spatial_remarks",
        f"Beyond the thesis: spatial RHIs — Remarks I and II in 3-D along u = {np.round(u, 3).tolist()}",
        [Table("Remarks I and II over the common workspace (RHI at its VME optimum, eq. 3.22, β = 0.01)", rows)],
        arrays,
        ["Not in the thesis (§8.2 future work). The common workspace is a grid over the sub-chain's joint box; "
         "the RHI starts from the sub-chain's configuration (extra joints at their locked values) and SLSQP "
         "minimises eq. 3.22 within its joint limits.",
         "VME matching does not maximise ρ or minimise Λ; the remarks are checked, not built in. Λ uses the "
         "documented inertial models (models/srhi5, models/gen3).",
         "gen3's sub-chain locks q3 = q5 = q6 = q7 = 0 (a shoulder–elbow arm); srhi5's locks the rehab base."],
    )


def _remark_item(item: tuple[str, tuple[float, ...], tuple[float, ...]]) -> tuple[float, ...]:
    name, q_sub, u = item
    return _remark_point(np.array(q_sub), name=name, u=u)


@checked
def spatial_force_capability(
    configurations: int = 20,
    directions: int = 50,
    devices: tuple[str, ...] = DEVICES,
    seed: int = 15,
    progress: Progress | None = None,
) -> Result:
    """F_max along seeded random 3-D directions: simple scaling vs ASCM (Algorithm 1) vs the LP optimum.

    Args:
        configurations: seeded configurations per device (uniform in the joint box, within its limits).
        directions: seeded unit directions per configuration (uniform on the sphere).
        devices: any of "srhi5", "gen3".
        seed: NumPy generator seed.
        progress: callback(done, total) in configurations.
    """
    for nm, v in (("configurations", configurations), ("directions", directions)):
        if not isinstance(v, (int, np.integer)) or v < 1:
            raise InvalidInput(f"{nm}: expected an integer >= 1, got {v!r}")
    rng = np.random.default_rng(seed)
    arrays: dict[str, np.ndarray] = {}
    rows: list[Row] = []
    total, done = configurations * len(devices), 0
    for d in devices:
        dev = _pair_cached(d)[0]
        lo, hi = dev.torque_limits
        qlo = np.where(np.isfinite(dev.q_min), dev.q_min, -math.pi)
        qhi = np.where(np.isfinite(dev.q_max), dev.q_max, math.pi)
        Q = np.empty((0, dev.n))
        while len(Q) < configurations:
            c = rng.uniform(qlo, qhi, size=(4 * configurations, dev.n))
            Q = np.vstack([Q, c[dev.within_limits(c)]])
        Q = Q[:configurations]
        F = np.zeros((configurations, directions, 3))
        Us = rng.normal(size=(configurations, directions, 3))
        Us /= np.linalg.norm(Us, axis=-1, keepdims=True)
        for i, q in enumerate(Q):
            J, M = dev.jacobian(q), dev.mass_matrix(q)
            for k, u in enumerate(Us[i]):
                F[i, k] = capabilities(J, u, torque_min=lo, torque_max=hi, M=M)
            done += 1
            if progress is not None:
                progress(done, total)
        fs, fa, fl = F[..., 0].ravel(), F[..., 1].ravel(), F[..., 2].ravel()
        arrays.update({f"{d}_q": Q, f"{d}_u": Us, f"{d}_fmax": F})
        rows += [
            Row(f"{d}: median F_max, simple scaling", None, float(np.median(fs)), "N"),
            Row(f"{d}: median F_max, ASCM", None, float(np.median(fa)), "N"),
            Row(f"{d}: median F_max, LP optimum", None, float(np.median(fl)), "N"),
            Row(f"{d}: median gain ASCM / scaling", None, float(np.median(fa / fs)), ""),
            Row(f"{d}: median ASCM / LP optimum", None, float(np.median(fa / fl)), ""),
            Row(f"{d}: fraction of cases with ASCM ≥ 99 % of the LP optimum", None, float(np.mean(fa >= 0.99 * fl))),
            Row(f"{d}: worst ASCM / LP optimum", None, float(np.min(fa / fl)), ""),
        ]
    return Result(
        "beyond.spatial_force_capability",
        "Beyond the thesis: spatial RHIs — force capability along random 3-D directions (scaling, ASCM, LP)",
        [Table(f"F_max over {configurations} configurations × {directions} directions per device", rows)],
        arrays,
        ["Static capability from the torque limits (device.toml): scaling keeps τ = α Jᵀ F u; ASCM (Algorithm 1) "
         "holds saturated joints and redistributes in the null space; the LP is the optimum over all null-space "
         "torques (dynamic J#). ASCM is evaluated over a ramp of requests up to 1.5× the LP optimum "
         "(`rhi.control.allocation.force_capability`)."],
    )


@checked
def spatial_ellipsoids(name: str = "srhi5", x=None, u: tuple[float, float, float] = U) -> Result:
    """A configuration of a spatial RHI and its sub-chain at one point with their velocity and force ellipsoids.

    Args:
        name: "srhi5" or "gen3".
        x: (3,) point [m]; default: the sub-chain's grid centre.
        u: (3,) direction of the VME matching.
    """
    rhi_dev, sub, embed = _pair_cached(name)
    lo, hi = (np.array(v) for v in GRID_BOX[name])
    q_sub = 0.5 * (np.maximum(lo, sub.q_min) + np.minimum(hi, sub.q_max))
    if x is not None:
        q_sub = sub.ik(np.asarray(x, dtype=float), q_sub)
    x = sub.fk(q_sub)
    uu = np.asarray(u, dtype=float) / np.linalg.norm(u)
    q = optimal_configuration(rhi_dev, x, VMEMatching(tuple(uu), BETA), embed(q_sub))
    arrays = {"x": x, "u": uu, "q": q, "q_sub": q_sub, "skeleton": chain_points(rhi_dev, q),
              "skeleton_sub": chain_points(sub, q_sub)}
    rows = []
    for tag, dev, qq in (("RHI", rhi_dev, q), ("sub-chain", sub, q_sub)):
        J = dev.jacobian(qq)
        arrays[f"vme_{tag}"] = velocity_ellipsoid(J)
        arrays[f"fme_{tag}"] = force_ellipsoid(J, dev.torque_max)
        r, lam = measures(dev, qq, uu)
        rows += [Row(f"ρ along u, {tag}", None, r, "m/s"), Row(f"Λ along u, {tag}", None, lam, "kg")]
    return Result(
        "beyond.spatial_ellipsoids",
        f"Beyond the thesis: spatial RHIs — {name} at {np.round(x, 3).tolist()} m with its ellipsoids",
        [Table("At the drawn configuration", rows)],
        arrays,
        ["Velocity ellipsoid JJᵀ and torque-weighted force ellipsoid (J W² Jᵀ)⁻¹ (eq. 6.9) of the RHI at its VME "
         "optimum and of the sub-chain at the same point."],
    )
