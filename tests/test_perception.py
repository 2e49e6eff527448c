"""System identification and virtual psychophysics on the MuJoCo plant.

rhi.experiments.identification, ch3.identification, ch3.discrimination, ch6.identification.

Reduced sizes (3 identification trials, a 3-level psychophysics protocol on one stroke
duration); the full runs are `sysid_table_3_2()`, `sysid_table_6_1()`, `psychophysics()`.
"""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from conftest import row

from rhi import thesis as T  # noqa: E402
from rhi.control import ZeroTorque  # noqa: E402
from rhi.devices.model import device  # noqa: E402
from rhi.errors import InvalidInput  # noqa: E402
from rhi.experiments import identification as ID  # noqa: E402
from rhi.experiments.ch3 import discrimination as D, sysid_table_3_2  # noqa: E402
from rhi.experiments.ch6 import sysid_table_6_1  # noqa: E402
from rhi.metrics import effective_inertia  # noqa: E402
from rhi.plots import perception as plots  # noqa: E402


# ------------------------------------------------------------------------------- sysid
@pytest.fixture(scope="module")
def table_3_2():
    return sysid_table_3_2(trials=3)


@pytest.fixture(scope="module")
def table_6_1():
    return sysid_table_6_1(trials=3)


def test_identified_inertia_matches_eq_3_13_on_the_plant(table_3_2):
    ident = table_3_2.arrays["lambda_identified"]
    model = table_3_2.arrays["lambda_model"]
    assert ident.shape == model.shape == (2, 3)
    assert np.all(np.abs(ident / model - 1.0) < 0.10)
    # and with the Coulomb friction fitted as a constant, tighter
    for key in ("RHI_0", "PHANToM_0", "Rehab_0", "RHI_1", "PHANToM_1", "Rehab_1"):
        assert abs(table_3_2.arrays[f"{key}_fit_c"][0] / table_3_2.arrays[f"{key}_model"][0] - 1.0) < 0.07


def test_identified_inertia_ordering(table_3_2):
    rhi, phantom, rehab = table_3_2.arrays["lambda_identified"][0]  # (0.49, -0.22)
    assert rhi <= phantom < rehab
    assert rehab > 3 * phantom
    ci = table_3_2.arrays["lambda_ci"]
    assert np.all(ci[..., 0] < table_3_2.arrays["lambda_identified"])
    assert np.all(ci[..., 1] > table_3_2.arrays["lambda_identified"])


def test_table_3_2_rows_carry_thesis_values(table_3_2):
    r = row(table_3_2, "M_x identified (eq. 3.24: M_x ẍ + Φ ẋ = F), Rehab at (0.49, -0.22)")
    assert r.source == "table3_2.Rehab.0" and r.unit == "kg" and np.isfinite(r.ours)


@pytest.mark.xfail(strict=True, reason="Table 3.2 was identified on the hardware; rhi identifies the simulated plant, "
                                      "whose link inertias are estimates (models/rhi4/README.md): Λ differs in value, "
                                      "the ordering RHI ≤ PHANToM < Rehab is what holds")
def test_table_3_2_rehab_value(table_3_2):
    r = row(table_3_2, "M_x identified (eq. 3.24: M_x ẍ + Φ ẋ = F), Rehab at (0.49, -0.22)")
    assert T.TABLE_3_2["Rehab"][0].within(r.ours)


def test_sysid_table_6_1(table_6_1):
    import json

    json.dumps(table_6_1.to_json())
    a = table_6_1.arrays
    free, stiff = a["free_fit"][0], a["stiff_fit"][0]
    assert abs(free / a["free_model"][0] - 1.0) < 0.10
    assert stiff > free  # the M_Stiff^des configuration is heavier along u (Table 6.1: 0.125 vs 0.036 kg)
    fs = row(table_6_1, "F_max along u, M_Stiff^des (J#): rhi.metrics.max_force").ours
    ff = row(table_6_1, "F_max along u, M_Free^des (J#): rhi.metrics.max_force").ours
    assert fs < ff < 0  # signed like Table 6.1: larger capability for M_Stiff^des
    # the ch. 6 controller with the pseudoinverse projector J⁺: its null-space torques are not dynamically
    # consistent and add to the identified inertia (issue 13's check: 0.0555 / 0.1149 kg vs 0.0277 / 0.0488 kg
    # with J# over 10 trials)
    for case in ("free", "stiff"):
        assert a[f"{case}_pinv_fit"][0] > 1.5 * a[f"{case}_fit"][0]
    assert row(table_6_1, "F_max along u, M_Stiff^des (J⁺): rhi.metrics.max_force").ours < fs
    # nothing holds x: the handle passes y = 0.1 m off the thesis's axis x = 0.5 m (stiff: by > 1.5 cm); held on the
    # axis, the mass along u would be uᵀM_x u ≥ eq. 3.13's (uᵀM_x⁻¹u)⁻¹ at the same configuration
    assert row(table_6_1, "x where the handle passes y = 0.1 m, M_Stiff^des (J#)").ours > 0.515
    dev = device("rhi4")
    for case, name in (("free", "M_Free^des"), ("stiff", "M_Stiff^des")):
        q = a[f"q_nominal_{case}"]
        J, M = dev.jacobian(q), dev.mass_matrix(q)
        myy = row(table_6_1, f"(M_x)_yy at the nominal configuration (the motion held on the axis x = 0.5 m), {name}")
        assert myy.ours == pytest.approx(np.linalg.inv(J @ np.linalg.solve(M, J.T))[1, 1], rel=1e-9)
        assert myy.ours > 1.1 * effective_inertia(J, M, np.array([0.0, 1.0]))


