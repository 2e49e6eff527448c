"""A thesis-calibrated rhi4 inertia model, fitted to half of the thesis's inertia numbers and tested on the rest.

The thesis takes rhi4's dynamics from its refs. [23] (Çavuşoğlu et al. 2002, PHANToM 1.5) and
[45] (Dyck 2013, M.Sc. thesis, the rehabilitation robot) without printing them. rhi's default
model (models/rhi4/README.md) uses a public transcription of [23] and estimates for the rest;
[45] could not be found. This module fits the uncertain parameters, within bounds stated in
`BOUNDS`, to the thesis's inertia-dependent numbers and writes the variant that
``rhi.device("rhi4", params="thesis-fit")`` loads (`write_thesis_fit`). The default model is
never changed.

Claims (14, all along u = [0, 1]): Table 3.1 Λ (the thesis's model: RHI at its printed
configurations, the PHANToM with q1 = q2 = 0, the Rehab with q3 = q4 = 0), Table 3.2 Λ (the same
devices identified on the hardware, with the JR3 force sensor on the handle, §3.5) and Table
6.1 M_x (the FME-matched configurations at [0.5, 0.1] m, sensor attached, §6.4). Split: the
point (0.49, −0.22) and M_Free^des fit (7 claims); the point (0.49, −0.14) and M_Stiff^des are
held out (7 claims). Table 6.1's Φ (joint friction) is not fitted: two numbers against at
least two unknown joint dampings leave nothing to validate.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from scipy.optimize import least_squares

from rhi import thesis as T
from rhi.devices.model import Device, device
from rhi.devices.spec import bundled_spec
from rhi.devices.variant import model_with_links
from rhi.experiments.arguments import checked
from rhi.experiments.ch3.measures import POINTS
from rhi.experiments.ch6.identification import ch6_configurations
from rhi.experiments.result import Result, Row, Table

U = np.array([0.0, 1.0])
#: Uncertain parameters: name -> (default model's value, lower bound, upper bound, why these bounds).
BOUNDS: dict[str, tuple[float, float, float, str]] = {
    "m_rehab1": (0.60, 0.3, 1.5, "rehab link 1 with its parallelogram bar, aluminium, 0.254 m [kg]"),
    "m_rehab2": (0.30, 0.1, 0.8, "rehab link 2, aluminium, 0.141 m [kg]"),
    "m_base": (0.7155, 0.4, 1.5, "PHANToM base: two motors, housing, 3D-printed coupler, lumped at rehab link 2's end [kg]"),
    "I_base": (2.0e-3, 1.0e-3, 1.0e-2, "its inertia about its centre: 0.4–1.5 kg within a 0.05–0.12 m radius [kg m²]"),
    "arm_rehab": (0.0, 0.0, 1.0e-2, "rehab motors' reflected rotor inertia: 0 (direct) to ~1e-5 kg m² × 30² gearing [kg m²]"),
    "s_phantom": (1.0, 0.75, 1.33, "scale of the PHANToM links' masses, inertias and rotor inertia: ±⅓ about the "
                                   "unverified public transcription of [23]"),
    "m_sensor": (0.0, 0.0, 0.3, "JR3 50M31A3 sensor + handle on the end-effector, experiments only [kg]"),
}
NAMES = tuple(BOUNDS)


def claims(stiff_free: dict[str, np.ndarray] | None = None) -> list[dict]:
    """The 14 inertia claims: {key, thesis, device ("RHI" | "PHANToM" | "Rehab"), q (4,), sensor, fit}.

    Args:
        stiff_free: Table 6.1's configurations {"free", "stiff"} (default: `ch6_configurations`).
    """
    rhi, ph, re = device("rhi4"), device("phantom"), device("rehab")
    cfg6 = ch6_configurations() if stiff_free is None else stiff_free
    out = []
    for i, x in enumerate(POINTS):
        q_rhi = np.array([float(v) for v in T.TABLE_3_1_Q[i]])
        q_ph = np.r_[0.0, 0.0, ph.ik(np.array(x), np.array([0.3, 0.5]))]
        q_re = np.r_[re.ik(np.array(x), np.array([-0.5, 0.5])), 0.0, 0.0]
        for dev_name, q in (("RHI", q_rhi), ("PHANToM", q_ph), ("Rehab", q_re)):
            for table, sensor in (("3.1", False), ("3.2", True)):
                thesis = (T.TABLE_3_1_LAMBDA if table == "3.1" else T.TABLE_3_2)[dev_name][i]
                out.append({"key": f"Table {table} Λ {dev_name} at {x}", "thesis": float(thesis), "device": dev_name,
                            "q": q, "sensor": sensor, "fit": i == 0})
    for case in ("free", "stiff"):
        out.append({"key": f"Table 6.1 M_x, M_{case.capitalize()}^des", "thesis": float(T.TABLE_6_1[case][0]),
                    "device": "RHI", "q": np.asarray(cfg6[case]), "sensor": True, "fit": case == "free"})
    del rhi
    return out


def variant_of(p: np.ndarray) -> dict:
    """The variant file's content (links, armature) for parameters p (order `NAMES`)."""
    v = dict(zip(NAMES, (float(x) for x in p)))
    d1, d2 = 0.254, 0.141
    base = device("rhi4")
    ph = _urdf_links(base)
    s = v["s_phantom"]
    links = {
        "rehab_link1": {"mass": v["m_rehab1"], "izz": v["m_rehab1"] * d1**2 / 12},
        "rehab_link2": {"mass": v["m_rehab2"], "izz": v["m_rehab2"] * d2**2 / 12},
        "phantom_base": {"mass": v["m_base"], "izz": v["I_base"]},
        "phantom_link1": {"mass": s * ph["phantom_link1"][0], "izz": s * ph["phantom_link1"][1]},
        "phantom_link2": {"mass": s * ph["phantom_link2"][0], "izz": s * ph["phantom_link2"][1]},
    }
    arm = [v["arm_rehab"], v["arm_rehab"], s * base.armature[2], s * base.armature[3]]
    return {"links": links, "armature": arm}


