"""§3.3 eqs. 3.16–3.19, Figs 3.2–3.3: apparent inertia of a 1-DoF prismatic robot and of it on a redundant joint.

The thesis writes the 1-DoF robot's apparent inertia A1 = F_h/(s²X1) = M1 + B1/s (eq. 3.17) and the 2-DoF one's
A2 = M1 + (B1/s)(B2/s + M2)/(B1/s + B2/s + M2) (eq. 3.19), and concludes from
|(B2/s + M2)/(B1/s + B2/s + M2)| ≤ 1 that "the apparent inertia of the redundant two-DoF robot is smaller".
It gives no masses or dampings, so the claim is checked over a grid of them and of frequencies s = jω:
the literal reading |A2(jω)| ≤ |A1(jω)|, the thesis's own step (the factor's modulus ≤ 1) and the mass
part Re A. Eqs. 3.17 and 3.19 are themselves checked against MuJoCo: two slide joints built with MjSpec
(the outer joint's damping acts on X1 − X2, as B1 in eq. 3.18), driven by a sinusoidal force on M1,
A measured from the steady-state response.
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

from rhi import thesis as T
from rhi.experiments.arguments import checked
from rhi.experiments.result import Result, Row, Table

#: The grid of M1, M2 [kg], B1, B2 [N s/m] and ω [rad/s] (the thesis gives no values).
MASSES1 = (0.05, 0.5)
MASSES2 = (0.05, 0.5, 5.0)
DAMPINGS = (0.1, 1.0, 10.0)
OMEGAS = np.logspace(-1, 3, 41)
#: The case drawn in the figure and simulated in MuJoCo: (M1, B1, M2, B2) and its frequencies [rad/s].
CASE = (0.05, 1.0, 0.5, 1.0)
SIM_OMEGAS = (5.0, 20.0, 80.0)


def a1(s: np.ndarray, m1: float, b1: float) -> np.ndarray:
    """Eq. 3.17: A1(s) = M1 + B1/s [kg] (complex, s = jω)."""
    return m1 + b1 / s


def a2(s: np.ndarray, m1: float, b1: float, m2: float, b2: float) -> np.ndarray:
    """Eq. 3.19: A2(s) = M1 + (B1/s)(B2/s + M2)/(B1/s + B2/s + M2) [kg]."""
    z = b2 / s + m2
    return m1 + (b1 / s) * z / (b1 / s + z)


def simulated_a(m1: float, b1: float, m2: float | None, b2: float, omega: float, *, dt: float = 2e-4) -> complex:
    """F_h/(s²X1) at s = jω measured on MuJoCo: the 1-DoF robot (m2 None) or the 2-DoF one of Fig. 3.3.

    The force F_h = sin(ωt) [N] acts on M1 for 6 periods (at least 2 s + 3 periods); X1's sine and cosine parts
    over the last 3 periods (with an offset and a drift) give X1(jω).
    """
    spec = mujoco.MjSpec()
    spec.option.timestep = dt
    spec.option.gravity = [0.0, 0.0, 0.0]
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    parent = spec.worldbody
    if m2 is not None:
        base = parent.add_body(name="m2", mass=m2, inertia=[1e-4] * 3)
        base.add_joint(name="x2", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0], damping=b2)
        parent = base
    end = parent.add_body(name="m1", mass=m1, inertia=[1e-4] * 3)
    end.add_joint(name="x1", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1, 0, 0], damping=b1)  # on X1 − X2
    model = spec.compile()
    data = mujoco.MjData(model)
    body = model.body("m1").id
    period = 2 * np.pi / omega
    t_end = max(6 * period, 2.0 + 3 * period)
    n = int(round(t_end / dt))
    t = np.arange(1, n + 1) * dt
    x1 = np.empty(n)
    for k in range(n):
        data.xfrc_applied[body, 0] = np.sin(omega * data.time)
        mujoco.mj_step(model, data)
        x1[k] = data.qpos.sum()  # X1 = (X1 − X2) + X2
    last = t > t[-1] - 3 * period
    basis = np.column_stack([np.sin(omega * t[last]), np.cos(omega * t[last]), np.ones(last.sum()), t[last]])
    c = np.linalg.lstsq(basis, x1[last], rcond=None)[0]
    x_jw = complex(c[0], c[1])  # X1 = Im(x_jw e^{jωt}) for F = Im(e^{jωt})
    return complex(1.0 / ((1j * omega) ** 2 * x_jw))


@checked
def apparent_inertia_example() -> Result:
    """§3.3 eqs. 3.16–3.19: A2 vs A1 over a grid of masses, dampings and frequencies; eqs. 3.17/3.19 vs MuJoCo."""
    s = 1j * OMEGAS
    ratio, factor, re_ok, beyond = [], [], [], []
    for m1, m2, b1, b2 in itertools.product(MASSES1, MASSES2, DAMPINGS, DAMPINGS):
        ratio.append(np.abs(a2(s, m1, b1, m2, b2)) / np.abs(a1(s, m1, b1)))
        z = b2 / s + m2
        factor.append(np.abs(z / (b1 / s + z)))
        re_ok.append(a2(s, m1, b1, m2, b2).real <= a1(s, m1, b1).real + 1e-12)
        beyond.append(np.abs(a2(s, m1, b1, m2, b2) - m1) / np.abs(a1(s, m1, b1) - m1))
    ratio_a, factor_a = np.array(ratio), np.array(factor)
    m1, b1, m2, b2 = CASE
    sim1 = np.array([simulated_a(m1, b1, None, b2, w) for w in SIM_OMEGAS])
    sim2 = np.array([simulated_a(m1, b1, m2, b2, w) for w in SIM_OMEGAS])
    s_sim = 1j * np.array(SIM_OMEGAS)
    err1 = float(np.max(np.abs(sim1 - a1(s_sim, m1, b1)) / np.abs(a1(s_sim, m1, b1))))
    err2 = float(np.max(np.abs(sim2 - a2(s_sim, m1, b1, m2, b2)) / np.abs(a2(s_sim, m1, b1, m2, b2))))
    holds = float(np.mean(ratio_a <= 1 + 1e-12))
    rows = [
        Row("fraction of (M1, M2, B1, B2, ω) with |A2(jω)| ≤ |A1(jω)|", None, holds, "",
            f"{ratio_a.size} cases: M1 ∈ {MASSES1} kg, M2 ∈ {MASSES2} kg, B1, B2 ∈ {DAMPINGS} N s/m, ω 0.1–1000 rad/s"),
        Row("|A2| ≤ |A1| everywhere (1 = yes)", T.PRISMATIC_A2_BELOW_A1, float(holds == 1.0), "",
            "the thesis's step bounds |A2 − M1| ≤ |A1 − M1| only: A2 − M1 = (B1/s)·f with a complex f, |f| ≤ 1, and "
            "at high ω A2 ≈ M1 + B1²/(ω²M2) + B1/s, larger than A1 = M1 + B1/s in modulus"),
        Row("max |A2(jω)|/|A1(jω)|", None, float(ratio_a.max()), ""),
        Row("min |A2(jω)|/|A1(jω)|", None, float(ratio_a.min()), ""),
        Row("max |(B2/s + M2)/(B1/s + B2/s + M2)| (the thesis's step)", None, float(factor_a.max()), ""),
        Row("fraction with Re A2 ≤ Re A1 (the mass part)", None, float(np.mean(re_ok)), ""),
        Row("fraction with |A2 − M1| ≤ |A1 − M1| (the part beyond M1, what the thesis's step bounds)", None,
            float(np.mean(np.array(beyond) <= 1 + 1e-12)), ""),
        Row("largest |A1 MuJoCo − eq. 3.17| / |eq. 3.17|", None, err1, "",
            f"M1 = {m1} kg, B1 = {b1} N s/m at ω = {SIM_OMEGAS} rad/s"),
        Row("largest |A2 MuJoCo − eq. 3.19| / |eq. 3.19|", None, err2, "", f"M2 = {m2} kg, B2 = {b2} N s/m"),
    ]
    arrays = {"omega": OMEGAS, "a1": np.abs(a1(s, m1, b1)), "a2": np.abs(a2(s, m1, b1, m2, b2)),
              "sim_omega": np.array(SIM_OMEGAS), "sim_a1": np.abs(sim1), "sim_a2": np.abs(sim2), "ratio": ratio_a}
    notes = ["The thesis gives no masses or dampings for Figs 3.2–3.3: the claim is checked over the grid of the "
             "first row; the figure shows the case M1 = 0.05 kg, B1 = 1 N s/m, M2 = 0.5 kg, B2 = 1 N s/m with "
             "MuJoCo's measured |A| at three frequencies."]
    return Result("ch3.apparent_inertia_example", "§3.3 eqs. 3.16–3.19: apparent inertia of 1-DoF and redundant "
                  "2-DoF prismatic robots (Figs 3.2–3.3)", [Table("eqs. 3.17 and 3.19", rows)], arrays, notes)
