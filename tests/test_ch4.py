"""Chapter 4 experiments at reduced resolution: the thesis's qualitative results and the θz optimum."""

from __future__ import annotations

import numpy as np
import pytest

from rhi.design import SerialExecutor, evaluate, optimize
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
    # ... and lies 10–15° from the thesis's 2° (see ch4.sensitivity). The difference is explained by the
    # flat landscape: the thesis's θz = 2° scores within 1 % of our optimum's C2 in our set-up.
    prob = ch4.problem("theta_z", density=40)
    c2_thesis = evaluate(prob, [np.deg2rad(2.0)])["C2"]
    c2_ours = evaluate(prob, [np.deg2rad(th2)])["C2"]
    assert c2_ours >= c2_thesis
    assert c2_thesis == pytest.approx(c2_ours, rel=0.01)


def test_theta_z_indices_are_near_the_thesis(theta):
    rows = _rows(theta)
    for which in ("C1", "C2"):  # same order of magnitude as the thesis's 0.038–0.044 (±20 %)
        assert rows[f"GM_M at the {which} optimum"].relative == pytest.approx(0, abs=0.2)
        assert rows[f"GM_T at the {which} optimum"].relative == pytest.approx(0, abs=0.2)
    assert rows["GM_T at the C2 optimum"].ours >= rows["GM_T at the C1 optimum"].ours


@pytest.fixture(scope="module")
def full() -> object:
    return ch4.full_design(density=40, maxiter=15, popsize=8, executor=SerialExecutor())


def test_table_4_1_qualitative_result(full):
    rows = _rows(full)
    assert rows["l2, C1 optimum"].ours > rows["l2, C2 optimum"].ours
    assert rows["GM_M, C1 optimum"].ours > rows["GM_M, C2 optimum"].ours
    assert rows["l2, C1 optimum"].ours == pytest.approx(0.365, abs=1e-3)  # reduced run; C1 drives l2 to its upper bound (thesis)
    assert all(np.isfinite(full.arrays[f"energy_{i}"]).all() for i in range(4))


def test_c2_optimum_has_the_larger_gm_t_when_gm_weighs_more():
    # With K2 = 10 (our baseline) C2's optimum trades GM_T for GC_M; with K2 = 30 the thesis's
    # GM_T ordering appears (documented in ch4.full_design's notes).
    prob = ch4.problem("full", density=40, K2=30.0)
    o1 = optimize(prob, "C1", seed=0, maxiter=15, popsize=8)
    o2 = optimize(prob, "C2", seed=0, maxiter=15, popsize=8)
    assert o2.values["GM_T"] > o1.values["GM_T"]
    assert o1.values["GM_M"] > o2.values["GM_M"]
