"""The dossiers' data: for each headline claim, its thesis passage, its literal reading and the other readings the text supports.

Each `rhi.report.dossiers.Reading` quotes the thesis sentence (with its line in the seed text) that allows
it and names the result row that holds rhi's number under it; `Dossier.missing` names data the thesis
does not publish; `Dossier.inconsistent` gives thesis numbers that contradict each other. Readings are
listed whatever their number; the conclusion follows from the run.
"""

from __future__ import annotations

from collections.abc import Callable

from rhi.report.dossiers import Dossier, Reading
from rhi.report.headline import Lookup


def _all(fraction: float) -> float:
    """A fraction of grid points as an "everywhere" claim: 1 where it is 1."""
    return float(fraction == 1.0)


def _neg(x: float) -> float:
    return -x


CAL = "calibration.thesis_fit"


def _ratio_of(a: str, b: str) -> Callable[[Lookup], float]:
    """100 a/b [%] of two appa.tracking rows."""
    return lambda r: 100.0 * r("appa.tracking", a) / r("appa.tracking", b)


def _fit_order(table: str) -> Callable[[Lookup], float]:
    """Points (of 2) where the thesis-fit model's Λ of Table `table` are ordered RHI ≤ PHANToM < Rehab."""
    def order(r: Lookup) -> float:
        lam = {(d, p): r(CAL, f"Table {table} Λ {d} at {p}: thesis-fit") for d in ("RHI", "PHANToM", "Rehab")
               for p in (P1, P2)}
        return float(sum(lam["RHI", p] <= lam["PHANToM", p] < lam["Rehab", p] for p in (P1, P2)))
    return order


def _energy_order_squared(r: Lookup) -> float:
    """Rounds (of 2) where C2's mean ‖q̇‖² is below C1's with Λ_T = diag(σ²)."""
    e = {(d, c): r("ch4.full_design", f"mean ‖q̇‖² A→B with Λ_T = diag(σ²) (eq. 4.21's (J_T J_Tᵀ)⁻¹), {d}, {c}")
         for d in ("θz only", "l2, θz, Z_PH") for c in ("C1", "C2")}
    return float(sum(e[d, "C2"] < e[d, "C1"] for d in ("θz only", "l2, θz, Z_PH")))


def _energy_order_printed(r: Lookup) -> float:
    """Rounds (of 2) where C2's mean ‖q̇‖² is below C1's at the designs §4.4 and Table 4.1 print."""
    e = {(d, c): r("ch4.full_design", f"thesis's design: mean ‖q̇‖² A→B, {d}, {c}")
         for d in ("θz only", "l2, θz, Z_PH") for c in ("C1", "C2")}
    return float(sum(e[d, "C2"] < e[d, "C1"] for d in ("θz only", "l2, θz, Z_PH")))


P1, P2 = "(0.49, -0.22)", "(0.49, -0.14)"
J_SHARP = ("J# = M_q⁻¹Jᵀ[JM_q⁻¹Jᵀ]⁻¹, 'generalized inverse of the Jacobian' (§3.4 line 565, §6.3 line 1260, "
           "§7.2 line 1510)")
J_PLUS = "the plain pseudoinverse J⁺ = Jᵀ(JJᵀ)⁻¹ projector"
J_PLUS_WHY = ("§4.2 (line 748): 'the superscript † indicates the pseudo-inverse of a matrix, J† = Jᵀ(JJᵀ)⁻¹' — the "
              "thesis's other generalized inverse, used for its manipulability measures")
ORTHO = "the orthogonal projector of J_q (eq. A.7 with Q = I)"
ORTHO_WHY = ("line 2030: 'J_q† = Q⁻¹J_qᵀ(J_qQ⁻¹J_qᵀ)⁻¹ is the weighted pseudoinverse of J_q' — the null space of the "
             "arm's own Jacobian, the base moving with the self-motion")
FIT = "the thesis-calibrated model (params=\"thesis-fit\")"
FIT_WHY = ("§3.3 (line 497): the inertias come from [23] Çavuşoğlu et al. 2002 and [45] Dyck 2013, which the thesis "
           "cites but does not print; the calibrated model fits them to the thesis's inertia-dependent numbers")
SUBJECTS = "the 10 subjects' per-trial responses (§3.5–3.6); only means, standard deviations and test statistics are printed"

PUSH_MISSING = ("the box push itself: the box's friction on the floor, its size and where the end effector touches it, "
                "the person's push profile (appa.box_push names rhi's reading of each); Fig. A.8 plots measured torques")
_BOX, _IS4, _WITHIN_20 = "appa.box_push", (lambda j: float(j == 4)), (lambda tau: float(tau <= 20.0))
_STATIC = ("a pure x force at the handle, statically, bringing ‖W_τ τ‖ to 40 N m at q0", "line 2212: 'without adopting "
           "it, the norm increased rapidly to almost 40 Nm and stopped the task'", "appa.dm_enhancement")
_MU = ("μ = 0.4, a handbook value for a loaded wooden or cardboard box on a hard floor", "line 2204 names the box's "
       "mass only ('approximately 26 kg'), neither its material nor the floor's", _BOX)
PUSH_CHECKED = "the plant's joint torques are J_mᵀ F of its contact force, which is μ m g sliding (tests/test_box_push.py)"
APPB_BEYOND_CHECKED = ("both controllers of the comparison equal an independent plain-NumPy transcription: the AMD "
                       "(eqs. B.6–B.19) on the sampled states of the R = 0.1 m circle, the traditional J†(ẍ − J̇q̇) + "
                       "(I − J†J) q̈_A of line 2489 on those of the R = 0.25 m circle (1e-4 rad/s², "
                       "tests/test_transcription_wmm.py)")