def test_sysid_table_6_1_null_space_torque_leaves_the_mass_alone_unless_clipped(table_6_1):
    """With Algorithm 2's law ("scaled") the null-space torque stays in the null space and eq. 3.13 predicts M_x.

    The stiff configuration passes the point fast enough that the Coriolis/centrifugal force eq. 6.22 omits matters
    (k ~ −15 %); with it, eq. 3.13 predicts the identified mass. Chapter 6's law as written (the default, "clipped")
    clips the FME-matching torque at the programmed limits on the stiff run, and the clipped part pushes the handle.
    """
    scaled = sysid_table_6_1(trials=3, projectors=("dynamic",), null_space="scaled").arrays
    assert abs(scaled["stiff_fit"][0] / scaled["stiff_lam_vp"] - 1.0) < 0.10
    assert abs(scaled["free_fit"][0] / table_6_1.arrays["free_fit"][0] - 1.0) < 0.02  # free: nothing is clipped
    assert table_6_1.arrays["stiff_fit"][0] > 1.05 * scaled["stiff_fit"][0]


def test_velocity_product_force_closes_the_dynamics():
    """On a frictionless plant, F = Λ uᵀẍ + F_vp holds sample by sample (the terms eq. 3.24 omits)."""
    from rhi.sim import Plant, PushForce, simulate

    dev = device("rhi4")
    u = np.array(ID.U)
    q0 = np.array([0.5, 0.95, 0.38, -0.29])
    plant = Plant(dev, friction=None)
    plant.reset(q0)
    log = simulate(plant, ZeroTorque(4), duration=0.1, hand=PushForce(u, 1.0))
    x = dev.fk(log.q) @ u
    a = np.gradient(np.gradient(x, log.t), log.t)
    lam = effective_inertia(dev.jacobian(log.q), dev.mass_matrix(log.q), u)
    vp = ID.velocity_product_force(dev, log.q, log.dq, u)
    F = log.ft[:, :2] @ u
    k = slice(5, -5)
    assert np.max(np.abs(vp[k])) > 0.05  # not negligible at these speeds
    np.testing.assert_allclose(lam[k] * a[k] + vp[k], F[k], atol=0.02)


def test_reflected_friction_of_a_2dof_chain():
    dev = device("phantom")
    q = np.array([0.47, 0.27])
    J, M = dev.jacobian(q), dev.mass_matrix(q)
    u = np.array([0.0, 1.0])
    dq = np.linalg.solve(M, J.T @ u)  # motion from rest under a force along u
    D, tc = np.array([0.01, 0.02]), np.array([0.005, 0.0])
    lam, phi, c = ID.reflected_friction(dev, q, dq, u, D, tc)
    assert lam == pytest.approx(float(effective_inertia(J, M, u)))
    row = np.linalg.solve(M, J.T @ u)
    assert phi == pytest.approx(lam * (row @ (D * dq)) / (u @ J @ dq))
    assert c == pytest.approx(lam * row @ (tc * np.sign(dq)))
    with pytest.raises(InvalidInput, match="dq"):
        ID.reflected_friction(dev, q, np.zeros(2), u, D, tc)


def test_trial_forces_seeded_in_range():
    f = ID.trial_forces(10, seed=3)
    assert f.shape == (10,) and np.all((f >= 0.5) & (f <= 1.5))
    np.testing.assert_array_equal(f, ID.trial_forces(10, seed=3))
    with pytest.raises(InvalidInput, match="trials"):
        ID.trial_forces(1)


# ------------------------------------------------------------------------ psychophysics
def test_minimum_jerk_palpation():
    h = D.MinimumJerkPalpation(np.zeros(2), [0.0, 2.0], 0.09, 0.6)
    x, v = h.reference(0.0)
    np.testing.assert_allclose(x, 0.0)
    np.testing.assert_allclose(v, 0.0)
    x, v = h.reference(0.3)
    np.testing.assert_allclose(x, [0.0, 0.045], atol=1e-12)
    assert v[1] == pytest.approx(1.875 * 0.09 / 0.6)
    np.testing.assert_allclose(h.reference(5.0)[0], [0.0, 0.09])
    F = h.force(0.3, np.array([0.0, 0.04]), np.zeros(2))
    assert F[1] == pytest.approx(300 * 0.005 + 10 * 1.875 * 0.09 / 0.6)
    with pytest.raises(InvalidInput, match="duration"):
        D.MinimumJerkPalpation(np.zeros(2), [0, 1], 0.09, 0.0)


