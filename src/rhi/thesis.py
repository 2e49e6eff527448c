"""Every number the thesis publishes that rhi compares against, with its tolerance and its source.

The one place the thesis's numbers live (Torabiparizi 2020, `shared/seed`): the experiments put
them in their tables, the report's headline claims read them, the tests assert against them.

Each number is a `ThesisValue`: a `float` (so it enters arithmetic and `Row` like any number) that
also carries

- ``key``: a stable id, e.g. ``"table3_1.rho.RHI.0"`` (``get(key)`` returns the value);
- ``tol``: half a unit of the last digit the thesis prints (``"0.371"`` → ±0.0005, ``"89"`` → ±0.5),
  unless stated otherwise (a claim such as an ordering is exact: tol 0);
- ``unit``, ``source`` (table, figure or section, with the thesis line it is printed on);
- ``text``: the number as the thesis prints it (``printed(v)`` also rounds a derived value to its tolerance);
- ``relative``: whether a relative difference means something (not for p-values, angles,
  counts, orderings or values within a few roundings of zero).

Arithmetic on a `ThesisValue` returns a plain float, so a number derived from thesis values is not
a thesis value: it must be registered here too (``derived=``) to be compared in a report.
"""

from __future__ import annotations

import math

from rhi.errors import InvalidInput

_REGISTRY: dict[str, ThesisValue] = {}


class ThesisValue(float):
    """A thesis number: a float with key, tolerance [same unit], unit, source and whether relative differences mean something."""

    key: str
    text: str
    tol: float
    unit: str
    source: str
    relative: bool
    claim: bool

    def __new__(cls, text: str, key: str, unit: str, source: str, *, tol: float | None = None,
                relative: bool | None = None, claim: bool = False) -> ThesisValue:
        """A float with the thesis's key, unit, source and rounding tolerance."""
        self = super().__new__(cls, float(text))
        self.key, self.text, self.unit, self.source, self.claim = key, text, unit, source, claim
        self.tol = _rounding(text) if tol is None else float(tol)
        if relative is None:
            relative = not claim and unit not in ("deg", "rad", "p") and abs(float(self)) > 10 * self.tol
        self.relative = relative
        return self

    def __reduce__(self):  # unpickled as the registered value (process pools)
        return (get, (self.key,))

    def within(self, x: float) -> bool:
        """Whether `x` equals this value within its tolerance (the thesis's rounding)."""
        return bool(math.isfinite(x) and abs(x - float(self)) <= self.tol * (1 + 1e-9) + 1e-15)


def printed(v: ThesisValue) -> str:
    """The number as the thesis prints it ("0.0590", "-5.674"); a derived one to the digits its tolerance allows."""
    if not v.source.startswith("derived:"):
        return v.text
    if v.tol <= 0:
        return f"{float(v):g}"
    decimals = max(0, math.ceil(-math.log10(2 * v.tol)))
    return f"{float(v):.{decimals}f}"


def _rounding(text: str) -> float:
    """Half a unit of the last printed digit: "0.371" → 0.0005, "89" → 0.5, "3.61e-7" → 5e-10."""
    mant, _, exp = text.lower().partition("e")
    decimals = len(mant.split(".")[1]) if "." in mant else 0
    return 0.5 * 10.0 ** (-decimals + (int(exp) if exp else 0))


def _v(key: str, text: str, unit: str, source: str, **kw) -> ThesisValue:
    if key in _REGISTRY:
        raise InvalidInput(f"key: thesis value {key!r} registered twice")
    v = ThesisValue(text, key, unit, source, **kw)
    _REGISTRY[key] = v
    return v


def _claim(key: str, source: str) -> ThesisValue:
    """A yes/no or count statement of the thesis (1 = holds), compared exactly."""
    return _v(key, "1", "", source, tol=0.0, claim=True)


def _derived(key: str, value: float, tol: float, unit: str, source: str, **kw) -> ThesisValue:
    """A number computed from printed thesis values (tolerance propagated by the caller)."""
    return _v(key, repr(float(value)), unit, f"derived: {source}", tol=tol, **kw)


def get(key: str) -> ThesisValue:
    """The thesis value registered under `key`.

    Raises:
        InvalidInput: `key` is not registered.
    """
    try:
        return _REGISTRY[key]
    except KeyError:
        raise InvalidInput(f"key: no thesis value {key!r}") from None


