"""The thesis's headline claims that open the report (`rhi.report.headline`), in thesis order.

Each claim reads rhi's number from the experiments' result rows (by quantity prefix), compares it with
a `rhi.thesis` value by the rules of `rhi.report.rules`, and names what the value rests on (`inputs`).
The headline number is the literal reading of the thesis (its text names the dynamically consistent
J# = M⁻¹Jᵀ(JM⁻¹Jᵀ)⁻¹ for every null-space projector of ch. 3–7, and eq. A.19 as printed); other readings
are in the claims' dossiers (`rhi.report.readings`). Reasons state this run's numbers.
"""

from __future__ import annotations

from collections.abc import Callable

from rhi import thesis as T
from rhi.report.headline import Claim, Lookup
from rhi.report.rules import Effect

P1, P2 = "(0.49, -0.22)", "(0.49, -0.14)"
K, INR, PLANT, BASE, HUMAN = ("kinematics",), ("inertias",), ("plant", "inertias"), ("mobile base",), ("human subjects",)
GAIN = Effect(0.0, "a gain (above 0 %)")
BELOW_100 = Effect(100.0, "a ratio below 100 %")


def _holds(*conds: bool) -> float:
    """1 where every condition holds, else 0."""
    return float(all(conds))


def _rho_order(r: Lookup) -> float:
    return _holds(*(r("ch3.table_3_1", f"ρ RHI at {p} (thesis configuration)") > max(
        r("ch3.table_3_1", f"ρ {d} at {p}") for d in ("PHANToM", "Rehab")) for p in (P1, P2)))


def _lambda_order(r: Lookup) -> float:
    return _holds(*(r("ch3.table_3_1", f"Λ RHI at {p} (thesis configuration)") < r("ch3.table_3_1", f"Λ PHANToM at {p}")
                    < r("ch3.table_3_1", f"Λ Rehab at {p}") for p in (P1, P2)))


def _t31(quantity: str) -> Callable[[Lookup], float]:
    return lambda r: r("ch3.table_3_1", quantity)


def _wf(r: Lookup) -> dict:
    return {k: r("ch3.psychophysics", f"WF mean, {d}") for k, d in (("rhi", "RHI"), ("ph", "PHANToM"), ("re", "Rehab"))}


_E47 = ("θz only", "l2, θz, Z_PH")


def _energy(r: Lookup) -> dict:
    return {f"{c}{i}": r("ch4.full_design", f"mean ‖q̇‖² A→B, {d}, {c}") for i, d in enumerate(_E47) for c in ("C1", "C2")}


def _energy_order(r: Lookup) -> float:
    e = _energy(r)
    return float(sum(e[f"C2{i}"] < e[f"C1{i}"] for i in range(len(_E47))))


def _reduction(r: Lookup, experiment: str, a: str, b: str) -> float:
    """100 (1 − a/b) [%] of two rows."""
    return 100.0 * (1.0 - r(experiment, a) / r(experiment, b))


def _beyond_b(claim: str, thesis: T.ThesisValue, quantity: str, line: str) -> Claim:
    """App. B's claim that beyond the workspace the proposed method lowers `quantity` by `thesis` % vs the traditional.

    `line` is the report's sentence, with {p} and {t} the proposed and the traditional values.
    """
    p, t = f"beyond, proposed: {quantity}", f"beyond, traditional: {quantity}"
    return Claim("App. B", claim, thesis, ("appb.tracking",), lambda r: _reduction(r, "appb.tracking", p, t), line,
                 BASE, effect=GAIN, details=lambda r: {"p": r("appb.tracking", p), "t": r("appb.tracking", t)})


def _mx(c: str, projector: str) -> Callable[[Lookup], float]:
    """Table 6.1's identified M_x for the desired FME `c` ("free" or "stiff") with the null-space `projector`."""
    quantity = f"M_x identified (eq. 3.24: M_x ẍ + Φ ẋ = F), M_{c.capitalize()}^des ({projector})"
    return lambda r: r("ch6.sysid_table_6_1", quantity)