# How the implementation behind each claim was checked against a second, independent transcription (issue 23 item 2).
_TR = "an independent plain-NumPy transcription of the thesis"
LAMBDA_CHECKED = ("Λ = (uᵀJM⁻¹Jᵀu)⁻¹ of eq. 3.13 on the closed-form Jacobian of eq. 5.12a, plain NumPy with rhi's mass "
                  "matrix as data, equals rhi's Λ at Table 3.1's printed configurations to 1e-12 "
                  "(tests/test_transcription_ch3.py): the difference is in the estimated inertias, not the formula")
RATIO_MAP_CHECKED = ("ρ_r and Λ_r of the map equal an independent plain-NumPy transcription (the Jacobian below Fig. "
                     "3.5, the PHANToM's closed-form IK, eqs. 3.6, 3.13, 3.22–3.23, §5.4's limits, the RHI at the "
                     "global minimum of eq. 3.22 found by sampling its whole self-motion manifold; rhi's M(q) as data) "
                     "at all 55 points of the quick grid to 1e-5 (tests/test_transcription_fig3_8.py). It found a bug, "
                     "fixed: one warm-started SLSQP stopped in a local minimum at 23 of them (full grid: Λ_r ≤ 1 at "
                     "60.0 % → 97.3 %, max Λ_r 3.16 → 1.10; ρ_r ≥ 1 at 100 % before and after, min 1.544 → 1.505)")
STUDY_CHECKED = ("the analysis transcribed in plain NumPy/SciPy from §3.6 — PSE, LT, UT of each fitted cumulative "
                 "Gaussian (from psignifit's threshold and width only), JND (eq. 3.26), WF (eq. 3.25), Table 3.3's mean "
                 "and std, the one-way ANOVA by its sums of squares, paired t-tests with Holm–Bonferroni written out — "
                 "equals rhi's fits, analysis and the experiment's rows on the same simulated responses to 1e-10 "
                 "(tests/test_transcription_ch3_study.py); the psignifit fit itself is not re-derived")
CH4_CHECKED = (f"rhi's GM_M, GC_M, GM_T, C1 and C2 at the thesis's four designs (θz = 89° and 2°, Table 4.1's C1 and C2) "
               f"equal {_TR} (eqs. 4.7–4.20, 4.25–4.26, its own IK; tests/test_transcription_ch4.py) to 1e-9: the "
               "difference lies in the set-up the thesis does not publish, not in the equations")
ENERGY_CHECKED = ("‖q̇‖² of eqs. 4.21–4.22 (under both readings of Λ_T) along A → B at the thesis's C2 design equals "
                  f"{_TR} to 1e-9 (tests/test_transcription_ch4.py)")
CH5_FIXED_CHECKED = (f"ν of eq. 5.11 (with and without eq. 4.20's penalty) and its gradient equal {_TR} (1e-10, finite "
                     "differences 1e-6), and so does one tick of eq. 5.9, each joint clipped at its limit, saturated "
                     "ticks included (1e-6 N m; tests/test_transcription_ch5_ch6.py)")
CH5_W_CHECKED = (f"the TMI of eqs. 4.11–4.17 (1e-10) and the gradient of eq. 5.14's μ (1e-6) equal {_TR} "
                 "(tests/test_transcription_ch5_ch6.py)")
CH6_CHECKED = (f"one tick of the §6.4 controller equals {_TR} (eqs. 6.2–6.6, 6.9–6.10) inside the torque box (1e-6 N m) "
               "and, with each joint clipped at its programmed limit, in saturation at β = 20 "
               "(tests/test_transcription_ch5_ch6.py)")
CH6_MATCH_CHECKED = (CH6_CHECKED + "; the matched configurations at X₀ are where eqs. 6.2–6.6, transcribed as a flow "
                     "along the self-motion manifold with the handle held, settle from each of rhi's starts and from "
                     "q = 0 (1e-5 rad): the global minima of the cost the controller descends (ν 0.239 / 0.466 with "
                     "rhi's limit barrier), not local ones (tests/test_transcription_ch6_matching.py)")
CH6_FMAX_CHECKED = (CH6_MATCH_CHECKED + "; a brute-force search of the whole self-motion manifold at X₀ (eq. 6.20's "
                    "kinematics, §5.4's limits with both parallelogram constraints, plain NumPy; "
                    "tests/test_transcription_table_6_1.py) finds rhi's minima of eq. 6.10 within the limits (ν 0.2199 / "
                    "0.4537 to 2e-6) and their force-scaling F_max (4.97 / 9.29 N to 1e-3); over every configuration at "
                    "X₀ force scaling gives 4.8–10.3 N, and where it gives the printed 5.674 N, ν to M_Free^des is at "
                    "least 0.373 (1.7 × its minimum), where it gives 8.564 N, ν to M_Stiff^des is within 4 % of its "
                    "minimum; without §5.4's joint box, or without its parallelogram bounds, the free-space minimum "
                    "still gives 4.7–5 N")
ON_AXIS = "the motion held on the axis x = 0.5 m: the mass along u is (M_x)_yy at the matched configuration"
ON_AXIS_WHY = ("line 1452: 'X, M_x, F_f, and F_ext are scalars as the experiments are performed along one axis'; line "
               "1454: measured 'at [0.5, 0.1]ᵀ m point' (pushed from rest with nothing holding x, rhi's handle passes "
               "y = 0.1 m 0.8 cm (free) and 2.4 cm (stiff) off it: rows 'x where the handle passes')")
MYY = "(M_x)_yy at the nominal configuration (the motion held on the axis x = 0.5 m)"
STOPS = "the minima of eq. 6.10 alone within the joint limits (the thesis's law on hard stops)"
STOPS_WHY = ("eq. 6.6 (line 1274): τ_S = −β∂ν/∂q − K_d q̇ has no limit term; on the hardware's §5.4 stops the flow "
             "slides to ν's lowest point within them (ch6.palpation rows 'JBLD ν … at the minimum of eq. 6.10 alone')")
