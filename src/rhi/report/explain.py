"""Why rhi's value can differ from a thesis value, per group of thesis values (by `rhi.thesis` key prefix).

The report shows these beside a row outside its tolerance whose experiment gave no note of its
own. Each sentence states what rhi measures or what the thesis does not publish (the experiments'
docstrings give the full account); the longest matching key prefix wins.
"""

from __future__ import annotations

from rhi.experiments.result import Row

#: thesis-key prefix → one sentence of reason.
EXPLANATIONS: dict[str, str] = {
    "table3_1.rho": "ρ depends on kinematics only; rows at rhi's own optimum of eq. 3.22 differ where SLSQP finds "
                    "another point of the self-motion manifold than the thesis's hardware controller did.",
    "table3_1.lambda": "Λ depends on link inertias the thesis cites ([23], [45]) but does not print; rhi's are the "
                       "estimates of models/rhi4/README.md (the report's dossiers show the thesis-calibrated variant).",
    "table3_1.q": "the thesis's configuration comes from its controller on the hardware; rhi's from SLSQP on eq. 3.22 "
                  "with the §5.4 joint limits: another point of a flat objective along the self-motion manifold.",
    "table3_2": "identified on the simulated plant whose inertias and friction are estimates (models/rhi4/README.md); "
                "the thesis identified its hardware with a human-held force sensor.",
    "table3_3": "the thesis's numbers come from 10 human subjects whose responses it does not publish; rhi's come "
                "from simulated observers whose noise grows with the device's reflected inertia and friction.",
    "s3_6": "p-values of human-subject data the thesis does not publish; rhi's come from simulated observers "
            "(their size depends on the observer model and the number of subjects).",
    "s4_4": "C1 is mirror-symmetric in θz and both costs are flat near their maxima; the optimum moves with set-up "
            "choices the thesis does not state (slave workspace W, placement radius r0, k_q, K2/K1: see ch4 sensitivity).",
    "table4_1": "the set-up the thesis leaves open (W, r0, K2/K1, Z_PH range) decides which C2 basin wins; scored at the "
                "thesis's own designs rhi's indices agree with Table 4.1 to ~2 %, and rhi's optimum beats them.",
    "s5_4_1": "the TME area depends on the slave's ME and the HI's joint-limit penalty k_q (not given in the thesis); "
              "the thesis's W trajectory is only drawn, ours is the letter W of ch5's docstring.",
    "table5_1": "Table 5.1 is measured with human users on hardware (friction uncompensated); rhi's simulated hand "
                "follows the W at constant speed, so time and error are set by the path, not by the user.",
    "s5_4_2": "human-user statistics the thesis does not publish per trial; rhi's come from a seeded simulated user.",
    "table5_2": "human-user statistics the thesis does not publish per trial; rhi's come from a seeded simulated user.",
    "fig5_4": "workspace areas from IK sampling of rhi's models with the §5.4 joint limits.",
    "s6_3_1": "eigenvalues of the torque-weighted FME at the thesis's initial configuration: rounding of the "
              "thesis's printed 2.6 and 5.8 (rhi: 2.58, 5.79).",
    "s6_4": "𝒦 and ζ follow from the kinematics and torque limits; the force gain depends on which configurations "
            "the constrained FME matching reaches (the §5.4 joint limits bind at X₀ for both FMEs) and on the projector.",
    "table6_1": "Table 6.1 was identified and measured on the hardware (friction, compliance, a human hand); rhi's are "
                "the simulated plant's, whose inertias and friction are partly estimates (models/rhi4/README.md).",
    "s6_5": "the transition time ρ‖M_Free − M_Stiff‖_F follows from the desired FMEs; the thesis rounds it to 0.5 s.",
    "fig7_1": "with the thesis's link masses unknown the dynamically consistent J# depends on rhi's inertias; the "
              "plain pseudoinverse projector J⁺ reproduces the thesis's 12 %.",
    "s7_5": "the thesis's 73 % comes from its hardware with a human hand; rhi simulates the palpation on estimated "
            "inertias and friction, and the uncompensated and ASCM cases stop at different criteria (issue 13).",
    "tableA_1": "rhi's base is a simulated mecanum base with seeded slip and noise (the thesis's wheel-ground slip is "
                "not published), so base commands differ in size while the ordering proposed < traditional is kept.",
    "sA_4_2": "rhi's base slip model is seeded and estimated (not published); tracking errors and base commands "
              "depend on it.",
    "sA_4_3": "rhi uses the gains and phase lengths §A.4.3 states; the report's dossier gives the readings of the "
              "projector (eq. A.19 as printed, generalized) and the largest DM the self-motion can reach.",
    "sB_4_2": "the time the arm becomes singular depends on the circle's start and speed and on σ_m,min, which "
              "the thesis states only in part; rhi reports three criteria of 'singular'.",
    "sB_4_3": "rhi's simulated base (seeded slip and noise) and the σ_m,min threshold decide when the base is "
              "enabled and released; the thesis's hardware slip is not published.",
    "tableB_2": "rhi's simulated base (seeded slip and noise) decides the base commands; the thesis's hardware slip "
                "is not published, and its 80 s duration is the run length.",
    "sB_5": "computed from rhi's tracking errors and base durations, which depend on the simulated base's slip.",
}


def explanation(row: Row) -> str:
    """The explanation for a row's thesis value ("" when there is none)."""
    key = row.source
    if key is None:
        return ""
    best = max((p for p in EXPLANATIONS if key == p or key.startswith(p + ".")), key=len, default=None)
    return "" if best is None else EXPLANATIONS[best]
