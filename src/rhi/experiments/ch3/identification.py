"""Table 3.2: Λ along u = [0, 1] identified on the simulated RHI, PHANToM and Rehab at the Table 3.1 points.

The protocol is `rhi.experiments.identification` with the motors off (``controller="off"``):
the identified dynamics are the device's own. For a free chain pushed from rest by F u the
joint acceleration is M⁻¹JᵀuF, so ``uᵀẍ = F/Λ`` with Λ = (uᵀJM⁻¹Jᵀu)⁻¹ *exactly* eq. 3.13,
for the redundant RHI too (its null space is free and follows the dynamically consistent
motion). Hence the model prediction we put beside the identified M_x.
"""

from __future__ import annotations

import numpy as np

from rhi import thesis as T
from rhi.control import VMEMatching
from rhi.control.configuration import optimal_configuration
from rhi.devices.model import device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.ch3.measures import BETA, DEVICE_NAMES, POINTS, THESIS_Q
from rhi.experiments.identification import TRIALS, WINDOW, U, case_arrays, fit_rows, identify_case, trial_forces
from rhi.experiments.result import Result, Row, Table
from rhi.experiments.setups import Progress

#: Table 3.2: identified Λ [kg] along u at the two points of Table 3.1.
THESIS_TABLE_3_2 = T.TABLE_3_2
#: Start of the ch. 3 identification before the point [m].
BEFORE_CH3 = 0.01


@checked
def sysid_table_3_2(
    trials: int = TRIALS,
    *,
    seed: int = 0,
    configuration: str = "thesis",
    window: float = WINDOW,
    cutoff_hz: float = 20.0,
    progress: Progress | None = None,
) -> Result:
    """Table 3.2: Λ along u = [0, 1] identified on the simulated RHI, PHANToM and Rehab at the Table 3.1 points.

    Motors off (`push_trials` with no controller: the devices' own dynamics), start 1 cm
    before each point, constant force 0.5–1.5 N along u, `trials` trials per case.

    Args:
        trials: trials per device and point (thesis: 10).
        seed: seed of the force magnitudes (the same magnitudes for every case).
        configuration: the RHI's configuration at the point: "thesis" (the optimised
            configuration printed in §3.5) or "optimum" (our optimum of eq. 3.22,
            `rhi.control.configuration.optimal_configuration`); the start is its nearest
            point on the self-motion manifold of the start point (IK without null-space motion).
        window: half-width of the position window around the point [m].
        cutoff_hz: low-pass cut-off [Hz].
        progress: callback(done, total) in trials.
    """
    if configuration not in ("thesis", "optimum"):
        raise InvalidInput(f"configuration: expected 'thesis' or 'optimum', got {configuration!r}")
    forces = trial_forces(trials, seed)
    u = np.array(U)
    total = 6 * len(forces)
    done = [0]
    rows, arrays, cases = [], {"forces": forces}, {}
    ordering_ok = []
    for i, point in enumerate(POINTS):
        x = np.array(point)
        where = f"({x[0]}, {x[1]})"
        lam_here = {}
        for name, dname in DEVICE_NAMES.items():
            dev = device(dname)
            if name == "RHI":
                q_nom = np.array(THESIS_Q[i])
                q_nom = dev.ik(x, q_nom, k_null=0.0)
                if configuration == "optimum":
                    q_nom = optimal_configuration(dev, x, VMEMatching(tuple(U), BETA), q_nom)
            else:
                q_nom = dev.ik(x, np.full(dev.n, 0.3))
            q_start = dev.ik(x - BEFORE_CH3 * u, q_nom, k_null=0.0)
            cb = None
            if progress is not None:
                base = done[0]
                cb = lambda k, n, base=base: progress(base + k, total)  # noqa: E731
            case = identify_case(dev, q_start, q_nom, x, label=f"{name} at {where}", forces=forces, u=u,
                                 window=window, cutoff_hz=cutoff_hz, progress=cb)
            done[0] += len(forces)
            cases[(name, i)] = case
            lam_here[name] = case.fit.mass
            rows += fit_rows(case, f"{name} at {where}", THESIS_TABLE_3_2[name][i], None,
                              "thesis: hardware identification (Table 3.2)")
            arrays.update(case_arrays(case, f"{name}_{i}"))
        ordering_ok.append(lam_here["RHI"] <= lam_here["PHANToM"] < lam_here["Rehab"])
    errs = np.array([c.lam_error for c in cases.values()])
    errs_vp = np.array([c.fit.mass / c.lam_vp - 1.0 for c in cases.values()])
    summary = [
        Row("largest |identified − eq. 3.13| / eq. 3.13 over the six cases", None, float(np.max(np.abs(errs))), "",
            "the loop between the formula and the physics"),
        Row("largest |identified − Λ/(1 − k)| / (Λ/(1 − k)) over the six cases", None,
            float(np.max(np.abs(errs_vp))), "", "eq. 3.13 with the velocity-product force eq. 3.24 omits"),
        Row("cases with identified Λ ordered RHI ≤ PHANToM < Rehab (of 2 points)", T.TABLE_3_2_ORDER,
            float(sum(ordering_ok)), ""),
    ]
    for i in range(2):
        for a, b in (("RHI", "PHANToM"), ("RHI", "Rehab")):
            th = T.TABLE_3_2_RATIO[a, b, i]
            summary.append(Row(f"ratio Λ_{a}/Λ_{b} identified at point {i + 1}", th,
                               cases[(a, i)].fit.mass / cases[(b, i)].fit.mass, ""))
    arrays["lambda_identified"] = np.array([[cases[(n, i)].fit.mass for n in DEVICE_NAMES] for i in range(2)])
    arrays["lambda_ci"] = np.array([[cases[(n, i)].fit.mass_ci for n in DEVICE_NAMES] for i in range(2)])
    arrays["lambda_model"] = np.array([[cases[(n, i)].lam_model for n in DEVICE_NAMES] for i in range(2)])
    arrays["lambda_thesis"] = np.array([[THESIS_TABLE_3_2[n][i] for n in DEVICE_NAMES] for i in range(2)])
    return Result(
        "ch3.sysid_table_3_2",
        "Table 3.2: effective apparent inertia Λ along u = [0, 1] identified on the simulated devices",
        [Table("Table 3.2: identified Λ (and Φ, c) beside the thesis and beside eq. 3.13", rows),
         Table("Identification vs model and ordering", summary)],
        arrays,
        [
            f"MuJoCo plant, motors off, {len(forces)} trials per case with seeded constant forces "
            f"{np.round(forces, 3).tolist()} N along u from 1 cm before the point; position from FK of the "
            "encoders, force from the F/T sensor; Savitzky–Golay derivatives, zero-phase 5th-order Butterworth "
            f"({cutoff_hz:g} Hz), least squares on the samples within ±{1000 * window:g} mm of the point, "
            "cluster-robust CIs (one cluster per trial).",
            "We fit M_x ẍ + Φ ẋ + c = F: the constant c absorbs the Coulomb friction of the moving joints "
            "(eq. 3.24 has none; the thesis starts 1 cm early to get past static friction).",
            "Thesis values are hardware identifications; their inertial model is not published, ours is estimated "
            "(models/rhi4/README.md), so the check is identified vs eq. 3.13 of our model and the ordering.",
            f"RHI configuration: {configuration!r} (see the docstring).",
        ],
    )