def _urdf_links(dev: Device) -> dict[str, tuple[float, float]]:
    """{link: (mass, izz)} of the default rhi4 URDF's PHANToM links."""
    import xml.etree.ElementTree as ET

    root = ET.parse(bundled_spec(dev.name).chain()[0]).getroot()
    out: dict[str, tuple[float, float]] = {}
    for el in root.iter("link"):
        inertial = el.find("inertial")
        if inertial is not None:
            out[str(el.get("name"))] = (float(inertial.find("mass").get("value", "nan")),  # type: ignore[union-attr]
                                        float(inertial.find("inertia").get("izz", "nan")))  # type: ignore[union-attr]
    return out


def predict(p: np.ndarray, items: list[dict]) -> np.ndarray:
    """Λ [kg] of each claim under parameters p: the variant's M, plus the sensor as a point mass where attached."""
    var = variant_of(p)
    base = device("rhi4")
    model = model_with_links(bundled_spec("rhi4").chain()[0], var["links"])
    data = model.createData()
    m_sensor = float(p[NAMES.index("m_sensor")])
    cols = {"RHI": [0, 1, 2, 3], "PHANToM": [2, 3], "Rehab": [0, 1]}
    out = []
    for c in items:
        q = c["q"]
        theta = base.A @ q + base.b
        M = base.A.T @ pin.crba(model, data, theta) @ base.A
        M = 0.5 * (M + M.T) + np.diag(var["armature"])
        J = base.jacobian(q)
        if c["sensor"]:
            M = M + m_sensor * J.T @ J  # a point mass on the handle
        k = cols[c["device"]]
        Jk, Mk = J[:, k], M[np.ix_(k, k)]
        out.append(1.0 / float(U @ Jk @ np.linalg.solve(Mk, Jk.T @ U)))
    return np.array(out)


def fit(items: list[dict] | None = None, starts: int = 8, seed: int = 23) -> dict:
    """Least squares of log(model/thesis) over the fit claims, within `BOUNDS`, from seeded starts.

    Returns:
        {"p": (7,) fitted parameters, "default": (7,), "items": claims, "pred_fit", "pred_default": (14,) [kg]}.
    """
    items = claims() if items is None else items
    lo = np.array([BOUNDS[k][1] for k in NAMES])
    hi = np.array([BOUNDS[k][2] for k in NAMES])
    p0 = np.array([BOUNDS[k][0] for k in NAMES])
    sel = [c for c in items if c["fit"]]
    target = np.log([c["thesis"] for c in sel])

    def residual(p):
        return np.log(predict(p, sel)) - target

    rng = np.random.default_rng(seed)
    best = None
    for x0 in [np.clip(p0, lo, hi), *rng.uniform(lo, hi, size=(starts - 1, len(NAMES)))]:
        r = least_squares(residual, x0, bounds=(lo, hi), x_scale=hi - lo, xtol=1e-12, ftol=1e-12)
        if best is None or r.cost < best.cost - 1e-15:
            best = r
    p = best.x  # type: ignore[union-attr]
    return {"p": p, "default": p0, "items": items, "pred_fit": predict(p, items), "pred_default": predict(p0, items)}


