"""Chapter 6 experiments at reduced resolution.

The 3-DoF example (Figs 6.3–6.4), palpation (Fig. 6.9, Table 6.1), the F_max ratio map (Fig. 6.10) and the
desired-FME transition (Fig. 6.11).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import fd_jacobian, random_q, row

from rhi import thesis as T
from rhi.control import FMEMatching, JointLimitBarrier
from rhi.design.executors import PoolExecutor, SerialExecutor
from rhi.devices.model import device
from rhi.errors import InvalidInput, Unreachable
from rhi.experiments import ch6
from rhi.experiments.ch6 import capability, setup as S6


@pytest.fixture(scope="module")
def ex3():
    return ch6.example_3dof(steps=81)


@pytest.fixture(scope="module")
def palp():
    # saturation starts near 5 mm (M_Free) and 9 mm (M_Stiff): 12 mm pushes past both
    return ch6.palpation(settle=0.2, depth=0.012, speed=0.02, hold=0.1)


@pytest.fixture(scope="module")
def small_map():
    return ch6.fmax_ratio_map(resolution=3, executor=SerialExecutor(), starts=1)


@pytest.fixture(scope="module")
def trans():
    return ch6.transition(settle=0.2, depth=0.015, speed=0.03, hold=0.3, release=0.7, compare_beta=None)


# ------------------------------------------------------------------ 3-DoF example
def test_3dof_fme_shape_matches_thesis(ex3):
    # §6.3.1: eigenvalues 2.6 and 5.8 of M̂ at the initial configuration, M_Free = diag(0.2·2.6, 5·5.8)
    assert row(ex3, "λ_min").ours == pytest.approx(2.6, abs=0.05)
    assert row(ex3, "λ_max").ours == pytest.approx(5.8, abs=0.05)
    assert row(ex3, "𝒦").ours == pytest.approx(29.0, abs=0.25)
    assert row(ex3, "ζ").ours == pytest.approx(0.52, abs=0.01)


def test_3dof_stiff_renders_full_force_free_does_not(ex3):
    a = ex3.arrays
    Fe = a["Fe"]
    # thesis: only at the M_Stiff^des configuration is F_e rendered without saturation
    np.testing.assert_allclose(a["force_stiff"], Fe, atol=1e-9)
    assert np.all(a["alpha_stiff"] == 1.0)
    assert a["alpha_free"].min() < 1.0 and a["alpha_initial"].min() < 1.0
    peaks = {k: np.abs(a[f"force_{k}"][:, 0]).max() for k in ("initial", "free", "stiff")}
    assert peaks["free"] < peaks["initial"] < peaks["stiff"]
    for k in ("initial", "free", "stiff"):
        assert np.all(np.abs(a[f"tau_{k}"]) <= 0.5 + 1e-12)
        assert np.abs(a[f"force_{k}"][:, 1]).max() < 1e-9  # scaling keeps the direction
    # the matched configurations hold the end-effector and lower the JBLD cost
    dev = device("planar3r")
    for k in ("free", "stiff"):
        np.testing.assert_allclose(dev.fk(a[f"q_{k}"]), a["x"], atol=1e-9)
        r = row(ex3, f"JBLD ν to M_{k.capitalize()}")
        assert r.ours < float(r.note.split(":")[1])


def test_3dof_fme_axes_follow_the_desired(ex3):
    # M_Free's minor axis along F_e (x): the matched FME is narrower along x than at the start, M_Stiff's wider
    a = ex3.arrays
    assert a["fme_free"][0, 0] < a["fme_initial"][0, 0] < a["fme_stiff"][0, 0]


# ------------------------------------------------------------------ configurations and objectives
def test_joint_limit_barrier_gradient_and_zero_inside(rhi4, rng):
    bar = JointLimitBarrier(0.2)
    for q in random_q(rhi4, rng, 20):
        g = bar.gradient(rhi4, q)
        np.testing.assert_allclose(g, fd_jacobian(lambda p: np.array(bar.value(rhi4, p)), q), atol=1e-6)
    mid = np.full(4, 0.5)  # > 0.2 rad from every box and linear limit
    assert bar.value(rhi4, mid) == 0.0 and np.all(bar.gradient(rhi4, mid) == 0.0)
    # just past q4's lower limit the barrier pushes q4 up (negative gradient > 0)
    q = mid.copy()
    q[3] = rhi4.q_min[3] - 0.01
    assert bar.value(rhi4, q) > 0 and -bar.gradient(rhi4, q)[3] > 0


def test_match_fme_stays_on_manifold_within_limits(rhi4):
    _, _, Mf, Ms = S6.desired_fmes(rhi4, np.array(S6.U), S6.Q_HOME)
    x = np.array(S6.X0)
    for D in (Mf, Ms):
        obj = FMEMatching(D, rhi4.torque_max)
        q0 = rhi4.ik(x, np.zeros(4))
        q = S6.match_fme(rhi4, x, obj, q0)
        np.testing.assert_allclose(rhi4.fk(q), x, atol=1e-9)
        assert rhi4.within_limits(q)
        assert obj.value(rhi4, q) < obj.value(rhi4, q0) - 0.1
    with pytest.raises(Unreachable):
        S6.best_match(rhi4, (2.0, 0.0), FMEMatching(Mf, rhi4.torque_max), starts=2)


# ------------------------------------------------------------------ palpation (Fig. 6.9, Table 6.1)
def test_palpation_stiff_renders_more_force(palp):
    f_free = row(palp, "F_max along u, M_Free^des: simulated").ours
    f_stiff = row(palp, "F_max along u, M_Stiff^des: simulated").ours
    assert f_free < 0 and f_stiff < 0  # the device pushes back along −u
    assert f_stiff < f_free  # the direction of §6.4: more force with M_Stiff^des (its size: test_palpation_gain_value)
    gain = row(palp, "force gain M_Stiff vs M_Free, simulated").ours
    assert gain == pytest.approx(100 * (f_stiff / f_free - 1))
    print(f"\nTable 6.1 F_max: free {f_free:.3f} N (thesis -5.674), stiff {f_stiff:.3f} N (thesis -8.564), "
          f"gain {gain:.1f} % (thesis 51 %)")


def test_palpation_force_saturates_at_the_static_capability(palp):
    for case in ("free", "stiff"):
        lab = "M_Free^des" if case == "free" else "M_Stiff^des"
        sim = row(palp, f"F_max along u, {lab}: simulated").ours
        fs = row(palp, f"F_max along u, {lab}: force scaling at the settled").ours
        lp = row(palp, f"F_max along u, {lab}: LP").ours
        # the force-scaling controller saturates at its static capability (friction and
        # reconfiguration during the push: within 5 %), never beyond the LP optimum by more
        assert sim == pytest.approx(fs, rel=0.05)
        assert lp <= fs + 1e-9
        a = palp.arrays
        assert np.all(np.abs(a[f"tau_{case}"]) <= device("rhi4").torque_max + 1e-12)
        # before saturation the sensor follows K_e δX
        early = (a[f"desired_{case}"] < 0) & (a[f"desired_{case}"] > 0.5 * sim)
        np.testing.assert_allclose(a[f"force_{case}"][early], a[f"desired_{case}"][early], atol=0.3)


def test_palpation_table_orders_like_thesis(palp):
    # Table 6.1: inertia, friction and force capability all larger at the M_Stiff^des configuration
    lam_f = row(palp, "M_x along u, M_Free").ours
    lam_s = row(palp, "M_x along u, M_Stiff").ours
    phi_f = row(palp, "Φ along u, M_Free").ours
    phi_s = row(palp, "Φ along u, M_Stiff").ours
    assert lam_s > lam_f > 0 and phi_s > phi_f > 0
    assert row(palp, "𝒦").ours == pytest.approx(123.0, abs=0.5)  # §6.4: 123 and 3.3
    assert row(palp, "ζ").ours == pytest.approx(3.3, abs=0.05)
    # the controller holds the matched configuration while the hand holds X₀
    for case in ("free", "stiff"):
        assert row(palp, f"|q_settled − q_opt|, {case}").ours < 0.02


# ------------------------------------------------------------------ transition (Fig. 6.11)
def test_transition_is_bounded_with_the_method_and_jumps_without(trans):
    a = trans.arrays
    Mf, Ms = a["M_free_des"], a["M_stiff_des"]
    dist = np.linalg.norm(Mf - Ms)
    assert row(trans, "full transition time").ours == pytest.approx(0.5, abs=0.01)  # thesis: 0.5 s
    bound = np.pi * 1e-3 / (2 * S6.RHO)
    assert a["dM_with"].max() <= bound * (1 + 1e-9)
    assert a["dM_without"].max() == pytest.approx(dist, rel=1e-9)  # the whole change in one tick
    jump_w = row(trans, "max per-tick jump of τ_S = −β∂ν/∂q from the M_des change, with").ours
    jump_wo = row(trans, "max per-tick jump of τ_S from the M_des change, without").ours
    assert jump_wo > 20 * jump_w > 0
    for name in ("with", "without"):
        V, om = a[f"V_{name}"], a[f"omega_{name}"]
        assert np.all((V >= 0) & (V <= 1)) and np.all((om >= 0) & (om <= 1))
        # the desired FME went to M_Stiff^des under load and came back after the release
        assert om.min() == 0.0 and om[-1] == 1.0 and om[0] == 1.0
        assert np.all(np.abs(a[f"tau_{name}"]) <= device("rhi4").torque_max + 1e-12)
    # with the method Ω moves continuously: no tick changes it by more than the cosine's slope allows
    dom = np.abs(np.diff(a["omega_with"]))
    assert dom.max() <= np.pi * 1e-3 / (2 * S6.RHO * dist) * (1 + 1e-9)
    assert np.abs(np.diff(a["omega_without"])).max() == 1.0


def test_transition_lowers_the_handle_disturbance_under_the_literal_reading(trans):
    """Fig. 6.11's substance (issue 23): the method lowers the handle-force disturbance.

    With the torque box read as clipping each joint (eqs. 6.2–6.6 as written), as in the thesis's
    experiment; it also removes the chattering of eq. 6.15.
    """
    w = row(trans, "max handle-force disturbance |F_sensor − F_commanded| along u, with (β = 20)").ours
    wo = row(trans, "max handle-force disturbance, without (β = 20)").ours
    assert w < wo
    assert (row(trans, "desired-FME switches (Ω crossing ½), with").ours
            <= row(trans, "desired-FME switches (Ω crossing ½), without").ours)
    # the other reading is reported beside it
    assert row(trans, "max handle-force disturbance, without (β = 20, reading 'scaled')").ours > 0


# ------------------------------------------------------------------ F_max ratio map (Fig. 6.10)
def test_ratio_map_bit_identical_serial_vs_pool(small_map):
    serial = small_map
    with PoolExecutor(2) as ex:
        pool = ch6.fmax_ratio_map(resolution=3, executor=ex, starts=1)
    for k, v in serial.arrays.items():
        np.testing.assert_array_equal(v, pool.arrays[k], err_msg=k)
    assert np.isfinite(serial.arrays["ratio"]).sum() >= 3


def test_ratio_map_at_palpation_point_agrees_with_palpation(palp):
    out = capability._ratio_row(S6.X0[1], np.array([S6.X0[0]]), 3, True)
    fs_free, fs_stiff = out[0, 0], out[1, 0]
    assert fs_stiff / fs_free > 1.3
    np.testing.assert_allclose(-fs_free, row(palp, "F_max along u, M_Free^des: force scaling at the static").ours,
                               rtol=1e-6)
    np.testing.assert_allclose(-fs_stiff, row(palp, "F_max along u, M_Stiff^des: force scaling at the static").ours,
                               rtol=1e-6)


def test_bad_input():
    with pytest.raises(InvalidInput, match="depth"):
        ch6.palpation(depth=0.0)
    with pytest.raises(InvalidInput, match="speed"):
        ch6.transition(speed=float("nan"))
    with pytest.raises(InvalidInput, match="resolution"):
        ch6.fmax_ratio_map(resolution=1)
    with pytest.raises(InvalidInput, match="starts"):
        ch6.fmax_ratio_map(resolution=3, starts=0)


def test_ch6_figures_draw(ex3, palp, trans, small_map):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rhi.plots import ch6 as pl6

    figs = [pl6.example_3dof(ex3), pl6.configurations_3dof(ex3), pl6.palpation(palp), pl6.transition(trans),
            pl6.fmax_ratio_map(small_map)]
    assert [len(f.axes) for f in figs[:3]] == [3, 2, 2]
    assert len(figs[3].axes) >= 4
    for f in figs:
        plt.close(f)


@pytest.mark.xfail(strict=True, reason="the §5.4 joint limits bind at X₀ for both desired FMEs, so rhi's matched "
                                      "configurations differ from the thesis's (unpublished) ones, and rhi's plant "
                                      "friction and inertias are estimates: the gain is not 51 %")
def test_palpation_gain_value(palp):
    assert T.GAIN_6_4.within(row(palp, "force gain M_Stiff vs M_Free, simulated").ours)


def test_chapter_6_controllers_run_the_law_as_written(rhi4):
    """Chapter 6's law (eqs. 6.2–6.6: τ_m + (I − JᵀJ#ᵀ)τ_S, each joint clipped) wherever chapter 6's controller runs.

    Palpation with force scaling, the spatial and intent experiments built on it, and Table 6.1's identification;
    with ASCM the controller is chapter 7's (Algorithm 2). The old default ran Algorithm 2 everywhere.
    """
    from rhi.experiments.ch6.identification import _ch6_controller

    _, _, Mf, _ = S6.desired_fmes(rhi4, np.array(S6.U), S6.Q_HOME)
    assert S6.palpation_controller(rhi4, Mf).config.null_space == "clipped"
    assert S6.palpation_controller(rhi4, Mf, saturation="ascm").config.null_space == "scaled"
    assert S6.palpation_controller(rhi4, Mf, null_space="scaled").config.null_space == "scaled"
    ctrl = _ch6_controller(rhi4, Mf)()
    assert ctrl.config.null_space == "clipped" and ctrl._kernel is not None  # compiled, not the reference tick


def test_ratio_map_reports_the_matched_cost(small_map, rhi4):
    """Fig. 6.10's map carries ν of each matched configuration (eq. 6.10 + barrier), recomputed here at one point."""
    a = small_map.arrays
    ok = np.isfinite(a["ratio"])
    assert ok.any() and np.all(np.isfinite(a["nu_stiff"][ok])) and np.all(a["nu_free"][ok] >= 0.0)
    i, j = np.argwhere(ok)[0]
    _, _, Mf, Ms = S6.desired_fmes(rhi4, np.array(S6.U), S6.Q_HOME)
    from rhi.control import WeightedSum

    obj = WeightedSum(S6.controller_terms(Ms, rhi4.torque_max))
    x = (a["x"][j], a["y"][i])
    q = S6.best_match(rhi4, x, obj, starts=S6.start_configurations(rhi4, x, 1))
    assert obj.value(rhi4, q) == pytest.approx(a["nu_stiff"][i, j], rel=1e-9)
