"""Table 6.1: M_x, Φ and F_max identified on the simulated rhi4 at the FME-matched configurations (§6.4).

The protocol is `rhi.experiments.identification` (the §3.5 one with a 5 cm run-up): the
ch. 6 null-space controller keeps matching the FME during the push (zero primary force). Null-space
torques satisfy J M⁻¹ Nᵀ τ = 0, so they do not change uᵀẍ and the identified M_x estimates Λ of
eq. 3.13, while Φ includes the null-space damping's effect on the joint velocities — as long as no
joint's torque is clipped: chapter 6's law as written (``null_space="clipped"``, the default) clips
each joint at its programmed limit, and a clipped null-space torque pushes the handle too.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from rhi import thesis as T
from rhi.control import ControllerConfig, ForceRendering, NullSpaceController, WeightedSum
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.ch6.setup import (
    CASES,
    K_D,
    Q_HOME,
    NullSpace,
    best_match,
    controller_terms,
    desired_fmes,
    match_fme,
)
from rhi.experiments.identification import TRIALS, U, case_arrays, fit_rows, identify_case, trial_forces
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress, projector_names
from rhi.metrics import max_force, max_force_scaling
from rhi.metrics.force import ProjectorKind

#: Table 6.1: (M_x [kg], Φ [N s/m], F_max [N]) at [0.5, 0.1] m.
THESIS_TABLE_6_1 = T.TABLE_6_1
#: Point of interest and start of the ch. 6 identification [m].
X_CH6 = (0.5, 0.1)
BEFORE_CH6 = 0.05
#: ch. 6: the handle passes [0.5, 0.1] m at up to 2 m/s after 5 cm of a 1.5 N push on a 0.04 kg
#: inertia, 1.5 mm per 1 kHz sample, so the window is wider [m].
WINDOW_CH6 = 0.01


def ch6_configurations(starts: int = 3) -> dict[str, np.ndarray]:
    """The rhi4 configurations at [0.5, 0.1] m set by FME matching to M_Free^des and M_Stiff^des.

    `rhi.experiments.ch6.setup.best_match` of the ch. 6 controller's null-space cost (FME matching,
    β = 20, plus the joint-limit barrier), exactly as `rhi.experiments.ch6.palpation` starts.

    Returns:
        {"free": (4,), "stiff": (4,)} [rad].
    """
    dev = device("rhi4")
    _, _, Mf, Ms = desired_fmes(dev, np.array(U), Q_HOME)
    out = {}
    for case, Md in (("free", Mf), ("stiff", Ms)):
        obj = WeightedSum(controller_terms(Md, dev.torque_max))
        out[case] = best_match(dev, np.array(X_CH6), obj, starts=starts)
    return out


def _ch6_controller(dev: Device, desired: np.ndarray, projector: ProjectorKind = "dynamic",
                    null_space: NullSpace = "clipped") -> Callable[[], NullSpaceController]:
    """Factory of the ch. 6 null-space controller with a zero primary force (sysid: nothing rendered).

    projector: "dynamic" (J#, eq. 5.9 as the thesis writes it) or "pseudoinverse" (J⁺).
    null_space: "clipped" (chapter 6's law as written, eqs. 6.2–6.6, like `rhi.experiments.ch6.palpation`) or
        "scaled" (chapter 7's Algorithm 2).
    """
    def make() -> NullSpaceController:
        cfg = ControllerConfig(primary=ForceRendering(damping=0.0, coriolis=False, gravity=False, passivity=None),
                               objectives=controller_terms(desired, dev.torque_max), damping=K_D,
                               saturation="scaling", projector=projector, null_space=null_space)
        return NullSpaceController(dev, cfg)

    return make


@checked
def sysid_table_6_1(
    trials: int = TRIALS,
    *,
    seed: int = 0,
    controller: str = "nullspace",
    window: float = WINDOW_CH6,
    starts: int = 3,
    cutoff_hz: float = 20.0,
    projectors: Sequence[ProjectorKind] = ("dynamic", "pseudoinverse"),
    null_space: NullSpace = "clipped",
    progress: Progress | None = None,
) -> Result:
    """Table 6.1: M_x, Φ and F_max along u at [0.5, 0.1] m for the FME-matched configurations of rhi4.

    The configurations at the point are `ch6_configurations`; each trial starts at rest at
    [0.5, 0.05] m at the FME-matched configuration of that start point (the null-space
    controller has converged there while the handle was placed), a constant force of
    0.5–1.5 N pushes along u, and the samples within ±window of [0.5, 0.1] m are fitted.
    F_max: `rhi.metrics.max_force` (LP with null-space torques, dynamic J#) and force
    scaling at the configuration of the point, signed like Table 6.1 (negative: along −u).

    Args:
        trials: trials per case (thesis: 10).
        seed: seed of the force magnitudes.
        controller: "nullspace" (the ch. 6 controller keeps matching the FME; zero primary
            force) or "off" (motors off).
        window: half-width of the position window [m].
        starts: starts of the FME matching (`rhi.experiments.ch6.setup.best_match`).
        cutoff_hz: low-pass cut-off [Hz].
        projectors: null-space projectors of the controller and of the F_max LP, each run in turn:
            "dynamic" (J#, the thesis's text) and/or "pseudoinverse" (J⁺). The first gives the
            array keys ``free_*``/``stiff_*``, the others ``free_pinv_*``/``stiff_pinv_*``. With
            ``controller="off"`` the projector only changes the F_max LP.
        null_space: the controller's law at the torque box: "clipped" (chapter 6 as written: each joint of
            τ_m + (I − JᵀJ#ᵀ)τ_S clipped at its limit, so a clipped null-space torque pushes the handle too) or
            "scaled" (chapter 7's Algorithm 2: the null-space torque stays in the null space).
        progress: callback(done, total) in trials.
    """
    if controller not in ("nullspace", "off"):
        raise InvalidInput(f"controller: expected 'nullspace' or 'off', got {controller!r}")
    if null_space not in ("clipped", "scaled"):
        raise InvalidInput(f"null_space: expected 'clipped' or 'scaled', got {null_space!r}")
    projectors = projector_names(projectors)
    dev = device("rhi4")
    u, x = np.array(U), np.array(X_CH6)
    x_start = x - BEFORE_CH6 * u
    forces = trial_forces(trials, seed)
    _, _, Mf, Ms = desired_fmes(dev, u, Q_HOME)
    desired = {"free": Mf, "stiff": Ms}
    q_point = ch6_configurations(starts)
    lo, hi = dev.torque_limits
    rows, arrays, rows_cmp = [], {"forces": forces, "u": u, "x": x}, []
    total = len(projectors) * 2 * len(forces)
    for j, proj in enumerate(projectors):
        tag = "J#" if proj == "dynamic" else "J⁺"
        cases = {}
        for k, case in enumerate(CASES):
            obj = WeightedSum(controller_terms(desired[case], hi))
            q_start = match_fme(dev, x_start, obj, q_point[case])
            factory = _ch6_controller(dev, desired[case], proj, null_space) if controller == "nullspace" else None
            done = (2 * j + k) * len(forces)
            cb = None if progress is None else (lambda i, n, done=done: progress(done + i, total))
            lab = ("M_Free^des" if case == "free" else "M_Stiff^des") + f" ({tag})"
            res = identify_case(dev, q_start, q_point[case], x, label=lab, forces=forces, u=u, window=window,
                                controller=factory, cutoff_hz=cutoff_hz, progress=cb)
            cases[case] = res
            mx, phi, fmax = THESIS_TABLE_6_1[case]
            rows += fit_rows(res, lab, mx, phi, "thesis: hardware identification (Table 6.1)")
            J, M = dev.jacobian(q_point[case]), dev.mass_matrix(q_point[case])
            f_lp = float(max_force(J, u, torque_min=lo, torque_max=hi, projector=proj,
                                   M=M if proj == "dynamic" else None))
            f_sc = float(max_force_scaling(J, u, torque_min=lo, torque_max=hi))
            rows += [
                Row(f"F_max along u, {lab}: rhi.metrics.max_force (LP, null-space torques)", fmax, -f_lp, "N",
                    "static capability at the FME-matched configuration; thesis: measured peak"),
                Row(f"F_max along u, {lab}: force scaling (the ch. 6 controller)", fmax, -f_sc, "N"),
            ]
            if j == 0:  # where the free push passes the point, and the mass along u were it held on the axis
                Mx = np.linalg.inv(J @ np.linalg.solve(M, J.T))
                name = "M_Free^des" if case == "free" else "M_Stiff^des"
                rows += [
                    Row(f"x where the handle passes y = {x[1]:g} m, {lab}", None,
                        float(np.mean(dev.fk(res.q_point)[:, 0])), "m",
                        f"the thesis measures at [{x[0]:g}, {x[1]:g}] m; pushed from rest along u with nothing "
                        "holding x, the handle drifts off that axis"),
                    Row(f"(M_x)_yy at the nominal configuration (the motion held on the axis x = {x[0]:g} m), {name}",
                        mx, float(u @ Mx @ u), "kg", "eq. 6.22 along one axis with the other held: uᵀM_x u, "
                        "M_x = (JM⁻¹Jᵀ)⁻¹; eq. 3.13's Λ = (uᵀM_x⁻¹u)⁻¹ is the mass of a free push"),
                ]
            key = case if j == 0 else f"{case}_pinv" if proj == "pseudoinverse" else f"{case}_dyn"
            arrays.update(case_arrays(res, key))
            arrays[f"q_nominal_{key}"] = q_point[case]
            arrays[f"q_start_{key}"] = q_start
        cf, cs = cases["free"], cases["stiff"]
        rows_cmp += [
            Row(f"M_x ratio Stiff/Free, identified ({tag})", T.MX_RATIO_6_1, cs.fit.mass / cf.fit.mass, ""),
            Row(f"Φ ratio Stiff/Free, identified ({tag})", T.PHI_RATIO_6_1, cs.fit.damping / cf.fit.damping, ""),
            Row(f"identified − eq. 3.13, M_Free^des ({tag})", None, cf.lam_error, ""),
            Row(f"identified − eq. 3.13, M_Stiff^des ({tag})", None, cs.lam_error, ""),
            Row(f"identified / (Λ/(1 − k)) − 1, M_Free^des ({tag})", None, cf.fit.mass / cf.lam_vp - 1.0, ""),
            Row(f"identified / (Λ/(1 − k)) − 1, M_Stiff^des ({tag})", None, cs.fit.mass / cs.lam_vp - 1.0, ""),
        ]
        if j == 0:
            first = (cf, cs)
    cf, cs = first
    return Result(
        "ch6.sysid_table_6_1",
        "Table 6.1: M_x, Φ and F_max along u = [0, 1] at [0.5, 0.1] m identified on the simulated rhi4",
        [Table("Table 6.1 beside the simulated identification", rows),
         Table("M_Stiff^des vs M_Free^des", rows_cmp)],
        arrays,
        [
            f"MuJoCo rhi4 plant, controller {controller!r} (null space {null_space!r}), {len(forces)} trials per case, "
            "forces "
            f"{np.round(forces, 3).tolist()} N along u from [0.5, 0.05] m; fit on ±{1000 * window:g} mm around "
            "[0.5, 0.1] m (eq. 6.22 plus a constant c for Coulomb friction).",
            "Configurations: FME matching to M_Free^des / M_Stiff^des within the §5.4 joint limits "
            "(rhi.experiments.ch6.setup.best_match); the thesis does not report its configurations.",
            "The thesis's M_x and Φ are hardware identifications; the plant's inertias and joint friction are "
            "estimates (models/rhi4/README.md, device.toml [plant]).",
            f"After a 5 cm push the handle passes the point at 1–2 m/s; the Coriolis and centrifugal force that "
            f"eq. 6.22 omits is k = {cf.vp_share:+.3f} (free) and {cs.vp_share:+.3f} (stiff) of the push force, and "
            "because it scales with the force (v² ∝ F from rest) the fit reads it as inertia: M_x ≈ Λ/(1 − k) "
            f"= {cf.lam_vp:.4f} and {cs.lam_vp:.4f} kg vs identified {cf.fit.mass:.4f} and {cs.fit.mass:.4f} kg.",
        ],
    )