@checked
def thesis_fit(starts: int = 8) -> Result:
    """The thesis-fit model: fitted parameters, and per claim thesis / default / thesis-fit, fit or held out."""
    f = fit(starts=starts)
    rows_p = [Row(f"{k}: {BOUNDS[k][3]}", None, float(v), "", f"default {BOUNDS[k][0]:g}, bounds "
                  f"[{BOUNDS[k][1]:g}, {BOUNDS[k][2]:g}]") for k, v in zip(NAMES, f["p"])]
    rows_c = []
    for c, pf, pd in zip(f["items"], f["pred_fit"], f["pred_default"]):
        role = "fit" if c["fit"] else "held out"
        rows_c.append(Row(f"{c['key']}: thesis-fit ({role})", None, float(pf), "kg",
                          f"thesis {c['thesis']:g}, error {100 * (pf / c['thesis'] - 1):+.1f} %"))
        rows_c.append(Row(f"{c['key']}: default model", None, float(pd), "kg",
                          f"error {100 * (pd / c['thesis'] - 1):+.1f} %"))
    summary = []
    for role, flag in (("fit", True), ("held-out", False)):
        idx = [i for i, c in enumerate(f["items"]) if c["fit"] == flag]
        th = np.array([f["items"][i]["thesis"] for i in idx])
        for name, pred in (("thesis-fit", f["pred_fit"]), ("default", f["pred_default"])):
            err = np.abs(pred[idx] / th - 1)
            summary.append(Row(f"mean |error| on the {role} claims, {name} model", None, 100 * float(err.mean()), "%"))
            summary.append(Row(f"max |error| on the {role} claims, {name} model", None, 100 * float(err.max()), "%"))
    return Result("calibration.thesis_fit", "A thesis-calibrated rhi4 inertia model (fit on half the claims, "
                  "tested on the other half)",
                  [Table("Fitted parameters (bounds and reasons: rhi.experiments.calibration.BOUNDS)", rows_p),
                   Table("Fit and held-out error, thesis-fit vs default model", summary),
                   Table("Per claim", rows_c)],
                  {"p": f["p"], "pred_fit": f["pred_fit"], "pred_default": f["pred_default"],
                   "thesis": np.array([c["thesis"] for c in f["items"]])},
                  ["Labelled variant: rhi.device('rhi4', params='thesis-fit'); the default model is unchanged.",
                   "The sensor mass applies to the experimental claims (Tables 3.2, 6.1) only; it is not part of "
                   "the device variant."])


def write_thesis_fit(path=None, starts: int = 8) -> dict:
    """Run `fit` and write the variant file models/rhi4/thesis_fit.toml (or `path`); returns the fit."""
    f = fit(starts=starts)
    var = variant_of(f["p"])
    path = bundled_spec("rhi4").folder / "thesis_fit.toml" if path is None else path
    lines = ["# rhi4 parameter variant \"thesis-fit\": inertias fitted to the thesis's Λ / M_x numbers (README.md).",
             "# Generated by rhi.experiments.calibration.write_thesis_fit(); do not edit by hand.",
             f"armature = [{', '.join(repr(float(a)) for a in var['armature'])}]", ""]
    for link, values in var["links"].items():
        lines += [f"[links.{link}]"] + [f"{k} = {float(v)!r}" for k, v in values.items()] + [""]
    lines += ["[fit]  # provenance, not read by the device"]
    lines += [f"{k} = {float(v)!r}" for k, v in zip(NAMES, f["p"])]
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return f


__all__ = ["BOUNDS", "claims", "fit", "predict", "thesis_fit", "variant_of", "write_thesis_fit"]