CH6_MAP_CHECKED = ("the matching (eqs. 6.2–6.6 as a flow along the self-motion manifold, 6.9–6.10, rhi's stated limit "
                   "barrier) and F_max by force scaling, transcribed in plain NumPy with its own kinematics of eq. "
                   "6.20, give rhi's F_max ratio at every reached point of a 3 × 3 grid to 1e-6, and the unweighted "
                   "FME moves it by > 0.1 % (tests/test_transcription_ch6_matching.py). It found a bug, fixed: SLSQP "
                   "alone jumped at some points to a minimum in another basin than the controller's flow reaches from "
                   "the same start (2 of the 34 points of the 7 × 7 quick grid when it was found). The points where "
                   "the ratio is ≤ 1 (52 of 506 on the full 25 × 25 grid, ratio ≥ 0.96) form a band along the outer "
                   "edge of the reach (x 0.5–0.73 m, y −0.4 to −0.07 m) and a few at its inner edge; at the five "
                   "sampled, both matches press on §5.4's bounds (the Rehab's parallelogram bound in each), and "
                   "without rhi's limit barrier most stay ≤ 1 (0.96–1.01 on three grid rows recomputed)")
TRANSITION_CHECKED = (f"Ω of eqs. 6.17–6.19 equals {_TR} (1e-12) when V crosses each threshold once, and the full "
                      "transition takes ρ‖M_Free − M_Stiff‖_F = 0.508 s; the blended FME of eq. 6.16 reaches the "
                      "controller's FME term (finite differences 1e-6; tests/test_transcription_ch5_ch6.py)")
CH7_CHECKED = ("rhi's ASCM with J⁺ equals Algorithm 1 as printed to 1e-9 N m; with J# the static capability and Fig. "
               "7.1's deficit equal Algorithm 1's (tests/test_transcription_ch7.py)")
APPA_CHECKED = (f"the App. A controller equals {_TR} (eqs. A.5–A.21) to 1e-6 rad/s on every sampled state of the "
                "circle and of the DM phases, under each reading (tests/test_transcription_wmm.py)")
APPB_CHECKED = (f"the AMD equals {_TR} (eqs. B.6–B.19) on every sampled state of the R = 0.1 m circle, the base "
                "decisions included (tests/test_transcription_wmm.py)")