def values() -> dict[str, ThesisValue]:
    """Every registered thesis value by key (a copy)."""
    return dict(_REGISTRY)


def is_registered(x: object) -> bool:
    """Whether `x` is a thesis value of this module (not a copy or a number derived outside it)."""
    return isinstance(x, ThesisValue) and _REGISTRY.get(x.key) is x


def _pair(key: str, texts: tuple[str, str], unit: str, source: str, **kw) -> tuple[ThesisValue, ThesisValue]:
    return tuple(_v(f"{key}.{i}", t, unit, source, **kw) for i, t in enumerate(texts))  # type: ignore[return-value]


# ---------------------------------------------------------------- chapter 3
_T31 = "Table 3.1 (thesis line 638)"
#: Table 3.1: effective manipulability ρ [m/s] along u = [0, 1] at (0.49, −0.22) and (0.49, −0.14).
TABLE_3_1_RHO = {d: _pair(f"table3_1.rho.{d}", t, "m/s", _T31)
                 for d, t in (("RHI", ("0.371", "0.387")), ("PHANToM", ("0.188", "0.167")), ("Rehab", ("0.296", "0.315")))}
#: Table 3.1: effective apparent inertia Λ [kg] at the same points.
TABLE_3_1_LAMBDA = {d: _pair(f"table3_1.lambda.{d}", t, "kg", _T31)
                    for d, t in (("RHI", ("0.0576", "0.0590")), ("PHANToM", ("0.0628", "0.0606")),
                                 ("Rehab", ("0.4379", "0.4414")))}
#: §3.5: the RHI configurations of Table 3.1 (optimum of eq. 3.22) [rad].
TABLE_3_1_Q = tuple(tuple(_v(f"table3_1.q.{i}.{k}", t, "rad", "§3.5 text below Table 3.1 (line 648)")
                          for k, t in enumerate(qs))
                    for i, qs in enumerate((("0.125", "0.022", "0.298", "0.175"), ("0.298", "0.077", "0.413", "0.208"))))
#: Table 3.1 / §3.5: ρ_RHI > ρ_PHANToM, ρ_Rehab and Λ_RHI < Λ_PHANToM < Λ_Rehab at both points.
TABLE_3_1_RHO_ORDER = _claim("table3_1.rho_order", "Table 3.1, §3.5: ρ_RHI larger than the PHANToM's and the Rehab's")
TABLE_3_1_LAMBDA_ORDER = _claim("table3_1.lambda_order", "Table 3.1, §3.5: Λ_RHI < Λ_PHANToM < Λ_Rehab")
#: Remark I (§3.3, eq. 3.10), Fig. 3.8: ρ_r = ρ_RHI/ρ_PHANToM ≥ 1 at every point of the common workspace.
REMARK_I = _claim("fig3_8.rho_r", "§3.3 Remark I (eq. 3.10), Fig. 3.8 (line 672): ρ_r ≥ 1 everywhere")
#: Remark II (§3.3, eq. 3.15), Fig. 3.7: Λ_r = Λ_RHI/Λ_PHANToM ≤ 1 at every point of the common workspace.
REMARK_II = _claim("fig3_7.lambda_r", "§3.3 Remark II (eq. 3.15), Fig. 3.7 (line 672): Λ_r ≤ 1 everywhere")
#: §3.3 eqs. 3.16–3.19, Figs 3.2–3.3: the redundant 2-DoF prismatic robot's apparent inertia is smaller than the
#: 1-DoF robot's ("As |(B2/s + M2)/(B1/s + B2/s + M2)| ≤ 1, ... smaller").
PRISMATIC_A2_BELOW_A1 = _claim("eq3_19.a2_below_a1", "§3.3 eqs. 3.16–3.19, Figs 3.2–3.3 (line 550): |A2| ≤ |A1|")
#: Table 3.2: identified Λ [kg] along u at the two points.
TABLE_3_2 = {d: _pair(f"table3_2.{d}", t, "kg", "Table 3.2 (line 652)")
             for d, t in (("RHI", ("0.0691", "0.0718")), ("PHANToM", ("0.0734", "0.0728")), ("Rehab", ("0.5399", "0.5683")))}


def _ratio(key: str, a: ThesisValue, b: ThesisValue, source: str) -> ThesisValue:
    """a/b of two printed values, with their roundings propagated (first order)."""
    r = float(a) / float(b)
    return _derived(key, r, r * (a.tol / abs(float(a)) + b.tol / abs(float(b))), "", f"{a.key} / {b.key}, {source}")


