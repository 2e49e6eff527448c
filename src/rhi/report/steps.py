"""The experiments of `rhi reproduce`: how each runs (full and --quick), whether it splits into parts, its figures."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from rhi.experiments import (
    appa as exa,
    appb as exb,
    calibration as excal,
    ch3 as ex3,
    ch4 as ex4,
    ch5 as ex5,
    ch6 as ex6,
    ch7 as ex7,
)
from rhi.experiments.beyond import (
    bilateral as exbi,
    intent as exin,
    passivity as expas,
    spatial as exsp,
    spatial_palpation as exspp,
    zwidth as exzw,
)
from rhi.experiments.parts import Plan
from rhi.experiments.result import Result
from rhi.plots import (
    appa as pla,
    appb as plb,
    bilateral as plbi,
    ch3 as pl3,
    ch3_control as pl3c,
    ch4 as pl4,
    ch5 as pl5,
    ch6 as pl6,
    ch7 as pl7,
    ch7_palpation as pl7p,
    intent as plin,
    passivity as plpas,
    perception as plp,
    renders as plr,
    spatial as plsp,
)


@dataclasses.dataclass(frozen=True)
class Step:
    """One experiment of the reproduction: how to run it (full and --quick) and draw it.

    The experiment's id is its chapter and function, the chapter being the module (or package) under
    `rhi.experiments` that defines the function: `rhi.experiments.ch3.discrimination.psychophysics` is
    "ch3.psychophysics", `rhi.experiments.beyond.passivity.passivity` is "beyond.passivity".
    `plan`, where given, takes the arguments of `run` but `progress` and returns the experiment's
    independent parts (`rhi.experiments.parts.Plan`), which a parallel reproduction runs side by side.
    """

    run: Callable[..., Result]
    full: dict
    quick: dict
    figures: dict[str, Callable[[Result], object]]
    progress: bool = False
    plan: Callable[..., Plan] | None = None

    @property
    def chapter(self) -> str:
        """Chapter id: the module or package directly under `rhi.experiments` that defines the experiment."""
        return self.run.__module__.split(".")[2]

    @property
    def name(self) -> str:
        """Experiment id, e.g. "ch7.example_3dof" (also the name of the `Result` it returns)."""
        return f"{self.chapter}.{self.run.__name__}"


STEPS: list[Step] = [
    Step(ex3.table_3_1, {}, {}, {"configurations": pl3.configurations,
                                        "configurations_rendered": plr.ch3_configurations}),
    Step(ex3.ratio_maps, {"resolution": 41}, {"resolution": 13},
         {"fig3_6": pl3.workspaces, "fig3_7": pl3.lambda_ratio, "fig3_8": pl3.rho_ratio}, progress=True),
    Step(ex3.apparent_inertia_example, {}, {}, {"fig3_2_3": pl3.apparent_inertia}),
    Step(ex3.nullspace_configurations, {}, {"duration": 4.0, "starts": ("rehab",), "hard_stops": False},
         {"fig_ch3_control": pl3c.convergence, "ch3_control_configurations": pl3c.configurations,
          "ch3_control_drift": pl3c.drift_hist}, progress=True),
    Step(ex3.sysid_table_3_2, {}, {"trials": 4}, {"table3_2": plp.sysid_fit}, progress=True),
    Step(ex3.psychophysics, {},
         {"subjects": 4, "repetitions": 6, "comparison_percent": (-35.0, -15.0, 0.0, 15.0, 35.0), "durations": (0.7, 1.4),
          "overdispersion": False},
         {"fig3_9": plp.psychometric_curves, "fig3_10": plp.wf_jnd_boxes, "perceived_stiffness": plp.perceived_stiffness},
         progress=True),
    Step(ex4.theta_z_design, {"density": 100.0}, {"density": 40.0, "step_deg": 5.0, "maxiter": 20},
         {"fig4_4": pl4.fig4_4, "theta_sweep": pl4.theta_sweep}, progress=True),
    Step(ex4.full_design, {"density": 100.0}, {"density": 40.0, "maxiter": 15, "popsize": 8},
         {"fig4_5": pl4.fig4_5, "fig4_6": pl4.fig4_6, "fig4_7": pl4.fig4_7, "l2_scan": pl4.l2_scan}, progress=True),
    Step(ex4.sensitivity, {"density": 100.0},
         {"density": 40.0, "densities": (20.0, 40.0, 80.0), "maxiter": 10, "k2_values": (10.0, 20.0)},
         {"convergence": pl4.convergence, "k2_scan": pl4.k2_scan}, progress=True),
    Step(ex5.fixed_point, {}, {"duration": 6.0, "variants": False},
         {"fig5_3": pl5.fig5_3, "fig5_3_convergence": pl5.fixed_point_convergence}, progress=True),
    Step(ex5.workspaces, {}, {"samples": 8000, "area_samples": 50000}, {"fig5_4": pl5.fig5_4}),
    Step(ex5.w_trajectory, {}, {"scale": 0.15},
         {"fig5_5": pl5.fig5_5, "fig5_6": pl5.fig5_6, "tme_along_w": pl5.tme_along_w}, progress=True,
         plan=ex5.w_trajectory_plan),
    Step(ex6.example_3dof, {"steps": 201}, {"steps": 101},
         {"fig6_3": pl6.example_3dof, "fig6_4": pl6.configurations_3dof}),
    Step(ex6.palpation, {}, {"settle": 0.2, "depth": 0.012, "speed": 0.02, "hold": 0.1}, {"fig6_9": pl6.palpation},
         progress=True),
    Step(ex6.sysid_table_6_1, {}, {"trials": 4}, {"table6_1": plp.sysid_fit}, progress=True),
    Step(ex6.transition, {},
         {"settle": 0.2, "depth": 0.015, "speed": 0.03, "hold": 0.3, "release": 0.7, "compare_beta": None},
         {"fig6_11": pl6.transition}, progress=True),
    Step(ex6.aso_example, {}, {"resolution": 41}, {"fig6_6": pl6.aso_example}),
    Step(ex6.fmax_ratio_map, {"resolution": 25}, {"resolution": 7, "starts": 1}, {"fig6_10": pl6.fmax_ratio_map},
         progress=True),
    Step(ex7.example_3dof, {"steps": 401}, {"steps": 101}, {"fig7_1": pl7.example_3dof}),
    Step(ex7.deficiency_map, {"resolution": 31}, {"resolution": 9}, {"fig7_5": pl7.deficiency_map},
         progress=True),
    Step(ex7.palpation, {},
         {"start": "optimum", "settle": 0.5, "depth": 0.03, "speed": 0.03,
          "cases": (("none", "dynamic"), ("ascm", "dynamic"), ("lp", "dynamic"))},
         {"fig7_6": pl7p.fig7_6, "fig7_6_force_penetration": pl7p.force_penetration,
          "ch7_palpation_settling": pl7p.settling}, progress=True),
    Step(expas.passivity, {},
         {"duration": 1.5, "stiff_duration": 2.0, "speed": 0.03,
          "cases": ("objectives", "objectives_pc", "objectives_damper", "objectives_tank")},
         {"passivity_energy": plpas.energy, "passivity_force": plpas.force, "passivity_chatter": plpas.chatter},
         progress=True, plan=expas.passivity_plan),
    Step(exzw.z_width, {"duration": 2.0},
         {"duration": 0.5, "stiffness": (1e3, 2e4, 5e4), "damping": (0.0, 10.0), "methods": ("none", "damper_bounding",
                                                                                          "damper")},
         {"passivity_z_width": plpas.z_width}, progress=True, plan=exzw.z_width_plan),
    Step(exa.tracking, {"duration": 40.0}, {"duration": 20.0}, {"fig_a5": pla.tracking, "fig_a6": pla.base_motion},
         progress=True),
    Step(exa.dm_enhancement, {}, {"t_long": 20.0},
         {"fig_a9": pla.dm_enhancement, "fig_a7_rendered": plr.wmm_configurations}, progress=True,
         plan=exa.dm_enhancement_plan),
    Step(exa.box_push, {},
         {"t_cartesian": 1.0, "t_null": 2.0, "distance": 0.05, "duration": 2.0, "hold": 0.5, "settle": 0.5,
          "alternatives": False, "frictions": ()},
         {"fig_a8": pla.box_push}, progress=True, plan=exa.box_push_plan),
    Step(exb.singularity, {}, {"duration": 16.0, "dt": 0.01}, {"fig_b7": plb.singularity}, progress=True),
    Step(exb.tracking, {}, {"duration": 24.0, "dt": 0.01},
         {"fig_b8": plb.within, "fig_b10": plb.beyond, "fig_b11": plb.base_paths}, progress=True,
         plan=exb.tracking_plan),
    Step(excal.thesis_fit, {}, {"starts": 2}, {}),
    Step(exbi.teleoperation_delay, {}, {"duration": 5.0, "delays": (0.1,), "extra_stiffness": ()},
         {"bilateral_energy": plbi.energy, "bilateral_forces": plbi.forces, "bilateral_drift": plbi.drift},
         progress=True,
         plan=exbi.teleoperation_delay_plan),
    Step(exsp.spatial_remarks, {"resolution": 7}, {"resolution": 2, "workers": 1}, {"spatial_remarks": plsp.remark_maps},
         progress=True),
    Step(exsp.spatial_force_capability, {}, {"configurations": 2, "directions": 5},
         {"spatial_force_capability": plsp.force_capability}, progress=True),
    Step(exsp.spatial_ellipsoids, {}, {}, {"spatial_ellipsoids": plsp.ellipsoids}),
    Step(exspp.spatial_vme, {}, {"duration": 0.5}, {"spatial_vme": plsp.vme_convergence}, progress=True),
    Step(exspp.spatial_palpation, {},
         {"settle": 0.1, "depth": 0.008, "speed": 0.02, "hold": 0.05, "starts": 1, "cases": ("free", "stiff")},
         {"spatial_palpation": plsp.palpation}, progress=True),
    Step(exin.intent_strokes, {}, {"train": 10, "test": 3}, {"intent_strokes": plin.strokes},
         progress=True),
    Step(exin.intent_w_trajectory, {}, {"scale": 0.06, "speed": 0.05, "settle": 0.1},
         {"intent_w_trajectory": plin.w_trajectory}, progress=True, plan=exin.intent_w_trajectory_plan),
    Step(exin.intent_palpation, {}, {"settle": 0.1, "depth": 0.01, "speed": 0.02, "hold": 0.05, "starts": 1},
         {"intent_palpation": plin.palpation}, progress=True),
]


def chapters() -> list[str]:
    """Chapters the reproduction covers."""
    return sorted({s.chapter for s in STEPS})


def experiments() -> list[str]:
    """Ids of the experiments, e.g. "ch7.example_3dof"."""
    return [s.name for s in STEPS]


def describe() -> list[tuple[str, str]]:
    """[(id, one line)] of the experiments: the first line of each experiment function's docstring."""
    return [(s.name, (s.run.__doc__ or "").strip().splitlines()[0] if s.run.__doc__ else "") for s in STEPS]


def step_names(s: Step) -> set[str]:
    """Every name `rhi experiment` accepts for a step: its id (its result's name) and its function's name."""
    return {s.name, s.run.__name__}