_D = [
    # ---- chapter 3
    Dossier("eq3_19.a2_below_a1", "§3.3 eqs. 3.16–3.19, Figs 3.2–3.3 (lines 529–553)",
            "|A2(jω)| ≤ |A1(jω)| for every mass, damping and frequency (no values are given: a grid of them)",
            (Reading("the part beyond M1: |A2 − M1| ≤ |A1 − M1|", "line 550: 'As |(B2/s + M2)/(B1/s + (B2/s + M2))| "
                     "≤ 1, thus, the apparent inertia of the redundant two-DoF robot is smaller' — the factor "
                     "multiplies B1/s, the part of A1 beyond M1", "ch3.apparent_inertia_example",
                     "fraction with |A2 − M1| ≤ |A1 − M1|", _all),
             Reading("the mass part: Re A2 ≤ Re A1", "line 540: A1 'is the apparent inertia' (its real part M1 is "
                     "the mass)", "ch3.apparent_inertia_example", "fraction with Re A2 ≤ Re A1", _all)),
            checked="eqs. 3.17 and 3.19 in plain NumPy (tests/test_transcription_ch3.py): |A2 − M1| ≤ |A1 − M1| on "
                    "every sample, |A2| > |A1| where B1/ω is small against M2 (M1 = M2 = 1 kg, B1 = 0.1 N s/m, B2 = 0, "
                    "ω = 1 rad/s); the MuJoCo plant agrees with both formulas (ch3.apparent_inertia_example)"),
    Dossier("table3_1.rho.RHI.0", "§3.5, Table 3.1 (line 638), eq. 3.6; the configuration printed below it (line 648)",
            "ρ = (uᵀ(JJᵀ)†u)^(−1/2) (eq. 3.6) at the printed q = [0.125, 0.022, 0.298, 0.175] rad",
            (Reading("the RHI at rhi's own optimum of eq. 3.22",
                     "line 640: 'Data reported for the RHI in Table 3.1 corresponds to the optimized configuration of "
                     "the RHI with the objective function given in (3.22)'", "ch3.table_3_1",
                     f"ρ RHI at {P1} (our optimum of eq. 3.22)"),),
            inconsistent="at (0.49, −0.14) the printed q and the printed ρ_RHI = 0.387 agree under eq. 3.6 with the "
                         "published link lengths; at (0.49, −0.22) the printed q gives a different ρ than the printed "
                         "0.371 (rhi's number in the literal row)",
            checked="eq. 3.6 on the closed-form Jacobian the thesis prints for the RHI (eq. 5.12a), plain NumPy, equals "
                    "rhi's ρ at both printed configurations to 1e-12; both reach their points within 1 mm "
                    "(tests/test_transcription_ch3.py)"),
    Dossier("table3_1.lambda.RHI.0", "§3.5, Table 3.1 (line 638), eq. 3.13",
            "Λ = (uᵀM_x⁻¹u)⁻¹ (eq. 3.13) at the printed q with rhi's estimated link inertias",
            (Reading("the RHI at rhi's own optimum of eq. 3.22", "line 640 (as for ρ)", "ch3.table_3_1",
                     f"Λ RHI at {P1} (our optimum of eq. 3.22)"),
             Reading(FIT, FIT_WHY, CAL, f"Table 3.1 Λ RHI at {P1}: thesis-fit")),
            missing="the link masses and inertias of the PHANToM and the Rehab halves: cited ([23], [45]), not printed",
            checked=LAMBDA_CHECKED),
    Dossier("table3_1.lambda_order", "§3.5, Table 3.1 (line 638), text line 648",
            "Λ_RHI < Λ_PHANToM < Λ_Rehab by eq. 3.13 at both points, the RHI at the printed q, rhi's inertias",
            (Reading(FIT, FIT_WHY, CAL, "", measure=_fit_order("3.1")),),
            missing="the link masses and inertias: cited ([23], [45]), not printed",
            checked="Λ = (uᵀJM⁻¹Jᵀu)⁻¹ of eq. 3.13 for all three interfaces, on closed-form Jacobians (eq. 5.12a, its "
                    "PHANToM and Rehab halves) with their own IK and rhi's mass matrices as data, equals rhi's Λ to "
                    "1e-7 (the IK's tolerance) and gives the same order at both points "
                    "(tests/test_transcription_ch3.py): the order is the estimated inertias', not the formula's"),
    Dossier("fig3_8.rho_r", "§3.3 Remark I, eqs. 3.8–3.10; §3.5 Fig. 3.8 (line 672)",
            "ρ_r = ρ_RHI/ρ_PHANToM ≥ 1 at every grid point, the RHI at the eq. 3.22 optimum of each point",
            (Reading("the RHI at the PHANToM's own angles, q = [0, 0, q_PHANToM]",
                     "eq. 3.8: ρ_RHI = (uᵀ(Ĵ_AD Ĵ_ADᵀ + J_NHI J_NHIᵀ)†u)^(−1/2) — the proof compares the NHI at the "
                     "same joint angles inside the RHI", "ch3.ratio_maps",
                     "fraction of points with ρ_r ≥ 1, the RHI at the PHANToM's angles", _all),),
            checked=RATIO_MAP_CHECKED),
    Dossier("fig3_7.lambda_r", "§3.3 Remark II, eqs. 3.11–3.15; §3.5 Fig. 3.7 (line 672)",
            "Λ_r = Λ_RHI/Λ_PHANToM ≤ 1 at every grid point, the RHI at the eq. 3.22 optimum of each point (as Table "
            "3.1's RHI data, line 640), rhi's estimated inertias",
            (Reading("the RHI at the PHANToM's own angles, q = [0, 0, q_PHANToM]",
                     "eq. 3.12: M_x,RHI = (M_x,NHI⁻¹ + M̂_x⁻¹)⁻¹ — the proof's NHI is the RHI's own PHANToM chain at "
                     "the same joint angles", "ch3.ratio_maps",
                     "fraction of points with Λ_r ≤ 1, the RHI at the PHANToM's angles", _all),),
            missing="the link masses and inertias: cited ([23], [45]), not printed",
            checked=LAMBDA_CHECKED + "; " + RATIO_MAP_CHECKED),
    Dossier("table3_2.order", "§3.5, Table 3.2 (line 652), eq. 3.24",
            "Λ identified by least squares (eq. 3.24) on the simulated plant, ordered RHI ≤ PHANToM < Rehab at both "
            "points",
            (Reading(FIT + ", Λ of eq. 3.13 with the sensor", FIT_WHY, CAL, "", measure=_fit_order("3.2")),),
            missing="the hardware's friction and the force-sensor records of the identification (line 656)",
            checked="eq. 3.24's least-squares fit, transcribed in plain NumPy (its own quadratic-fit derivatives, "
                    "SciPy's Butterworth in transfer-function form, numpy.linalg.lstsq), equals rhi's identified Λ and "
                    "B on the same logged trials of the RHI and the PHANToM at both points to 1e-8 (without the "
                    "low-pass Λ moves 0.5–0.8 %) and orders Λ_RHI, Λ_PHANToM at the second point as rhi's fit does "
                    "(tests/test_transcription_table_3_2.py); pushed from rest along u without a fixture (line 662 "
                    "names none), the PHANToM passes the second point's y 2 mm off the line, where its eq. 3.13 Λ is "
                    "1.5 % below that at the point and equal to the RHI's to 0.01 %, while at the point itself the "
                    "model orders RHI < PHANToM by 1.5 % (rows 'Λ eq. 3.13 at the plant's "
                    "configuration' vs 'at the nominal configuration'); the identified order there then rests on that "
                    "drift and on the velocity-product force eq. 3.24 omits, of opposite sign for the two (rows "
                    "'velocity-product … k')"),
    *[Dossier(key, "§3.5–3.6, Table 3.3 (line 691), line 699", literal, missing=SUBJECTS, checked=STUDY_CHECKED)
      for key, literal in (("table3_3.wf_order", "mean WF over the subjects, RHI < PHANToM < Rehab"),
                           ("s3_6.anova.p", "one-way ANOVA on the subjects' WF, p"),
                           ("s3_6.paired.RHI-PHANToM", "Holm-adjusted paired t-test RHI vs PHANToM on WF, p"))],
    # ---- chapter 4
    Dossier("s4_4.theta_z.C1", "§4.4 first round, Fig. 4.4 caption (line 927)",
            "θz maximising C1 over D = {θz} in rhi's §4.4 set-up",
            (Reading("the mirror design −θz", "C1 is symmetric in θz (row 'max |C1(θz) − C1(−θz)|'), so both signs "
                     "are optima of the printed C1", "ch4.theta_z_design", "θz maximising C1", _neg),),
            missing="the slave workspace W and the placement radius r0 of the design (§4.4 draws them only). rhi's W, "
                    "a square rotated about its centre, makes C1 even and 90°-periodic in θz (C1(89°) = C1(−1°); "
                    "GM_M varies 1 % over all θz, < 0.01 % from −1° to 2°), while the thesis's GM_M goes from 0.0433 "
                    "at 89° to 0.0428 at 2° (−1.2 %): the thesis's W is not symmetric under a quarter turn about the "
                    "rotation centre",
            checked=CH4_CHECKED),
    Dossier("s4_4.theta_z.C2", "§4.4 first round, Fig. 4.4 caption (line 927)",
            "θz maximising C2 over D = {θz} in rhi's §4.4 set-up", (),
            missing="the slave workspace W and the placement radius r0 of the design (§4.4 draws them only)",
            checked=CH4_CHECKED),
    Dossier("table4_1.C2.l2", "§4.4 second round, Table 4.1 (line 929)",
            "l2 of rhi's C2 optimum over D = {l2, θz, Z_PH}, K2/K1 as Table 4.1 implies", (),
            missing="the slave workspace W, r0 and K2/K1 (§4.4 gives them only in part)",
            checked=CH4_CHECKED),
    Dossier("table4_1.C2.GM_T", "§4.4, Table 4.1 (line 929), eq. 4.18",
            "GM_T of eq. 4.18 at the thesis's printed C2 design in rhi's set-up", (),
            missing="the slave workspace W over which the global index is averaged",
            checked=CH4_CHECKED),
    Dossier("fig4_7.energy_order", "§4.4, Fig. 4.7 (line 968), eq. 4.22",
            "mean ‖q̇‖² along A → B at 0.01 m/s (eq. 4.22 with Λ_T = diag(σ_I)), C2's below C1's in both rounds",
            (Reading("Λ_T = diag(σ²): eq. 4.21's ẋᵀ(J_T J_Tᵀ)⁻¹ẋ",
                     "line 953: 'joints kinetic energy, defined as ‖q̇‖² by using (4.21)'; eq. 4.21 (line 857) is "
                     "ẋᵀ(J_T J_Tᵀ)⁻¹ẋ, whose eigenvalues are the squared semi-axes where eq. 4.22 prints diag(σ)",
                     "ch4.full_design", "", measure=_energy_order_squared),
             Reading("the thesis's printed designs (θz = 89° and 2°; Table 4.1's C1 and C2)",
                     "line 953: 'Fig. 4.7 shows the teleoperation system's joint energy for various simulation "
                     "scenarios discussed above' — the scenarios are the designs lines 916 and 929 print",
                     "ch4.full_design", "", measure=_energy_order_printed)),
            missing="the designs' energies are drawn only; Fig. 4.7 prints no number",
            checked=ENERGY_CHECKED),
    # ---- chapter 5
    Dossier("s5_4_1.tme_increase", "§5.4.1, Fig. 5.3 (line 1121)",
            "TME area σ₁σ₂ after / before the null-space controller of eq. 5.9 minimising ν of eq. 5.11 on the "
            "penalised J^q (k_q = 10, rhi's choice), from q_i = [−0.63, 0.25, 0.28, 0.09] rad",
            (Reading("the penalised TMI (eq. 4.17 with J^q)", "line 847: the joint-limit penalty of eq. 4.20 enters "
                     "the TMI the controller maximises", "ch5.fixed_point", "penalised TMI"),
             Reading("eq. 5.11 as printed: ᵐM = JJᵀ, no penalty", "line 1058: 'The manipulability ellipsoid, M = JJᵀ' "
                     "in eq. 5.11 (the headline follows line 1064's 'by using the index penalized Jacobian', k_q = 10, "
                     "a value the thesis does not give)", "ch5.fixed_point",
                     "TME area increase, plain eq. 5.11 (ᵐM = JJᵀ, no penalty)")),
            missing="the penalty's k_q (eq. 4.20 gives only its form)",
            checked=CH5_FIXED_CHECKED),
    Dossier("s5_4_1.s2_below_s1", "§5.4.1 (line 1134), Fig. 5.5, eq. 5.14",
            "100 (1 − mean TME area of scenario 2 / scenario 1) along rhi's W, scenario 2 by eq. 5.14 as printed: "
            "τ_N = α ∂μ/∂q, μ = √det(J Jᵀ)",
            (Reading("scenario 2 ascending −log μ of the joint-limit-penalised J^q (k_q = 10)", "line 847: eq. 4.20's "
                     "penalty keeps the joints off their limits (eq. 5.14 as printed drives q3 into its −55° limit)",
                     "ch5.w_trajectory", "scenario 2's mean TME area below"),
             Reading("both scenarios on the plain J (k_q = None in eqs. 5.11, 5.14)", "eq. 4.20's penalty is a "
                     "design-chapter device; eqs. 5.11 and 5.14 print the plain J", "ch5.w_trajectory",
                     "reading 'plain J': scenario 2's mean TME area below scenario 1's")),
            missing="the W trajectory's coordinates (Fig. 5.5 draws it only)",
            checked=CH5_W_CHECKED),
    Dossier("table5_1.effort_order", "§5.4.1, Fig. 5.6 (line 1163), eq. 5.15",
            "the user's work of eq. 5.15 over the W, scenario 1 < 2 < 3, same B^d in all", (),
            missing="the W trajectory's coordinates and the hand's motion along it",
            checked="eq. 5.15, W = ∫F_hᵀẋ dt, integrated in plain NumPy (trapezoid) from the logged hand force and "
                    "handle velocity of the three scenarios equals rhi's in-simulation integral to 1 % (its physics "
                    "steps; 1e-12 J with one step per period) and orders the scenarios as rhi does "
                    "(tests/test_transcription_ch5_effort.py)"),
    # ---- chapter 6
    Dossier("s6_4.gain", "§6.4, Fig. 6.9 (line 1428)",
            "peak simulated F/T-sensor force with M_Stiff^des over M_Free^des, J# null-space projector",
            (Reading("static force scaling at the settled configurations", "line 1428: 'the force feedback "
                     "capability of the RHI' (a capability, not a measured peak)", "ch6.palpation",
                     "force gain, force scaling at the settled"),
             Reading(J_PLUS, J_PLUS_WHY, "ch6.palpation", "force gain M_Stiff vs M_Free, simulated sensor peak, "
                     "controller with J⁺"),
             Reading(STOPS, STOPS_WHY, "ch6.palpation", "force gain, force scaling at the minima of eq. 6.10 alone")),
            missing="the hardware's friction and the human hand's stiffness during the palpation",
            checked=CH6_MATCH_CHECKED),
    *[Dossier(f"table6_1.{c}.F_max", "§6.4, Table 6.1 (line 1442)",
              f"peak simulated F/T-sensor force along u with M_{c.capitalize()}^des, J#",
              (Reading("static force scaling at the settled configuration", "Table 6.1 caption: 'maximum force "
                       "feedback capability'", "ch6.palpation",
                       f"F_max along u, M_{c.capitalize()}^des: force scaling at the settled"),
               Reading("LP with null-space torques at the settled configuration", "§7.2's F_max (eq. 7.4) is an LP "
                       "over the torque box", "ch6.palpation", f"F_max along u, M_{c.capitalize()}^des: LP with "
                       "null-space torques"),
               Reading(STOPS, STOPS_WHY, "ch6.palpation", f"F_max along u, M_{c.capitalize()}^des: force scaling at "
                       "the minimum of eq. 6.10 alone")),
              missing="the hardware's friction and the human hand's stiffness during the palpation"
              + (", and the configuration the hardware settled to (force scaling gives the printed 5.674 N only at "
                 "configurations far from eq. 6.10's minimum under §5.4's limits)" if c == "free" else ""),
              checked=CH6_FMAX_CHECKED)
      for c in ("free", "stiff")],
    Dossier("table6_1.M_x_ratio", "§6.4, Table 6.1 (line 1442)",
            "identified M_x(M_Stiff)/M_x(M_Free), eq. 3.24 on the simulated plant, J#",
            (Reading(J_PLUS, J_PLUS_WHY, "ch6.sysid_table_6_1", "M_x ratio Stiff/Free, identified (J⁺)"),
             Reading("the model's Λ ratio at the settled configurations", "Table 6.1 caption: 'inertia M_x'",
                     "ch6.palpation", "inertia ratio Λ_Stiff/Λ_Free"),
             Reading(ON_AXIS, ON_AXIS_WHY, "ch6.sysid_table_6_1", "",
                     measure=lambda r: r("ch6.sysid_table_6_1", f"{MYY}, M_Stiff^des")
                     / r("ch6.sysid_table_6_1", f"{MYY}, M_Free^des")),
             Reading(FIT + ", Λ of eq. 3.13 with the sensor", FIT_WHY, CAL, "",
                     measure=lambda r: r(CAL, "Table 6.1 M_x, M_Stiff^des: thesis-fit")
                     / r(CAL, "Table 6.1 M_x, M_Free^des: thesis-fit"))),
            missing="the link inertias (cited, not printed) and the hardware's friction",
            checked=CH6_CHECKED),
    *[Dossier(f"table6_1.{c}.M_x", "§6.4, Table 6.1 (line 1442), eq. 3.24",
              f"M_x identified by eq. 3.24 on the simulated plant with M_{c.capitalize()}^des, J# null-space "
              "projector (the text's)",
              (Reading(J_PLUS, J_PLUS_WHY, "ch6.sysid_table_6_1",
                       f"M_x identified (eq. 3.24: M_x ẍ + Φ ẋ = F), M_{c.capitalize()}^des (J⁺)"),
               Reading("the model's Λ at the settled configuration", "eq. 3.13 (Table 6.1's 'inertia M_x')",
                       "ch6.palpation", f"M_x along u, M_{c.capitalize()}^des: our model's Λ"),
               Reading(FIT + ", Λ of eq. 3.13 with the sensor", FIT_WHY, CAL,
                       f"Table 6.1 M_x, M_{c.capitalize()}^des: thesis-fit"),
               Reading(ON_AXIS, ON_AXIS_WHY, "ch6.sysid_table_6_1", f"{MYY}, M_{c.capitalize()}^des")),
              missing="the link inertias (cited, not printed)",
              checked=CH6_CHECKED)
      for c in ("free", "stiff")],
    Dossier("s6_5.t_f", "§6.4 (line 1462), eqs. 6.16–6.19",
            "the full transition time ρ‖M_Free − M_Stiff‖_F with ρ = 0.003",
            (Reading("the time spent blending in the run", "line 1462: 'so that the transition performed in 0.5 "
                     "second'", "ch6.transition", "time spent blending (0 < Ω < 1)"),),
            checked=TRANSITION_CHECKED),
    Dossier("fig6_10.entire", "§6.4, Fig. 6.10 (line 1459)",
            "F_max (force scaling) with the M_Stiff^des configuration above that with M_Free^des at every grid point",
            (Reading("LP with null-space torques", "line 1459: 'the maximum force feedback capability'",
                     "ch6.fmax_ratio_map", "fraction of points with ratio > 1, LP", _all),),
            missing="the grid and the configurations of Fig. 6.10 (a map only, no numbers)",
            checked=CH6_MAP_CHECKED),
    *[Dossier(key, "§6.4, Fig. 6.11 (line 1469)", literal,
              (Reading("the same at β = 2", "line 1414 gives β = 20; the figure shows no saturation, which β = 2 "
                       "avoids in rhi's plant", "ch6.transition", w, below=wo),),
              missing="Fig. 6.11 shows curves only; the hardware's friction",
              checked=TRANSITION_CHECKED + "; " + CH6_CHECKED + "; the closed-loop runs themselves are not compared")
      for key, literal, w, wo in (
          ("fig6_11.effort", "max per-tick ‖Δτ_N‖ with the method below without, β = 20",
           "max per-tick ‖Δτ_N‖ of the applied null-space torque, with (β = 2)",
           "max per-tick ‖Δτ_N‖ of the applied null-space torque, without (β = 2)"),
          ("fig6_11.interference", "max handle-force disturbance with the method below without, β = 20",
           "max handle-force disturbance |F_sensor − F_commanded| along u, with (β = 2)",
           "max handle-force disturbance, without (β = 2)"))],
    # ---- chapter 7
    Dossier("fig7_1.scaling_gap", "§7.3, Fig. 7.1 (line 1627)",
            "peak force of simple scaling below ASCM's, J# null-space projector (the text's) with rhi's planar3r masses",
            (Reading(J_PLUS, J_PLUS_WHY, "ch7.example_3dof", "peak force deficit of scaling vs ASCM (pseudoinverse"),),
            missing="the 3-DoF example's link masses, which J# needs (line 1627 gives lengths and torque bounds only)",
            checked=CH7_CHECKED),
    Dossier("s7_5.gain", "§7.5, Fig. 7.6 (line 1714); J# of §7.2 (line 1510) in eq. 7.5 and Algorithm 1 (line 1564)",
            "peak force before a joint range limit, ASCM over no compensation, J#",
            (Reading("the static capability at the contact configuration, J# (Algorithm 1 as printed reaches the same "
                     "peak: tests/test_transcription_ch7.py)", "line 1714: 'the maximum force feedback of the RHI is "
                     "enhanced'", "ch7.palpation", "static gain of ASCM over scaling (dynamic J#)"),
             Reading("the static capability at the contact configuration, " + J_PLUS, J_PLUS_WHY, "ch7.palpation",
                     "static gain of ASCM over scaling (pseudoinverse J⁺)"),
             Reading("the LP allocation", "§7.2 eq. 7.4 (the capability ASCM approaches)", "ch7.palpation",
                     "peak force before a joint range limit, lp (dynamic) vs none"),
             Reading("the peak force over the whole run, joint range stops included", "line 1714: 'the maximum force "
                     "feedback of the RHI is enhanced by 73% (Fig. 7.6(b))' — the figure's peak measured force, with the "
                     "hardware's joint stops", "ch7.palpation", "",
                     measure=lambda r: 100.0 * (r("ch7.palpation", "max force over the run (joint stops included), ascm "
                                                  "(dynamic") / r("ch7.palpation", "max force over the run (joint stops "
                                                                  "included), none (dynamic") - 1.0))),
            missing="the hardware's friction, the hand's stiffness and the link inertias J# needs (cited, not printed)",
            checked=CH7_CHECKED + "; the contact configuration is the minimum of eq. 7.18 (M^des = diag(0.01, 170)) "
            "within §5.4's limits that a brute-force search of the self-motion manifold at X₀ finds (ν to 1e-6 without "
            "rhi's limit barrier, 0.5 % with it), and there eq. 7.5's capability over simple scaling, two small LPs in "
            "plain NumPy/SciPy, is +2 % with J# (+1.5 % with the thesis-fit inertias) and +101 % with J⁺ "
            "(tests/test_transcription_s7_5.py)"),
    # ---- appendix A
    *[Dossier(f"sA_4_2.rms_ratio.{c}", "§A.4.2, Table A.1 (line 2161), line 2194",
              f"RMS {name} commanded, proposed / traditional, on the 0.25 m circle with K_x = 10 I, ε = 0.2, "
              "W_x on the wheel velocities as printed (eq. A.12)",
              (Reading("W_x on the generalized Jacobian", "line 2068: 'we choose the entire system Jacobian J in "
                       "(A.5) to command motion to each actuator'", "appa.tracking", "",
                       measure=_ratio_of(f"proposed generalized: RMS {name}", f"traditional: RMS {name}")),
               Reading("the proposed RMS over the base's motion only", "line 2194: 'the mobile base moved only during "
                       "time 7.15-20.35 s'", "appa.tracking", "",
                       measure=_ratio_of(f"proposed: RMS {name} over the base's motion only",
                                         f"traditional: RMS {name}"))),
              inconsistent=("Table A.1's proposed max |v_xb| = 2.8 cm/s with the base moving only 7.15–20.35 s bounds "
                            "its RMS over a 40 s turn by 2.8·√(13.2/40) = 1.61 cm/s, below the printed 1.68"
                            if c == "vx" else ""),
              missing="the wheel-ground slip and the motion-capture noise of the experiment",
              checked=APPA_CHECKED)
      for c, name in (("vx", "v_xb"), ("w", "ω_b"))],
    Dossier("sA_4_2.base_interval.0", "§A.4.2, Fig. A.6 (line 2194)",
            "first time the proposed controller commands the base", (),
            missing="the wheel-ground slip and the motion-capture noise of the experiment",
            checked=APPA_CHECKED),
    Dossier("sA_4_3.dm_z.0", "§A.4.3 (line 2202), eq. A.17",
            "DM = 1/‖W_τ J_mᵀ u‖ along u = [0, 0, 1] at the stated q0, rhi's Gen3 model (Kinova's published lengths)", (),
            missing="the arm model the thesis used (it names the Kinova Gen3 but prints no kinematic parameters)",
            checked=f"DM = 1/‖W_τ J_mᵀ u‖ along z at the stated q0 equals {_TR} (eqs. A.8, A.17) to 1e-12 on rhi's "
                    "Gen3 Jacobian (tests/test_transcription_wmm.py, the DM-enhancement test along z): the difference "
                    "is the arm model"),
    *[Dossier(f"sA_4_3.dm_{ax}.{i}", f"§A.4.3 (line {line}), eqs. A.9, A.19",
              f"DM along {ax} after the experiment's phases (5 s Cartesian, 15 s null space), the stated gains, "
              "eq. A.19 as printed (weighted J†: the base is still while γ = 0)",
              (Reading(ORTHO, ORTHO_WHY, "appa.dm_enhancement", f"DM along {ax} after {phase} (t"),
               *((Reading("the null-space phase run until DM stops rising (orthogonal projector)", "line 2202 "
                          "states no duration for the simulation", "appa.dm_enhancement", "largest DM along z within"),)
                 if ax == "z" else ())),
              inconsistent=(f"eq. A.19 as printed keeps the base still (γ = 0 while the arm is within its limits), "
                            f"and the arm's self-motion alone reaches at most DM = {{0}} along {ax} at the held "
                            f"position (rhi's Gen3, SLSQP), below the printed {thesis}; with the base free the most is "
                            "{1}"),
              evidence=(("appa.dm_enhancement", f"largest DM along {ax} the arm's self-motion can reach"),
                        ("appa.dm_enhancement", f"largest DM along {ax} with the base free")),
              checked=APPA_CHECKED + "; with the base fixed and the end effector at q0's x, y at any height of the "
              "Cartesian phase's [0.36, 0.56] m, SLSQP on the device model from 30 starts (12 in the test) finds "
              "at most DM 1.568 along z and 4.208 along x, W_τ as printed (tests/test_transcription_wmm.py, "
              "test_the_printed_dm_needs_the_base): the printed 4.031 and 5.88 need the base to move")
      for ax, i, line, phase, thesis in (("z", 1, 2202, "enhancement", "4.031"),
                                         ("x", 2, 2212, "the null-space phase", "5.88"))],
    Dossier("figA_8.joint4_first", "§A.4.3, Fig. A.8(a) (line 2210)",
            "the first arm joint whose torque (gravity subtracted) reaches its limit (32 N m joints 1–4, 13 N m joints "
            "5–7) on the MuJoCo plant without DM enhancement: the traditional J⁺ with no null-space term (line 2198) "
            "pushes the 26 kg box by a 0.2 m minimum-jerk reference from 20 s in 10 s; μ = 0.692 from Fig. A.9(b)'s "
            "30 N m at DM 5.88 (appa.box_push's readings, fixed before the first run)",
            (Reading("without DM = the weighted distribution with the DM off", "Fig. A.8's caption '(a) Without DM "
                     "enhancement' names no other controller", _BOX, "without DM (weighted distribution): first arm "
                     "joint to saturate", _IS4),
             Reading(*_MU, "without DM (traditional J⁺), μ = 0.40: first arm joint to saturate", _IS4),
             Reading(*_STATIC, "box push, static: first arm joint to reach its limit", _IS4)),
            missing=PUSH_MISSING, checked=f"{APPA_CHECKED}; {PUSH_CHECKED}"),
    Dossier("figA_8.within_20", "§A.4.3, Fig. A.8(b) (line 2210)",
            "the largest arm joint torque (gravity subtracted) on the MuJoCo plant while pushing the same box after "
            "the DM enhancement (5 s Cartesian, 15 s null space), eq. A.19 as printed (weighted J†) with the DM term "
            "during the push, μ = 0.692 (appa.box_push's readings, fixed before the first run)",
            (Reading(ORTHO, ORTHO_WHY, _BOX, "with DM (orthogonal projector): largest arm joint torque during the push",
                     _WITHIN_20),
             Reading(*_MU, "with DM (eq. A.19 as printed), μ = 0.40: largest arm joint torque during the push",
                     _WITHIN_20),
             *(Reading(f"{_STATIC[0]}, after the DM enhancement ({v})", *_STATIC[1:], "box push, static: largest arm "
                       f"joint torque at that force after the DM enhancement ({v})", _WITHIN_20)
               for v in ("eq. A.19 as printed", "orthogonal projector"))),
            missing=PUSH_MISSING, checked=f"{APPA_CHECKED}; {PUSH_CHECKED}"),
    # ---- appendix B
    Dossier("sB_4_2.singular_t", "§B.4.2, Fig. B.7 (line 2483)",
            "first time σ_min(J_m) < 0.05 without avoidance",
            (Reading("the task must be scaled (α < 1)", "line 2483: 'the desired trajectory cannot be tracked at "
                     "about 8.35s'", "appb.singularity", "without avoidance: first time the task must be scaled"),
             Reading("the tracking error exceeds 1 cm", "line 2483: 'significant tracking errors start to emerge'",
                     "appb.singularity", "without avoidance: first time the tracking error exceeds")),
            checked=f"the AMD without avoidance (eqs. B.4–B.9, Fig. B.4, no tertiary objective) equals {_TR} at every "
                    "state of the experiment's run to 12 s (1e-6 rad/s², measured 2e-8), and σ_min(J_m) of the logged "
                    "configurations by NumPy's SVD equals the logged one (1e-12; tests/"
                    "test_transcription_appb_singular.py). It found a bug, fixed: Fig. B.4's scaling named the wrong "
                    "critical joint where one was already beyond its bound, so the SNS gave up the task (α = 0) where it "
                    "was feasible; from 9.31 s on, after the singular time, which is unchanged"),
    Dossier("sB_4_3.base_on", "§B.4.3, Fig. B.11 (line 2549)",
            "first time the proposed controller enables the base beyond the workspace (σ_m,min = 0.15)", (),
            missing="the wheel-ground slip of the experiment",
            checked=f"the AMD equals {_TR} (eqs. B.6–B.19) on sampled states of the R = 0.25 m circle, the states "
                    "around the first base activation and the base decisions included (1e-4 rad/s²; another σ_m,min "
                    "disagrees; tests/test_transcription_wmm.py)"),
    Dossier("sB_4_3.periods.within", "§B.4.3, Table B.2 (line 2501)",
            "base activation periods within the workspace with σ_m,min = 0.15 (line 2479)", (),
            inconsistent="§A.4.2 (line 2172) gives the arm's workspace at q0 as a 0.11 m circle (rhi's Gen3: {0} m), "
                         "§B.4.2 (line 2479) as 0.2 m; with 0.11 m the R = 0.1 m circle's far point leaves the arm at "
                         "best σ_min(J_m) = {1} (rhi), below the stated σ_m,min = 0.15, so the base must be enabled",
            evidence=(("appb.tracking", "largest circle radius within the arm's workspace at q0 (far point reachable, "
                                        "base fixed; vs §A.4.2)"),
                      ("appb.tracking", "best σ_min(J_m) the arm alone")),
            checked=APPB_CHECKED),
    *[Dossier(key, "§B.5 conclusion (line 2555), §B.4.3", literal, (),
              missing="the wheel-ground slip of the experiment", checked=APPB_BEYOND_CHECKED)
      for key, literal in (("sB_5.err_reduction.0", "100 (1 − max error x proposed / traditional), beyond"),
                           ("sB_5.err_reduction.1", "100 (1 − max error y proposed / traditional), beyond"),
                           ("sB_5.base_time_reduction", "100 (1 − base motion time proposed / traditional), beyond"))],
]

#: The dossiers by claim key.
DOSSIERS: dict[str, Dossier] = {d.key: d for d in _D}