#: Table 3.2: ratios of identified Λ between devices at each point, (a, b, point) → Λ_a/Λ_b.
TABLE_3_2_RATIO = {(a, b, i): _ratio(f"table3_2.ratio.{a}/{b}.{i}", TABLE_3_2[a][i], TABLE_3_2[b][i], "Table 3.2")
                   for a, b in (("RHI", "PHANToM"), ("RHI", "Rehab")) for i in (0, 1)}
#: §3.5 / Table 3.2: identified Λ ordered RHI ≤ PHANToM < Rehab at both points.
TABLE_3_2_ORDER = _v("table3_2.order", "2", "", "Table 3.2: the ordering holds at both points", tol=0.0, claim=True)
_T33 = "Table 3.3 (line 691)"
#: Table 3.3: (mean, std) of WF [1], JND [N/m] and PSE [N/m] per device (10 human subjects).
TABLE_3_3 = {
    m: {d: _pair(f"table3_3.{m}.{d}", t, u, _T33) for d, t in vals.items()}
    for m, u, vals in (
        ("wf", "", {"RHI": ("0.111", "0.019"), "PHANToM": ("0.118", "0.021"), "Rehab": ("0.145", "0.021")}),
        ("jnd", "N/m", {"RHI": ("5.571", "0.916"), "PHANToM": ("5.953", "1.068"), "Rehab": ("7.205", "1.024")}),
        ("pse", "N/m", {"RHI": ("50.035", "0.578"), "PHANToM": ("50.238", "1.695"), "Rehab": ("49.654", "1.267")}),
    )
}
#: Table 3.3 / §3.6: mean WF RHI < PHANToM < Rehab.
TABLE_3_3_WF_ORDER = _claim("table3_3.wf_order", "Table 3.3, §3.6: mean WF of the RHI < PHANToM's < Rehab's")
#: §3.6: one-way ANOVA on WF, F(2, 27) = 7.36, p = 0.0032.
ANOVA_3_6 = (_v("s3_6.anova.F", "7.36", "", "§3.6 (line 699)", relative=False),
             _v("s3_6.anova.p", "0.0032", "p", "§3.6 (line 699)"))
#: §3.6: Holm-adjusted paired t-tests on WF (p).
PAIRED_3_6 = {pair: _v(f"s3_6.paired.{pair[0]}-{pair[1]}", t, "p", "§3.6 (line 699)")
              for pair, t in ((("RHI", "PHANToM"), "0.2958"), (("RHI", "Rehab"), "0.00002"), (("PHANToM", "Rehab"), "0.0075"))}

# ---------------------------------------------------------------- chapter 4
_U4 = "m²/s²·(s/rad)²"
#: §4.4 first round (D = {θz}): θz [deg] maximising C1 and C2 (Fig. 4.4).
THETA_Z = {c: _v(f"s4_4.theta_z.{c}", t, "deg", "§4.4, Fig. 4.4 caption (line 927)") for c, t in (("C1", "89"), ("C2", "2"))}
#: §4.4 first round: GM_T and GM_M at those optima.
GM_T_ROUND1 = {c: _v(f"s4_4.GM_T.{c}", t, _U4, "§4.4 first round") for c, t in (("C1", "0.0378"), ("C2", "0.0437"))}
GM_M_ROUND1 = {c: _v(f"s4_4.GM_M.{c}", t, _U4, "§4.4 first round") for c, t in (("C1", "0.0433"), ("C2", "0.0428"))}
_T41 = "Table 4.1 (line 929)"
_T41_UNITS = {"l2": "m", "z_ph": "m", "theta_z": "deg", "GM_T": "", "GC_M": "", "GM_M": ""}
#: Table 4.1 (D = {l2, θz, Z_PH}): the C1 and C2 designs and their indices.
TABLE_4_1 = {
    c: {k: _v(f"table4_1.{c}.{k}", t, _T41_UNITS[k], _T41) for k, t in vals.items()}
    for c, vals in (
        ("C1", {"l2": "0.365", "z_ph": "-0.2162", "theta_z": "-63.5", "GM_T": "0.0549", "GC_M": "0.7785", "GM_M": "0.1023"}),
        ("C2", {"l2": "0.269", "z_ph": "-0.065", "theta_z": "0", "GM_T": "0.0590", "GC_M": "0.7315", "GM_M": "0.0728"}),
    )
}

