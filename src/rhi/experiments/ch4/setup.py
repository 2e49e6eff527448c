"""The §4.4 set-up: the design problems, constants, and the figure data of a design (ellipses, TMI map, energy).

See `rhi.experiments.ch4` for the choices the thesis leaves open.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Any

import numpy as np

from rhi import thesis as T
from rhi.design import (
    DesignProblem,
    Phantom3Master,
    Solution,
    Workspace,
    penalize,
    rectangle,
    slave_solution,
    sweep,
)
from rhi.design.executors import DEFAULTS
from rhi.errors import InvalidInput
from rhi.metrics import joint_energy as _joint_energy, teleoperation_ellipsoid, tmi, velocity_ellipsoid

XLIM = (0.324, 0.524)
YLIM = (-0.1, 0.1)
CENTER = (0.424, 0.0)
A, B = (0.424, -0.1), (0.424, 0.1)
SPEED = 0.01
K_Q = 1.0
K1, K2 = 1.0, 20.0
SLAVE_Q0 = np.deg2rad([40.0, 30.0])
BOUNDS = {"l2": (0.165, 0.365), "theta_z": (-np.pi / 2, np.pi / 2), "z_ph": (-0.54, 0.19)}
FIXED_ROUND1 = {"l2": 0.165, "z_ph": 0.0539}
#: The designs of Fig. 4.7, in the order of the arrays energy_0 … energy_3.
ENERGY_LABELS = ("θz only, C1", "θz only, C2", "l2, θz, Z_PH, C1", "l2, θz, Z_PH, C2")
ELLIPSE_POINTS = np.array([(x, y) for x in (0.374, 0.474) for y in (-0.067, 0.0, 0.067)])

#: §4.4 first round (D = {θz}).
THESIS_THETA, THESIS_GMT, THESIS_GMM = T.THETA_Z, T.GM_T_ROUND1, T.GM_M_ROUND1
#: Table 4.1 (D = {l2, θz, Z_PH}).
THESIS_TABLE = T.TABLE_4_1

#: The smallest K2/K1 for which Table 4.1's C2 design beats its C1 design on C2 (eq. 4.24): ≈ 11.46.
K2_MIN_TABLE_4_1 = ((THESIS_TABLE["C1"]["GC_M"] - THESIS_TABLE["C2"]["GC_M"])
                    / (THESIS_TABLE["C2"]["GM_T"] - THESIS_TABLE["C1"]["GM_T"]))



def problem(
    design: str = "theta_z",
    *,
    density: float = 100.0,
    kind: str = "grid",
    k_q: float | None = K_Q,
    K2: float = K2,
    xlim: tuple[float, float] = XLIM,
    ylim: tuple[float, float] = YLIM,
    r0: float | str = "auto",
) -> DesignProblem:
    """The §4.4 design problem: ``design`` = "theta_z" (first round) or "full" (D = {l2, θz, Z_PH})."""
    try:
        ws, slave = _sampled(tuple(map(float, xlim)), tuple(map(float, ylim)), float(density), kind)
    except (TypeError, ValueError):  # not a pair of numbers, an unhashable kind: rectangle names the argument
        ws, slave = _sampled.__wrapped__(xlim, ylim, density, kind)
    center = (0.5 * (xlim[0] + xlim[1]), 0.5 * (ylim[0] + ylim[1]))
    if design == "theta_z":
        bounds, fixed = {"theta_z": BOUNDS["theta_z"]}, dict(FIXED_ROUND1)
    elif design == "full":
        bounds, fixed = dict(BOUNDS), {}
    else:
        raise InvalidInput(f"design: expected 'theta_z' or 'full', got {design!r}")
    return DesignProblem(Phantom3Master(), ws, slave, center, r0, bounds, fixed, k_q=k_q, K1=K1, K2=K2)


@functools.lru_cache(maxsize=16)
def _sampled(xlim, ylim, density, kind) -> tuple[Workspace, Solution]:
    """The workspace samples and the slave's IK at them (400 IK solves at 100 /m).

    They do not depend on the design, K2, k_q or r0, so the problems of one sweep (`sensitivity`'s
    variants, the K2 scan) share them: cached.
    """
    ws = rectangle(xlim, ylim, density=density, kind=kind)
    return ws, slave_solution("rehab_slave", ws.points, SLAVE_Q0)


def checkpoint(checkpoint_dir: str | Path | None, name: str) -> str | None:
    """The checkpoint file `name`.json in `checkpoint_dir` (default: the executors' default folder), or None."""
    checkpoint_dir = checkpoint_dir or DEFAULTS["checkpoint_dir"]
    return None if checkpoint_dir is None else str(Path(checkpoint_dir) / f"{name}.json")


def ellipses(prob: DesignProblem, x, points: np.ndarray = ELLIPSE_POINTS) -> dict[str, np.ndarray]:
    """Penalized master ME, slave ME and TME at slave points (k, 2): each (k, 2, 2), plus λ (k,)."""
    sub = dataclasses.replace(prob, workspace=dataclasses.replace(prob.workspace, points=np.asarray(points),
                                                                  weights=np.ones(len(points))),
                              slave=slave_solution("rehab_slave", points, SLAVE_Q0))
    sol = sub.solve(x)
    Jm = penalize(sol.J, sol.q, sol.q_min, sol.q_max, prob.k_q)
    Js = penalize(sub.slave.J, sub.slave.q, sub.slave.q_min, sub.slave.q_max, prob.k_q)
    return {"master": velocity_ellipsoid(Jm), "slave": velocity_ellipsoid(Js),
            "tme": teleoperation_ellipsoid(Jm, Js), "tmi": tmi(Jm, Js), "ok": sol.ok & sub.slave.ok}


def tmi_map(prob: DesignProblem, x) -> np.ndarray:
    """λ (eq. 4.17) at every workspace sample of `prob` for design x: (N,), 0 where unreachable."""
    sol = prob.solve(x)
    Jm = penalize(sol.J, sol.q, sol.q_min, sol.q_max, prob.k_q)
    Js = penalize(prob.slave.J, prob.slave.q, prob.slave.q_min, prob.slave.q_max, prob.k_q)
    ok = sol.ok & prob.slave.ok
    return np.where(ok, tmi(np.where(ok[:, None, None], Jm, 0), np.where(ok[:, None, None], Js, 0)), 0.0)


def energy_along_task(prob: DesignProblem, x, n: int = 41, *, axes_squared: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """‖q̇‖² (eq. 4.21–4.22) moving the slave from A to B at ẏ = 0.01 m/s: (t [s], energy), each (n,).

    axes_squared: Λ_T = diag(σ²) (eq. 4.21's (J_T J_Tᵀ)⁻¹) instead of eq. 4.22's printed diag(σ) (`joint_energy`).
    """
    y = np.linspace(A[1], B[1], n)
    pts = np.column_stack([np.full(n, A[0]), y])
    e = ellipses(prob, x, pts)
    xdot = np.tile([0.0, SPEED], (n, 1))
    en = np.where(e["ok"], _joint_energy(e["tme"], xdot, axes_squared=axes_squared), np.nan)
    return (y - A[1]) / SPEED, en


def mirror(prob: DesignProblem, x) -> np.ndarray:
    """Design x with θz negated (the mirror image under which C1 is invariant, module docstring)."""
    x = np.array(x, dtype=float)
    names = prob.names
    if "theta_z" in names:
        x[names.index("theta_z")] *= -1.0
    return x


def gmt_vs_l2(
    prob: DesignProblem, l2s=(0.165, 0.215, 0.265, 0.315, 0.365), *, step_deg: float = 10.0, z_step: float = 0.02,
    executor=None,
) -> dict[str, np.ndarray]:
    """Best GM_T over a (θz, Z_PH) grid of the bounds at each l2: why C2 favours a long link in our set-up.

    Args:
        prob: a "full" problem (its θz and Z_PH bounds span the grid).
        l2s: (k,) link lengths [m].
        step_deg: grid step in θz [deg].
        z_step: grid step in Z_PH [m].
        executor: evaluates the grid.

    Returns:
        {"l2": (k,), "GM_T": (k,) grid maxima, "theta_z": (k,) [rad], "z_ph": (k,) [m] where they occur,
        "GC_M": (k,), "GM_M": (k,) there}.
    """
    (t0, t1), (z0, z1) = prob.bounds["theta_z"], prob.bounds["z_ph"]
    th = np.deg2rad(np.arange(np.rad2deg(t0), np.rad2deg(t1) + 1e-9, step_deg))
    zs = np.arange(z0, z1 + 1e-12, z_step)
    out: dict[str, list[float]] = {k: [] for k in ("l2", "GM_T", "theta_z", "z_ph", "GC_M", "GM_M")}
    names = prob.names
    for l2 in l2s:
        xs: list[Any] = []  # design vectors (NumPy rows) for `sweep`
        for t in th:
            for z in zs:
                x = np.empty(len(names))
                x[names.index("l2")], x[names.index("theta_z")], x[names.index("z_ph")] = l2, t, z
                xs.append(x)
        res = sweep(prob, xs, executor=executor)
        i = int(np.argmax([r["GM_T"] for r in res]))
        for k, v in (("l2", l2), ("GM_T", res[i]["GM_T"]), ("theta_z", xs[i][names.index("theta_z")]),
                     ("z_ph", xs[i][names.index("z_ph")]), ("GC_M", res[i]["GC_M"]), ("GM_M", res[i]["GM_M"])):
            out[k].append(float(v))
    return {k: np.array(v) for k, v in out.items()}

