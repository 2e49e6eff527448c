"""Chapter 4 experiments at reduced resolution: the thesis's qualitative results and the θz optimum."""

from __future__ import annotations

import numpy as np
import pytest

from rhi import thesis as T
from rhi.design import SerialExecutor, evaluate, optimize
from rhi.errors import InvalidInput
from rhi.experiments import ch4


@pytest.fixture(scope="module")
def theta() -> object:
    return ch4.theta_z_design(density=40, step_deg=5, maxiter=20, executor=SerialExecutor())


def _rows(result, table=0):
    return {r.quantity: r for r in result.tables[table].rows}


def test_theta_z_optimum_of_c2_and_the_explained_difference(theta):
    rows = _rows(theta)
    th2 = rows["θz maximising C2"].ours
    # Our optimum is the best point of the sweep (to the sweep's 5° step) ...
    best = theta.arrays["theta_deg"][np.argmax(theta.arrays["sweep_C2"])]
    assert abs(th2 - best) <= 5.0
    # ... and lies about 10–15° from the thesis's 2° (see ch4.sensitivity). The difference is explained by a
    # plateau: GM_T at the thesis's θz = 2° is within a quarter of GM_T's range over θz from its maximum.
    prob = ch4.setup.problem("theta_z", density=40)
    at2, ours = evaluate(prob, [np.deg2rad(2.0)]), evaluate(prob, [np.deg2rad(th2)])
    gmt = theta.arrays["sweep_GM_T"]
    assert ours["C2"] >= at2["C2"]
    assert ours["GM_T"] - at2["GM_T"] < 0.25 * (gmt.max() - gmt.min())
    assert rows["C2 at θz = 2° / C2 at our optimum"].ours == pytest.approx(at2["C2"] / ours["C2"], rel=1e-12)


def test_theta_z_c1_is_mirror_symmetric(theta):
    # C1 cannot tell θz from −θz (W and the HI's θ1 limits are symmetric), so its θz optimum is a mirror pair.
    c1 = theta.arrays["sweep_C1"]
    assert theta.arrays["theta_deg"] == pytest.approx(-theta.arrays["theta_deg"][::-1])
    np.testing.assert_allclose(c1, c1[::-1], rtol=1e-12)
    assert not np.allclose(theta.arrays["sweep_GM_T"], theta.arrays["sweep_GM_T"][::-1], rtol=1e-3)  # C2 is not
    assert _rows(theta)["max |C1(θz) − C1(−θz)| over the sweep"].ours < 1e-12


def test_theta_z_indices_are_near_the_thesis(theta):
    rows = _rows(theta)
    for which in ("C1", "C2"):  # same order of magnitude as the thesis's 0.038–0.044 (±20 %)
        assert rows[f"GM_M at the {which} optimum"].relative == pytest.approx(0, abs=0.2)
        assert rows[f"GM_T at the {which} optimum"].relative == pytest.approx(0, abs=0.2)
    assert rows["GM_T at the C2 optimum"].ours >= rows["GM_T at the C1 optimum"].ours


@pytest.fixture(scope="module")
def full() -> object:
    return ch4.full_design(density=40, maxiter=15, popsize=8, executor=SerialExecutor())


def test_baseline_weights_satisfy_table_4_1():
    # Table 4.1's C2 design beats its C1 design on C2 only for K2/K1 >= 11.46; our baseline respects that.
    t = ch4.setup.THESIS_TABLE
    k = ch4.setup.K2_MIN_TABLE_4_1
    assert k == pytest.approx(11.46, abs=0.01)
    c2 = {w: ch4.setup.K1 * t[w]["GC_M"] + ch4.setup.K2 * t[w]["GM_T"] for w in ("C1", "C2")}
    assert ch4.setup.K2 / ch4.setup.K1 > k and c2["C2"] > c2["C1"]