#: §4.4, Fig. 4.7: the joint energy A→B is "much smaller" where C2 is optimised, in both rounds (D = {θz} and
#: D = {l2, θz, Z_PH}): C2's below C1's at 2 design rounds.
ENERGY_ORDER_4_7 = _v("fig4_7.energy_order", "2", "", "§4.4, Fig. 4.7 (line 968): C2's joint energy is much smaller",
                      tol=0.0, claim=True)

# ---------------------------------------------------------------- chapter 5
#: §5.4.1: TME area increase by the TMI null-space controller at the fixed point [%].
TME_INCREASE = _v("s5_4_1.tme_increase", "18.1", "%", "§5.4.1, Fig. 5.3 (line 1121)")
#: §5.4.1: mean TME area of scenario 2 (RHI + its own manipulability optimiser).
MEAN_TME_S2 = _v("s5_4_1.mean_tme_s2", "0.1034", "m²/s² per (rad/s)²", "§5.4.1, Fig. 5.5 (line 1134)")
#: §5.4.1: scenario 2's mean TME area below scenario 1's [%].
S2_BELOW_S1 = _v("s5_4_1.s2_below_s1", "15.3", "%", "§5.4.1 (line 1134)")
#: Scenario 1's mean TME area, from the two numbers above.
MEAN_TME_S1 = _derived("s5_4_1.mean_tme_s1", float(MEAN_TME_S2) / (1 - float(S2_BELOW_S1) / 100),
                       float(MEAN_TME_S2) / (1 - float(S2_BELOW_S1) / 100) * (0.00005 / 0.1034 + 0.0005 / 0.847),
                       "m²/s² per (rad/s)²", "0.1034 / (1 − 0.153), §5.4.1")
_T51 = "Table 5.1 (line 1193)"
#: Table 5.1 means per scenario: effort [kg m²/s²], completion time [s], trajectory error [mm].
TABLE_5_1 = {m: tuple(_v(f"table5_1.{m}.{i}", t, u, _T51) for i, t in enumerate(ts))
             for m, u, ts in (("effort", "kg m²/s²", ("0.207", "0.425", "2.048")), ("time", "s", ("48.8", "54.3", "62.3")),
                              ("error", "mm", ("105.0", "126.5", "129.2")))}
#: Table 5.1: effort of scenarios 2 and 3 over scenario 1's.
EFFORT_RATIO_5_1 = tuple(_ratio(f"table5_1.effort_ratio.{k}", TABLE_5_1["effort"][k], TABLE_5_1["effort"][0], "Table 5.1")
                         for k in (1, 2))
#: Table 5.1 / §5.4.2: effort in scenario 1 < 2 < 3.
EFFORT_ORDER = _claim("table5_1.effort_order", "Fig. 5.6, §5.4.1 (line 1163; simulation, eq. 5.15): user's effort "
                      "scenario 1 < 2 < 3 (Table 5.1 prints the same order for the human study)")
#: §5.4.2: one-way ANOVAs (F, p) on effort, time and error, F(2, 21).
ANOVA_5 = {m: (_v(f"s5_4_2.anova.{m}.F", f, "", "§5.4.2 (lines 1188–1211)", relative=False),
               _v(f"s5_4_2.anova.{m}.p", p, "p", "§5.4.2 (lines 1188–1211)"))
           for m, f, p in (("effort", "32.63", "3.61e-7"), ("time", "3.57", "0.046"), ("error", "0.55", "0.583"))}
#: Table 5.2: FDR-adjusted p of the paired t-tests on completion time.
TABLE_5_2 = {pair: _v(f"table5_2.{pair[0]}<{pair[1]}", t, "p", "Table 5.2 (line 1200)")
             for pair, t in (((1, 2), "0.0245"), ((1, 3), "0.00039"), ((2, 3), "0.0012"))}
#: Fig. 5.4 / §5.4.1: the RHI's workspace is larger than the Rehab's; the W lies inside both.
WORKSPACE_LARGER = _claim("fig5_4.rhi_larger", "Fig. 5.4, §5.4.1: RHI workspace larger than the Rehab's")
W_INSIDE = _claim("fig5_4.w_inside", "§5.4.2: the W trajectory is performed by every HI")