def _mx_pinv(c: str) -> Callable[[Lookup], dict]:
    """The J⁺ identification beside the J# one, for the claim's reason."""
    pinv = _mx(c, "J⁺")
    return lambda r: {"pinv": pinv(r)}


def _transition(rows: tuple[str, str]) -> Callable[[Lookup], float]:
    """1 where Fig. 6.11's measure at the thesis's β = 20 is smaller with the method (rows[0]) than without."""
    return lambda r: _holds(r("ch6.transition", rows[0]) < r("ch6.transition", rows[1]))


def _transition_details(rows: tuple[str, str]) -> Callable[[Lookup], dict]:
    return lambda r: {"w": r("ch6.transition", rows[0]), "wo": r("ch6.transition", rows[1])}


_S2_LITERAL = "reading 'literal eq. 5.14': scenario 2's mean TME area below scenario 1's"
_DTAU = ("max per-tick ‖Δτ_N‖ of the applied null-space torque, with (β = 20)",
         "max per-tick ‖Δτ_N‖ of the applied null-space torque, without (β = 20)")
_DIST = ("max handle-force disturbance |F_sensor − F_commanded| along u, with (β = 20)",
         "max handle-force disturbance, without (β = 20)")
_BOX = "appa.box_push"
_WITHOUT, _WITH = "without DM (traditional J⁺)", "with DM (eq. A.19 as printed)"


def _saturation(r: Lookup, case: str) -> str:
    """Which joint of a box-push case saturates first, and when, in words."""
    j = r(_BOX, f"{case}: first arm joint to saturate")
    if j != j:
        return "no joint saturates"
    return f"joint {j:.0f} saturates first, at {r(_BOX, f'{case}: time the first joint saturates'):.2f} s"


_HUMAN = ("rests on the responses of 10 human subjects, which the thesis does not publish; rhi's simulated observers "
          "give {ours:.3g}")