def test_perceived_stiffness_through_origin():
    d = np.linspace(0.001, 0.075, 50)
    assert D.perceived_stiffness(d, 50.0 * d) == pytest.approx(50.0)
    # a constant friction force is attributed to the spring: K̂ = K + c Σd/Σd²
    k = D.perceived_stiffness(d, 50.0 * d + 0.1)
    assert k == pytest.approx(50.0 + 0.1 * d.sum() / (d @ d))
    with pytest.raises(InvalidInput):
        D.perceived_stiffness(np.zeros(5), np.ones(5))


@pytest.fixture(scope="module")
def tiny_study():
    return D.psychophysics(subjects=2, repetitions=6, comparison_percent=(-35.0, 0.0, 35.0), durations=(0.7,),
                           overdispersion=False, seed=1)


def test_psychophysics_pipeline_end_to_end(tiny_study):
    a = tiny_study.arrays
    assert a["pse"].shape == a["jnd"].shape == a["wf"].shape == (3, 2)
    assert np.all(np.isfinite(a["pse"])) and np.all(np.isfinite(a["jnd"])) and np.all(a["jnd"] > 0)
    assert np.all((a["pse"] > 30) & (a["pse"] < 70))
    assert row(tiny_study, "WF mean, RHI").source == "table3_3.wf.RHI.0"
    p = row(tiny_study, "one-way ANOVA on WF: p").ours
    assert 0.0 <= p <= 1.0
    import json

    json.dumps(tiny_study.to_json())  # the report serialises every result


def test_palpation_physics(tiny_study):
    """Slow-ish strokes: every device renders K within 15 %; the heavy Rehab distorts the most."""
    a = tiny_study.arrays
    K = a["stiffness"]
    dev = {d: a[f"khat_{d}"][:, 0] for d in ("RHI", "PHANToM", "Rehab")}
    for d, kh in dev.items():
        assert np.all(np.abs(kh / K - 1) < 0.15), d
        assert np.all(np.diff(kh) > 0), d  # stiffer springs feel stiffer
    err = {d: np.max(np.abs(kh / K - 1)) for d, kh in dev.items()}
    assert err["Rehab"] > err["RHI"]


def test_simulate_study_validates_and_is_seeded():
    table = {"stiffness": np.array([40.0, 50.0, 60.0]), "durations": np.array([1.0]),
             "RHI": np.array([[40.0], [50.0], [60.0]])}
    kw = dict(subjects=2, devices=("RHI",), repetitions=4, comparison_percent=(-20.0, 0.0, 20.0))
    r1, w1 = D.simulate_study(table, seed=5, **kw)
    r2, w2 = D.simulate_study(table, seed=5, **kw)
    np.testing.assert_array_equal(r1.response, r2.response)
    np.testing.assert_array_equal(w1, w2)
    # a noiseless observer on a transparent device answers by the physics alone
    r0, _ = D.simulate_study(table, seed=5, weber_mean=1e-9, weber_sd=0.0, **kw)
    big = r0.comparison > 55
    small = r0.comparison < 45
    assert np.all(r0.response[big] == 1) and np.all(r0.response[small] == 0)
    with pytest.raises(InvalidInput, match="comparison_percent"):
        D.simulate_study(table, subjects=1, devices=("RHI",), comparison_percent=(-20.0, 10.0, 20.0))
    with pytest.raises(InvalidInput, match="device"):
        D.simulate_study(table, subjects=1, devices=("Rehab",), comparison_percent=(-20.0, 0.0, 20.0))


# ------------------------------------------------------------------------------ figures
def test_figures_draw(table_3_2, table_6_1, tiny_study):
    for fig in (plots.sysid_fit(table_3_2), plots.sysid_fit(table_6_1), plots.psychometric_curves(tiny_study),
                plots.wf_jnd_boxes(tiny_study), plots.perceived_stiffness(tiny_study)):
        assert fig.axes and any(ax.has_data() for ax in fig.axes)
        plt.close(fig)
    with pytest.raises(InvalidInput, match="arrays"):
        plots.wf_jnd_boxes(table_3_2)


@pytest.mark.xfail(strict=True, reason="Table 3.3 comes from 10 human subjects whose responses the thesis does not "
                                      "publish; rhi's simulated observers have their own Weber fractions")
def test_table_3_3_wf_rhi(tiny_study):
    assert T.TABLE_3_3["wf"]["RHI"][0].within(row(tiny_study, "WF mean, RHI").ours)