# ---------------------------------------------------------------- chapter 6
#: §6.3.1 / Fig. 6.3: eigenvalues of the 3-DoF RHI's FME at the initial configuration.
EIG_3DOF = _pair("s6_3_1.eig", ("2.6", "5.8"), "N²/(N m)²", "§6.3.1 (line 1337)")
#: §6.3.1: amplitude of the environment force F_e = [3.5 sin(tπ/2), 0] N, rendered in full at M_Stiff^des.
F_E_3DOF = _v("s6_3_1.F_e", "3.5", "N", "§6.3.1 (line 1337)")
#: The desired FMEs of Fig. 6.3 with μ = 5: 𝒦 = μ λ_max = 29, ζ = λ_min/μ = 0.52.
K_3DOF = _derived("s6_3_1.K", 5 * float(EIG_3DOF[1]), 5 * 0.05, "N²/(N m)²", "5 × 5.8, §6.3.1")
ZETA_3DOF = _derived("s6_3_1.zeta", float(EIG_3DOF[0]) / 5, 0.05 / 5, "N²/(N m)²", "2.6 / 5, §6.3.1")
#: §6.4: 𝒦 and ζ of the 4-DoF RHI at q = 0 (μ = 5).
K_ZETA_6_4 = (_v("s6_4.K", "123", "N²/(N m)²", "§6.4 (line 1414)"), _v("s6_4.zeta", "3.3", "N²/(N m)²", "§6.4 (line 1414)"))
_T61 = "Table 6.1 (line 1442)"
#: Table 6.1: (M_x [kg], Φ [N s/m], F_max [N]) along u at [0.5, 0.1] m for M_Free and M_Stiff.
TABLE_6_1 = {c: tuple(_v(f"table6_1.{c}.{k}", t, u, _T61) for k, u, t in zip(("M_x", "Phi", "F_max"), ("kg", "N s/m", "N"), ts))
             for c, ts in (("free", ("0.036", "0.2953", "-5.674")), ("stiff", ("0.125", "0.6325", "-8.564")))}
#: Table 6.1: M_x and Φ ratios stiff/free.
MX_RATIO_6_1 = _ratio("table6_1.M_x_ratio", TABLE_6_1["stiff"][0], TABLE_6_1["free"][0], "Table 6.1")
PHI_RATIO_6_1 = _ratio("table6_1.Phi_ratio", TABLE_6_1["stiff"][1], TABLE_6_1["free"][1], "Table 6.1")
#: §6.4: force feedback gain of M_Stiff over M_Free [%].
GAIN_6_4 = _v("s6_4.gain", "51", "%", "§6.4, Fig. 6.9 (line 1428)")
#: §6.5: duration of the M_Free → M_Stiff transition [s] ("performed in 0.5 second").
TRANSITION_TIME = _v("s6_5.t_f", "0.5", "s", "§6.5 (line 1462)")

#: §6.3.2, Fig. 6.6: the ASO V of eq. 6.14 spans [0, 1] over the torque box of a 2-DoF robot (|T1| ≤ 0.5 N m,
#: |T2| ≤ 2 N m, S = 50): 1 at zero torque, 0 at saturation.
ASO_SPAN_6_6 = _claim("fig6_6.aso_span", "§6.3.2, Fig. 6.6 (line 1364): V spans [0, 1], 0 at saturation")
#: §6.4, Fig. 6.10: F_max with the M_Stiff^des configuration larger than with M_Free^des "over the entire workspace".
FMAX_ENTIRE_6_10 = _claim("fig6_10.entire", "§6.4, Fig. 6.10 (line 1459): larger over the entire workspace")
#: §6.4, Fig. 6.11: the transition method prevents the discontinuity in the control effort (per-tick jump of the
#: null-space torque smaller with it) ...
EFFORT_6_11 = _claim("fig6_11.effort", "§6.4, Fig. 6.11 (line 1469): the method prevents the control-effort "
                                       "discontinuity")
#: ... and so the interference of the internal motion with the handle's force (disturbance smaller with it).
INTERFERENCE_6_11 = _claim("fig6_11.interference", "§6.4, Fig. 6.11(a–b) (line 1469): less interference of the "
                                                   "internal motion with the handle force")