def test_table_4_1_qualitative_result(full):
    rows = _rows(full)
    # Thesis: C1 gives the larger GM_M and GC_M, C2 the larger GM_T — all hold with K2/K1 = 20 ...
    assert rows["GM_M, C1 optimum"].ours > rows["GM_M, C2 optimum"].ours
    assert rows["GC_M, C1 optimum"].ours > rows["GC_M, C2 optimum"].ours
    gmt_c1 = max(rows["GM_T, C1 optimum"].ours, rows["GM_T, mirror image (−θz) of the C1 optimum"].ours)
    assert rows["GM_T, C2 optimum"].ours > gmt_c1  # against both mirror designs of C1
    # C1's l2 is at its upper bound, as in the thesis (C2's: test_table_4_1_c2_l2)
    assert T.TABLE_4_1["C1"]["l2"].within(rows["l2, C1 optimum"].ours)
    gmt_l2 = full.arrays["l2_scan_GM_T"]
    assert np.all(np.diff(gmt_l2) > 0) and gmt_l2[-1] > 1.5 * gmt_l2[0]
    assert all(np.isfinite(full.arrays[f"energy_{i}"]).all() for i in range(4))
    # Fig. 4.7's second reading (eq. 4.21's (J_T J_Tᵀ)⁻¹, Λ_T = diag(σ²)): a row per design, its own number
    every = [r for t in full.tables for r in t.rows]
    sq = [r for r in every if r.quantity.startswith("mean ‖q̇‖² A→B with Λ_T = diag(σ²)")]
    lit = [r for r in every if r.quantity.startswith("mean ‖q̇‖² A→B, ")]
    assert len(sq) == len(lit) == 4 and all(a.ours > 0 and a.ours != b.ours for a, b in zip(sq, lit))
    # ... and at the designs the thesis prints (a third reading): the same function at those designs
    printed = {r.quantity.split(", ", 1)[1]: r.ours for r in every
               if r.quantity.startswith("thesis's design: mean ‖q̇‖² A→B, ")}
    assert len(printed) == 4
    t = T.TABLE_4_1["C2"]
    x = [t["l2"], np.deg2rad(t["theta_z"]), t["z_ph"]]
    want = np.nanmean(ch4.setup.energy_along_task(ch4.setup.problem("full", density=40), x)[1])
    assert printed["l2, θz, Z_PH, C2"] == pytest.approx(want, rel=1e-12)


def test_with_equal_weights_c2_shortens_l2_but_loses_gm_t():
    # K2/K1 = 10 (below Table 4.1's bound of 11.5): C2's optimum moves to the short-l2, high-GC basin, so the
    # thesis's "C1 has the larger l2" holds, but GC_M is ordered against the thesis and C2's GM_T falls below
    # that of one of C1's two mirror designs (ch4 module docstring).
    prob = ch4.setup.problem("full", density=40, K2=10.0)
    o1 = optimize(prob, "C1", seed=0, maxiter=15, popsize=8)
    o2 = optimize(prob, "C2", seed=0, maxiter=15, popsize=8)
    mirror = evaluate(prob, ch4.setup.mirror(prob, o1.x))
    assert mirror["C1"] == pytest.approx(o1.values["C1"], rel=1e-12)
    assert o2.params["l2"] < o1.params["l2"] - 0.01
    assert o1.values["GM_M"] > o2.values["GM_M"]
    assert o2.values["GC_M"] > o1.values["GC_M"]
    assert o2.values["GM_T"] < max(o1.values["GM_T"], mirror["GM_T"])


def test_sensitivity_and_figures_draw(theta, full):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rhi.plots import ch4 as pl4

    sens = ch4.sensitivity(density=20, densities=(10.0, 20.0), maxiter=3, k2_values=(20.0,),
                           variants=("baseline", "r0 = 0.25 m fixed"), executor=SerialExecutor())
    a = sens.arrays
    assert a["k2_values"].tolist() == [20.0]
    assert np.all(a["k2_l2_C1"] <= 0.365 + 1e-9) and np.all(a["k2_l2_C2"] >= 0.165 - 1e-9)
    assert len(sens.tables[1].rows) == 2 * 2 and len(sens.tables[2].rows) == 2
    with pytest.raises(InvalidInput, match="variants"):
        ch4.sensitivity(density=20, densities=(10.0, 20.0), variants=("r0 = 1 km",), executor=SerialExecutor())
    for fig in (pl4.fig4_4(theta), pl4.theta_sweep(theta), pl4.fig4_5(full), pl4.fig4_6(full), pl4.fig4_7(full),
                pl4.l2_scan(full), pl4.k2_scan(sens), pl4.convergence(sens)):
        assert fig.axes
        plt.close(fig)


@pytest.mark.xfail(strict=True, reason="GM_T's best value rises with l2 for rhi's slave (its ME is larger than the "
                                      "HI's over W), so C2 keeps l2 at its 0.365 m bound like C1 at every K2/K1 that "
                                      "Table 4.1 allows (ch4 docstring); the thesis's 0.269 m needs a set-up it does "
                                      "not publish")
def test_table_4_1_c2_l2(full):
    assert T.TABLE_4_1["C2"]["l2"].within(_rows(full)["l2, C2 optimum"].ours)


@pytest.mark.xfail(strict=True, reason="scored at the thesis's C2 design rhi's GM_T is 0.0593, outside the printed "
                                      "0.0590 ± 0.00005: the slave workspace W and placement r0 are rhi's choices")
def test_table_4_1_gm_t_at_the_thesis_design(full):
    assert T.TABLE_4_1["C2"]["GM_T"].within(_rows(full, 1)["GM_T at the thesis's C2 design (our set-up)"].ours)