CLAIMS: list[Claim] = [
    # ---- chapter 3
    Claim("Eq. 3.19", "the redundant 2-DoF prismatic robot's apparent inertia is smaller: |A2| ≤ |A1|",
          T.PRISMATIC_A2_BELOW_A1, ("ch3.apparent_inertia_example",),
          lambda r: r("ch3.apparent_inertia_example", "|A2| ≤ |A1| everywhere"),
          "|A2(jω)| ≤ |A1(jω)| at {frac:.1%} of the (M1, M2, B1, B2, ω) grid (max ratio {hi:.3f}); eqs. 3.17 and 3.19 "
          "agree with MuJoCo to {err:.1%}", K, shown="holds for every M, B, ω",
          details=lambda r: {"frac": r("ch3.apparent_inertia_example", "fraction of (M1, M2, B1, B2, ω)"),
                             "hi": r("ch3.apparent_inertia_example", "max |A2(jω)|/|A1(jω)|"),
                             "err": max(r("ch3.apparent_inertia_example", f"largest |A{i} MuJoCo") for i in (1, 2))}),
    Claim("Table 3.1", "ρ_RHI > ρ_PHANToM, ρ_Rehab at both points", T.TABLE_3_1_RHO_ORDER, ("ch3.table_3_1",),
          _rho_order, "at (0.49, −0.22): ρ_RHI {a:.3f}, ρ_PHANToM {b:.3f}, ρ_Rehab {c:.3f} m/s", K,
          details=lambda r: {"a": _t31(f"ρ RHI at {P1} (thesis configuration)")(r),
                             "b": _t31(f"ρ PHANToM at {P1}")(r), "c": _t31(f"ρ Rehab at {P1}")(r)},
          shown="holds at both points"),
    Claim("Table 3.1", "ρ_RHI = 0.371 m/s at (0.49, −0.22), thesis configuration", T.TABLE_3_1_RHO["RHI"][0],
          ("ch3.table_3_1",), _t31(f"ρ RHI at {P1} (thesis configuration)"),
          "at the printed q: {ours:.4f} m/s; at (0.49, −0.14) rhi gives {p2:.4f} (thesis 0.387), the Rehab's "
          "{re2:.5f} (thesis 0.315)", K,
          details=lambda r: {"p2": _t31(f"ρ RHI at {P2} (thesis configuration)")(r), "re2": _t31(f"ρ Rehab at {P2}")(r)}),
    Claim("Table 3.1", "Λ_RHI < Λ_PHANToM < Λ_Rehab at both points", T.TABLE_3_1_LAMBDA_ORDER, ("ch3.table_3_1",),
          _lambda_order, "at (0.49, −0.22): Λ_RHI {a:.4f}, Λ_PHANToM {b:.4f}, Λ_Rehab {c:.4f} kg", INR,
          details=lambda r: {"a": _t31(f"Λ RHI at {P1} (thesis configuration)")(r),
                             "b": _t31(f"Λ PHANToM at {P1}")(r), "c": _t31(f"Λ Rehab at {P1}")(r)},
          shown="holds at both points"),
    Claim("Table 3.1", "Λ_RHI = 0.0576 kg at (0.49, −0.22)", T.TABLE_3_1_LAMBDA["RHI"][0], ("ch3.table_3_1",),
          _t31(f"Λ RHI at {P1} (thesis configuration)"),
          "with rhi's estimated link inertias: {ours:.4f} kg; Λ_PHANToM {ph:.4f} (thesis 0.0628), Λ_Rehab {re:.4f} "
          "(thesis 0.4379)", INR,
          details=lambda r: {"ph": _t31(f"Λ PHANToM at {P1}")(r), "re": _t31(f"Λ Rehab at {P1}")(r)}),
    Claim("Fig. 3.8", "Remark I: ρ_r ≥ 1 over the common workspace", T.REMARK_I, ("ch3.ratio_maps",),
          lambda r: _holds(r("ch3.ratio_maps", "fraction of points with ρ_r ≥ 1") == 1.0),
          "ρ_r ≥ 1 at {frac:.1%} of rhi's grid; min ρ_r = {rho:.3f}", K,
          details=lambda r: {"rho": r("ch3.ratio_maps", "min ρ_r"),
                             "frac": r("ch3.ratio_maps", "fraction of points with ρ_r ≥ 1")},
          shown="holds everywhere"),
    Claim("Fig. 3.7", "Remark II: Λ_r ≤ 1 over the common workspace", T.REMARK_II, ("ch3.ratio_maps",),
          lambda r: _holds(r("ch3.ratio_maps", "fraction of points with Λ_r ≤ 1") == 1.0),
          "Λ_r ≤ 1 at {frac:.1%} of rhi's grid (max Λ_r = {lam:.3f}), the RHI at the eq. 3.22 optimum of each point, "
          "rhi's estimated inertias", INR,
          details=lambda r: {"lam": r("ch3.ratio_maps", "max Λ_r over"),
                             "frac": r("ch3.ratio_maps", "fraction of points with Λ_r ≤ 1")},
          shown="holds everywhere"),
    Claim("Table 3.2", "identified Λ ordered RHI ≤ PHANToM < Rehab", T.TABLE_3_2_ORDER, ("ch3.sysid_table_3_2",),
          lambda r: r("ch3.sysid_table_3_2", "cases with identified Λ ordered"),
          "identified by least squares on the simulated plant (eq. 3.24); Λ_RHI/Λ_PHANToM = {r1:.3f} and {r2:.3f} "
          "at the two points", PLANT, points=2,
          details=lambda r: {f"r{i + 1}": r("ch3.sysid_table_3_2", f"ratio Λ_RHI/Λ_PHANToM identified at point {i + 1}")
                             for i in (0, 1)}),
    Claim("Table 3.3", "mean WF: RHI < PHANToM < Rehab", T.TABLE_3_3_WF_ORDER, ("ch3.psychophysics",),
          lambda r: _holds(_wf(r)["rhi"] < _wf(r)["ph"] < _wf(r)["re"]),
          "rests on 10 human subjects whose responses the thesis does not publish; rhi's simulated observers give "
          "{rhi:.3f} / {ph:.3f} / {re:.3f}", HUMAN, details=_wf, shown="holds"),
    Claim("Table 3.3", "device effect on WF, one-way ANOVA p = 0.0032", T.ANOVA_3_6[1], ("ch3.psychophysics",),
          lambda r: r("ch3.psychophysics", "one-way ANOVA on WF: p"), _HUMAN, HUMAN),
    Claim("§3.6", "RHI vs PHANToM WF not significant, p = 0.2958", T.PAIRED_3_6["RHI", "PHANToM"],
          ("ch3.psychophysics",), lambda r: r("ch3.psychophysics", "paired t-test on WF RHI vs PHANToM"),
          _HUMAN, HUMAN),
    # ---- chapter 4
    Claim("§4.4", "θz = 89° maximises C1 (D = {θz})", T.THETA_Z["C1"], ("ch4.theta_z_design",),
          lambda r: r("ch4.theta_z_design", "θz maximising C1"),
          "rhi's C1 is largest at θz = {ours:.1f}°", K),
    Claim("§4.4", "θz = 2° maximises C2 (D = {θz})", T.THETA_Z["C2"], ("ch4.theta_z_design",),
          lambda r: r("ch4.theta_z_design", "θz maximising C2"),
          "rhi's C2 is largest at θz = {ours:.1f}°", K),
    Claim("Table 4.1", "C2 design: l2 = 0.269 m", T.TABLE_4_1["C2"]["l2"], ("ch4.full_design",),
          lambda r: r("ch4.full_design", "l2"),
          "rhi's C2 optimum has l2 = {ours:.3f} m; GM_T rises with l2 in rhi's set-up (table 'GM_T vs l2')", K),
    Claim("Table 4.1", "GM_T = 0.0590 at the thesis's C2 design", T.TABLE_4_1["C2"]["GM_T"], ("ch4.full_design",),
          lambda r: r("ch4.full_design", "GM_T at the thesis's C2 design"),
          "scored at the thesis's C2 design: {ours:.4f}", K),
    Claim("Fig. 4.7", "C2's joint energy A→B is much smaller than C1's (both rounds)", T.ENERGY_ORDER_4_7,
          ("ch4.full_design",), _energy_order,
          "mean ‖q̇‖² C2 vs C1: {C20:.3g} vs {C10:.3g} (θz only), {C21:.3g} vs {C11:.3g} (l2, θz, Z_PH)", K,
          details=_energy, points=2),
    # ---- chapter 5
    Claim("§5.4.1", "TMI null-space control increases the TME area by 18.1 %", T.TME_INCREASE, ("ch5.fixed_point",),
          lambda r: r("ch5.fixed_point", "TME area increase by the TMI"),
          "from §5.4.1's start q_i = [−0.63, 0.25, 0.28, 0.09]: {ours:+.1f} %", K, effect=GAIN),
    Claim("§5.4.1", "scenario 2's mean TME area 15.3 % below scenario 1's", T.S2_BELOW_S1, ("ch5.w_trajectory",),
          lambda r: r("ch5.w_trajectory", _S2_LITERAL),
          "eq. 5.14 as printed (τ_N = α ∂μ/∂q, plain J) along rhi's W (the thesis's is only drawn): {ours:+.1f} %; "
          "rhi's joint-limit-penalised variant {pen:+.1f} %", K, effect=GAIN,
          details=lambda r: {"pen": r("ch5.w_trajectory", "scenario 2's mean TME area below")},
          variant="eq. 5.14 as printed; the penalised-J^q variant is in the dossier"),
    Claim("Fig. 5.6", "user's effort (eq. 5.15): scenario 1 < 2 < 3", T.EFFORT_ORDER, ("ch5.w_trajectory",),
          lambda r: r("ch5.w_trajectory", "effort order 1 < 2 < 3"),
          "simulated hand on the W: user work {w1:.4g} / {w2:.4g} / {w3:.4g} J", PLANT,
          details=lambda r: {f"w{i}": r("ch5.w_trajectory", f"user work over the W, scenario {i}") for i in (1, 2, 3)}),
    Claim("Fig. 5.4", "the RHI's workspace is larger than the Rehab's", T.WORKSPACE_LARGER, ("ch5.workspaces",),
          lambda r: r("ch5.workspaces", "RHI workspace larger than the Rehab's"),
          "workspace areas by sampling rhi's models within the §5.4 joint limits", K),
    # ---- chapter 6
    Claim("Fig. 6.6", "the ASO V spans [0, 1]: 1 at zero torque, 0 at saturation (S = 50)", T.ASO_SPAN_6_6,
          ("ch6.aso_example",), lambda r: r("ch6.aso_example", "V spans [0, 1]"),
          "V(0) = {v0:.6f}, max V on the box's edges {edge:.3g}, V at half the limits {half:.3f}", K,
          details=lambda r: {"v0": r("ch6.aso_example", "V at τ = 0"), "edge": r("ch6.aso_example", "max V on"),
                             "half": r("ch6.aso_example", "V at half")}, shown="holds"),
    Claim("§6.3.1", "FME eigenvalue λ_max = 5.8 at the 3-DoF example's start", T.EIG_3DOF[1], ("ch6.example_3dof",),
          lambda r: r("ch6.example_3dof", "λ_max of M̂"), "{ours:.3f} from the thesis's kinematics and torque limits", K),
    Claim("§6.4", "𝒦 = 123 at q = 0 (μ = 5)", T.K_ZETA_6_4[0], ("ch6.palpation",),
          lambda r: r("ch6.palpation", "𝒦 (μ λ_max at q = 0)"), "{ours:.1f} from the kinematics and torque limits", K),
    Claim("§6.4", "M_Stiff gives 51 % more force than M_Free", T.GAIN_6_4, ("ch6.palpation",),
          lambda r: r("ch6.palpation", "force gain M_Stiff vs M_Free, simulated sensor peak"),
          "simulated palpation with J#: {ours:+.1f} %; static force scaling at the settled configurations {fs:+.1f} %",
          PLANT, effect=GAIN,
          details=lambda r: {"fs": r("ch6.palpation", "force gain, force scaling at the settled")}),
    Claim("Table 6.1", "F_max with M_Free^des = −5.674 N", T.TABLE_6_1["free"][2], ("ch6.palpation",),
          lambda r: r("ch6.palpation", "F_max along u, M_Free^des: simulated F/T sensor peak"),
          "simulated palpation with J#: {ours:.3f} N; static force scaling at the settled configuration {fs:.3f} N",
          PLANT, details=lambda r: {"fs": r("ch6.palpation", "F_max along u, M_Free^des: force scaling at the settled")}),
    Claim("Table 6.1", "F_max with M_Stiff^des = −8.564 N", T.TABLE_6_1["stiff"][2], ("ch6.palpation",),
          lambda r: r("ch6.palpation", "F_max along u, M_Stiff^des: simulated F/T sensor peak"),
          "simulated palpation with J#: {ours:.3f} N; static force scaling at the settled configuration {fs:.3f} N",
          PLANT, details=lambda r: {"fs": r("ch6.palpation", "F_max along u, M_Stiff^des: force scaling at the settled")}),
    Claim("Table 6.1", "M_x(M_Stiff)/M_x(M_Free) = 0.125/0.036", T.MX_RATIO_6_1, ("ch6.sysid_table_6_1",),
          lambda r: r("ch6.sysid_table_6_1", "M_x ratio Stiff/Free, identified (J#)"),
          "identified on the simulated plant with J#: {ours:.3f}; with J⁺ {pinv:.3f}", PLANT,
          effect=Effect(1.0, "a ratio above 1"),
          details=lambda r: {"pinv": r("ch6.sysid_table_6_1", "M_x ratio Stiff/Free, identified (J⁺)")},
          shown="3.47 (0.125/0.036)"),
    *[Claim("Table 6.1", f"M_x(M_{c.capitalize()}^des) = {T.TABLE_6_1[c][0].text} kg, identified", T.TABLE_6_1[c][0],
            ("ch6.sysid_table_6_1",), _mx(c, "J#"),
            "identified on the simulated plant with J# (the text's projector): {ours:.4f} kg; with J⁺: {pinv:.4f} kg",
            PLANT, details=_mx_pinv(c),
            variant="J# as the text names it; the J⁺ variant is in the dossier")
      for c in ("free", "stiff")],
    Claim("§6.5", "the M_Free → M_Stiff transition takes 0.5 s", T.TRANSITION_TIME, ("ch6.transition",),
          lambda r: r("ch6.transition", "full transition time"),
          "ρ‖M_Free − M_Stiff‖_F with the thesis's ρ = 0.003 (this is how the thesis defines the 0.5 s)", K),
    Claim("Fig. 6.10", "F_max(M_Stiff) > F_max(M_Free) over the entire workspace", T.FMAX_ENTIRE_6_10,
          ("ch6.fmax_ratio_map",),
          lambda r: _holds(r("ch6.fmax_ratio_map", "fraction of points with F_max(M_Stiff) > F_max(M_Free)") == 1.0),
          "larger at {frac:.1%} of the grid; min ratio {lo:.2f}, median {med:.2f}", K,
          details=lambda r: {"frac": r("ch6.fmax_ratio_map", "fraction of points with F_max(M_Stiff) > F_max(M_Free)"),
                             "lo": r("ch6.fmax_ratio_map", "min ratio F_Stiff/F_Free"),
                             "med": r("ch6.fmax_ratio_map", "median ratio, force scaling")}),
    Claim("Fig. 6.11", "the transition method prevents the control-effort jump (β = 20)", T.EFFORT_6_11,
          ("ch6.transition",), _transition(_DTAU),
          "max per-tick ‖Δτ_N‖ {w:.2f} N m with the method, {wo:.2f} without", PLANT, details=_transition_details(_DTAU)),
    Claim("Fig. 6.11", "with it the internal motion disturbs the handle force less (β = 20)", T.INTERFERENCE_6_11,
          ("ch6.transition",), _transition(_DIST),
          "max handle-force disturbance {w:.1f} N with the method, {wo:.1f} N without", PLANT,
          details=_transition_details(_DIST)),
    # ---- chapter 7
    Claim("Fig. 7.1", "simple scaling gives 12 % less force than ASCM", T.SCALING_GAP, ("ch7.example_3dof",),
          lambda r: r("ch7.example_3dof", "peak force deficit of scaling vs ASCM (dynamic"),
          "with J# (the text's projector, rhi's planar3r masses): {ours:.1f} %; with the plain pseudoinverse J⁺: "
          "{pinv:.1f} %", INR, effect=GAIN,
          details=lambda r: {"pinv": r("ch7.example_3dof", "peak force deficit of scaling vs ASCM (pseudoinverse")},
          variant="J# as the text names it; the J⁺ variant is in the dossier"),
    Claim("Fig. 7.1(c)", "two joints are saturated when ASCM starts scaling", T.HELD_AT_SCALING,
          ("ch7.example_3dof",), lambda r: r("ch7.example_3dof", "joints at a torque limit when ASCM first scales"),
          "Algorithm 1 on the thesis's 3-DoF example: {ours:.0f} joints", K, shown="2 joints"),
    Claim("§7.5", "ASCM gives 73 % more palpation force than no compensation", T.GAIN_7_5, ("ch7.palpation",),
          lambda r: r("ch7.palpation", "peak force before a joint range limit, ascm (dynamic) vs none (dynamic)"),
          "peak force before a joint range limit, J#: ASCM {ours:+.1f} %, the LP allocation {lp:+.1f} %; static "
          "capability at the contact configuration {stat:+.1f} % with J#, {pinv:+.0f} % with J⁺", PLANT, effect=GAIN,
          details=lambda r: {"stat": r("ch7.palpation", "static gain of ASCM over scaling (dynamic J#)"),
                             "pinv": r("ch7.palpation", "static gain of ASCM over scaling (pseudoinverse J⁺)"),
                             "lp": r("ch7.palpation", "peak force before a joint range limit, lp (dynamic) vs none")}),
    # ---- appendix A
    Claim("Table A.1", "RMS v_xb, proposed / traditional = 65.12 %", T.RMS_RATIO_A[0], ("appa.tracking",),
          lambda r: r("appa.tracking", "RMS v_xb proposed / traditional"),
          "RMS v_xb {p:.3g} cm/s proposed, {t:.3g} traditional (thesis 1.68, 2.58)", BASE, effect=BELOW_100,
          details=lambda r: {"p": r("appa.tracking", "proposed: RMS v_xb"), "t": r("appa.tracking", "traditional: RMS v_xb")}),
    Claim("Table A.1", "RMS ω_b, proposed / traditional = 6.94 %", T.RMS_RATIO_A[2], ("appa.tracking",),
          lambda r: r("appa.tracking", "RMS ω_b proposed / traditional"),
          "RMS ω_b {p:.3g} °/s proposed, {t:.3g} traditional (thesis 0.035, 0.504)", BASE, effect=BELOW_100,
          details=lambda r: {"p": r("appa.tracking", "proposed: RMS ω_b"), "t": r("appa.tracking", "traditional: RMS ω_b")}),
    Claim("Fig. A.6", "the base moves first at 7.15 s (proposed)", T.BASE_INTERVAL_A[0], ("appa.tracking",),
          lambda r: r("appa.tracking", "proposed: base first commanded"),
          "the proposed controller first commands the base at {ours:.2f} s on the 0.25 m circle", BASE,
          absent="never reached"),
    Claim("§A.4.3", "DM along z at q0 = 1.125", T.DM_Z[0], ("appa.dm_enhancement",),
          lambda r: r("appa.dm_enhancement", "DM along z at q0"),
          "rhi's Gen3 model (Kinova's published lengths) at the stated q0: {ours:.4f}", K),
    Claim("§A.4.3", "DM enhancement along z: 1.125 → 4.031", T.DM_Z[1], ("appa.dm_enhancement",),
          lambda r: r("appa.dm_enhancement", "DM along z after enhancement, eq. A.19 as printed"),
          "eq. A.19 as printed (weighted J†): {ours:.3f} after the stated phases with the stated gains; with the "
          "orthogonal projector {ortho:.3f}; the gradient ascent raises DM by construction, so only the size is "
          "judged", BASE,
          details=lambda r: {"ortho": r("appa.dm_enhancement", "DM along z after enhancement (t")},
          variant="eq. A.19 as printed; the orthogonal-projector variant is in the dossier"),
    Claim("§A.4.3", "DM enhancement along x: 3.825 → 5.88", T.DM_X[2], ("appa.dm_enhancement",),
          lambda r: r("appa.dm_enhancement", "DM along x after the null-space phase, eq. A.19 as printed"),
          "eq. A.19 as printed (weighted J†): {ours:.3f}; with the orthogonal projector {ortho:.3f}; the gradient "
          "ascent raises DM by construction, so only the size is judged", BASE,
          details=lambda r: {"ortho": r("appa.dm_enhancement", "DM along x after the null-space phase (t")},
          variant="eq. A.19 as printed; the orthogonal-projector variant is in the dossier"),
    Claim("Fig. A.8", "without DM enhancement joint 4 is the one that saturates in the box push",
          T.PUSH_JOINT4_FIRST, (_BOX,), lambda r: _holds(r(_BOX, f"{_WITHOUT}: first arm joint to saturate") == 4),
          "on the MuJoCo plant, pushing the 26 kg box (μ = {mu:.3f}, appa.box_push's readings) with the traditional "
          "J⁺: {sat}; the largest |τ_4| is {t4:.1f} N m (thesis: joint 4 at 23 s)", BASE, shown="joint 4",
          details=lambda r: {"mu": r(_BOX, "box–floor friction μ"), "sat": _saturation(r, _WITHOUT),
                             "t4": r(_BOX, f"{_WITHOUT}: largest |τ_4|")}),
    Claim("Fig. A.8", "with DM enhancement no joint torque exceeds 20 N m in the box push", T.PUSH_WITHIN_20,
          (_BOX,), lambda r: _holds(r(_BOX, f"{_WITH}: largest arm joint torque during the push") <= 20.0),
          "on the MuJoCo plant, pushing the 26 kg box (μ = {mu:.3f}) after the DM enhancement (DM {dm:.3f} at the "
          "push's start): largest arm joint torque {top:.1f} N m; {sat}", BASE, shown="≤ 20 N m",
          details=lambda r: {"mu": r(_BOX, "box–floor friction μ"), "sat": _saturation(r, _WITH),
                             "top": r(_BOX, f"{_WITH}: largest arm joint torque during the push"),
                             "dm": r(_BOX, f"{_WITH}: DM along x at the push's start")},
          variant="eq. A.19 as printed; the orthogonal projector, another μ and the static reading are in the dossier"),
    # ---- appendix B
    Claim("§B.4.2", "without avoidance the arm is singular at ≈ 8.35 s", T.SINGULAR_TIME_B, ("appb.singularity",),
          lambda r: r("appb.singularity", "without avoidance: first time σ_min"),
          "first time σ_min(J_m) < 0.05 (rhi's reading of 'singular'): {ours:.2f} s", BASE, absent="never reached"),
    Claim("§B.4.3", "beyond the workspace the base is enabled at 6.40 s", T.BASE_ON_B, ("appb.tracking",),
          lambda r: r("appb.tracking", "beyond, proposed: base first enabled"),
          "σ_min(J_m) first falls below σ_m,min = 0.15 at {ours:.2f} s", BASE, absent="never reached"),
    Claim("Table B.2", "within the workspace the base never moves (proposed)", T.BASE_PERIODS_B["within"],
          ("appb.tracking",), lambda r: r("appb.tracking", "within, proposed (σ_m,min = 0.150)"),
          "the base is enabled {ours:.0f} times; the best σ_min(J_m) the arm alone can have at the far point of the "
          "inner circle is {best:.3f} < σ_m,min = 0.15", BASE,
          details=lambda r: {"best": r("appb.tracking", "best σ_min(J_m) the arm alone")},
          shown="0 base activation periods"),
    _beyond_b("max tracking error beyond the workspace −63.3 % in x", T.ERROR_REDUCTION_B[0], "max tracking error x",
              "max error x {p:.2f} cm proposed, {t:.2f} traditional (thesis 2.44, 6.65)"),
    _beyond_b("max tracking error beyond the workspace −33.1 % in y", T.ERROR_REDUCTION_B[1], "max tracking error y",
              "max error y {p:.2f} cm proposed, {t:.2f} traditional (thesis 1.82, 2.72)"),
    _beyond_b("base motion time −84.90 % beyond the workspace", T.BASE_TIME_REDUCTION_B, "duration x_b",
              "the base runs {p:.2f} s proposed, {t:.2f} s traditional (thesis 12.08, 80)"),
]