# ---------------------------------------------------------------- chapter 7
#: §7.3 / Fig. 7.1: simple scaling's peak force below ASCM's [%].
SCALING_GAP = _v("fig7_1.scaling_gap", "12", "%", "§7.3, Fig. 7.1 (line 1627)")
#: Fig. 7.1(c): two joints saturated when ASCM starts scaling.
HELD_AT_SCALING = _v("fig7_1.held", "2", "", "§7.3, Fig. 7.1(c) (line 1627)", tol=0.0, claim=True)
#: §7.5 / Fig. 7.6: palpation force gain of ASCM over no compensation [%].
GAIN_7_5 = _v("s7_5.gain", "73", "%", "§7.5, Fig. 7.6 (line 1714)")

# ---------------------------------------------------------------- appendix A
_TA1 = "Table A.1 (line 2161)"
#: Table A.1: (max, RMS) of commanded v_xb, v_yb [cm/s] and ω_b [°/s] per method.
TABLE_A_1 = {
    m: {s: tuple(_v(f"tableA_1.{m}.{s}.{c}", t, u, _TA1) for c, u, t in zip(("vx", "vy", "w"), ("cm/s", "cm/s", "°/s"), ts))
        for s, ts in vals.items()}
    for m, vals in (("proposed", {"max": ("2.8", "1.72", "0.0917"), "rms": ("1.68", "0.65", "0.035")}),
                    ("traditional", {"max": ("3.91", "2.38", "0.882"), "rms": ("2.58", "1.42", "0.504")}))
}
#: §A.4.2: max tracking error (x, y) [cm] per method.
ERROR_A = {m: _pair(f"sA_4_2.err.{m}", t, "cm", "§A.4.2 (line 2194)")
           for m, t in (("proposed", ("2.71", "1.88")), ("traditional", ("7.25", "2.71")))}
#: §A.4.2: RMS base commands proposed / traditional for x_b, y_b, θ_b [%].
RMS_RATIO_A = tuple(_v(f"sA_4_2.rms_ratio.{c}", t, "%", "§A.4.2 (line 2194)")
                    for c, t in zip(("vx", "vy", "w"), ("65.12", "45.77", "6.94")))
#: §A.4.2 / Fig. A.6: the proposed method's base moves only during 7.15–20.35 s.
BASE_INTERVAL_A = _pair("sA_4_2.base_interval", ("7.15", "20.35"), "s", "§A.4.2, Fig. A.6 (line 2194)", relative=False)
#: §A.4.2: "the maximum radius of the circle within the manipulator workspace at this initial position is only 0.11 m".
WORKSPACE_RADIUS_A = _v("sA_4_2.workspace_radius", "0.11", "m", "§A.4.2 (line 2172)")
#: §B.4.2: the 0.25 m radius "is beyond the manipulator workspace (0.2 m) at its initial configuration".
WORKSPACE_RADIUS_B = _v("sB_4_2.workspace_radius", "0.2", "m", "§B.4.2 (line 2479)")
_A43 = "§A.4.3 (lines 2202–2212)"
#: §A.4.3: DM along z before/after enhancement [N], and ‖W_τ τ‖ for a 10 N z force before/after [N m].
DM_Z = _pair("sA_4_3.dm_z", ("1.125", "4.031"), "N", _A43)
TAU_Z = _pair("sA_4_3.tau_z", ("8.89", "2.48"), "N m", _A43)
#: §A.4.3: DM along x at q0, after the Cartesian phase, after the null-space phase [N]; z after the Cartesian phase [m].
DM_X = tuple(_v(f"sA_4_3.dm_x.{i}", t, "N", _A43) for i, t in enumerate(("3.825", "3.905", "5.88")))
Z_AFTER_CARTESIAN = _v("sA_4_3.z_cart", "0.456", "m", _A43)
#: §A.4.3: ‖W_τ τ‖ during the push, ≈ 40 N m without and ≈ 30 N m with DM enhancement: their ratio.
TAU_RATIO_PUSH = _derived("sA_4_3.tau_ratio", 40 / 30, 40 / 30 * (5 / 40 + 5 / 30), "", "“almost 40” / “about 30” N m, §A.4.3")
#: Fig. A.8: without DM enhancement joint four saturated (at 23 s); with it the largest joint torque stayed ≤ 20 N m.
PUSH_JOINT = _v("sA_4_3.push_joint", "4", "", "§A.4.3, Fig. A.8 (line 2210)", tol=0.0, relative=False)
PUSH_MAX_TORQUE = _v("sA_4_3.push_max_torque", "20", "N m", "§A.4.3, Fig. A.8 (line 2210)")
PUSH_SATURATION_T = _v("sA_4_3.push_saturation_t", "23", "s", "§A.4.3, Fig. A.8(a) (line 2210)", relative=False)
#: Fig. A.8 as the headline states it: joint four is the one that saturates without DM enhancement; with it no
#: joint torque exceeds 20 N m.
PUSH_JOINT4_FIRST = _claim("figA_8.joint4_first", "§A.4.3, Fig. A.8(a) (line 2210): without DM enhancement joint four "
                           "saturated (at 23 s)")
PUSH_WITHIN_20 = _claim("figA_8.within_20", "§A.4.3, Fig. A.8(b) (line 2210): with DM enhancement the maximum joint "
                        "torque no more than 20 N m")

# ---------------------------------------------------------------- appendix B
#: §B.4.2: without singularity avoidance the arm becomes singular at about 8.35 s.
SINGULAR_TIME_B = _v("sB_4_2.singular_t", "8.35", "s", "§B.4.2, Fig. B.7 (line 2483)", relative=False)
#: §B.4.3: base enabled at 6.40 s and released at 16.48 s (beyond the workspace, proposed).
BASE_ON_B = _v("sB_4_3.base_on", "6.40", "s", "§B.4.3, Fig. B.11 (line 2549)", relative=False)
BASE_OFF_B = _v("sB_4_3.base_off", "16.48", "s", "§B.4.3, Fig. B.11 (line 2549)", relative=False)
#: §B.4.3: the base is enabled once (beyond) and never (within the workspace, proposed).
BASE_PERIODS_B = {"beyond": _v("sB_4_3.periods.beyond", "1", "", "§B.4.3", tol=0.0, claim=True),
                  "within": _v("sB_4_3.periods.within", "0", "", "§B.4.3, Table B.2", tol=0.0, claim=True)}
_TB2 = "Table B.2 (line 2501)"
#: Table B.2: (RMS of x_b, y_b [cm/s], θ_b [°/s]; duration [s] of each) per (region, method).
TABLE_B_2 = {
    (w, m): (tuple(_v(f"tableB_2.{w}.{m}.rms.{c}", t, u, _TB2, relative=(t != "0"))
                   for c, u, t in zip(("x", "y", "th"), ("cm/s", "cm/s", "°/s"), rms)),
             tuple(_v(f"tableB_2.{w}.{m}.duration.{c}", t, "s", _TB2, relative=(t != "0"))
                   for c, t in zip(("x", "y", "th"), dur)))
    for (w, m), rms, dur in (
        (("within", "proposed"), ("0", "0", "0"), ("0", "0", "0")),
        (("within", "traditional"), ("1.10", "0.75", "0.287"), ("80", "80", "80")),
        (("beyond", "proposed"), ("1.58", "0.24", "0.241"), ("12.08", "12.08", "12.08")),
        (("beyond", "traditional"), ("2.77", "1.86", "0.739"), ("80", "80", "80")),
    )
}
#: §B.4.3: max tracking error (x, y) [cm] per (region, method).
ERROR_B = {k: _pair(f"sB_4_3.err.{k[0]}.{k[1]}", t, "cm", "§B.4.3 (lines 2514, 2547)")
           for k, t in ((("within", "traditional"), ("0.91", "1.89")), (("beyond", "proposed"), ("2.44", "1.82")),
                        (("beyond", "traditional"), ("6.65", "2.72")))}
#: §B.4.3: mean base tracking error (x_b, y_b) [cm] beyond the workspace.
BASE_ERROR_B = {m: _pair(f"sB_4_3.base_err.{m}", t, "cm", "§B.4.3 (line 2549)")
                for m, t in (("traditional", ("2.81", "1.12")), ("proposed", ("0.81", "0.37")))}
#: §B.5: reduction of the max tracking error beyond the workspace, x and y [%] (1 − 2.44/6.65, 1 − 1.82/2.72).
ERROR_REDUCTION_B = _pair("sB_5.err_reduction", ("63.3", "33.1"), "%", "§B.5 conclusion (line 2555)")
#: §B.5: reduction of the base's motion time [%] (1 − 12.08/80).
BASE_TIME_REDUCTION_B = _v("sB_5.base_time_reduction", "84.90", "%", "§B.5 conclusion (line 2555)")
