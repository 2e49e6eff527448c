"""rhi's ch. 6 configuration matching (§6.4, Fig. 6.10) against an independent transcription (issue 23).

`tests/fme_transcription.py` runs the null-space controller of eqs. 6.2–6.6 with the handle held as a
flow along the self-motion manifold, in plain NumPy from the thesis text. These tests feed it and rhi
the same start configurations and compare where each settles, the §6.4 matches and Fig. 6.10's
F_max ratio; a planted difference (the unweighted FME (JJᵀ)⁻¹ instead of eq. 6.9's) shows each
comparison can fail.
"""

from __future__ import annotations

import fme_transcription as ft
import numpy as np
import pytest
from conftest import random_q

from rhi.control import FMEMatching, WeightedSum
from rhi.experiments.ch6 import fmax_ratio_map
from rhi.experiments.ch6.setup import (
    Q_HOME,
    X0,
    U,
    best_match,
    controller_terms,
    desired_fmes,
    match_fme,
    start_configurations,
)

Q_TOL = 1e-5  # [rad]: the flow and SLSQP's settling meet to about 1e-7 rad; ν and F_max follow to ~1e-9


@pytest.fixture(scope="module")
def fmes(rhi4):
    _, _, Mf, Ms = desired_fmes(rhi4, np.array(U), Q_HOME)
    return {"free": Mf, "stiff": Ms}


def test_the_transcribed_kinematics_are_rhis(rhi4, rng):
    for q in random_q(rhi4, rng, 20):
        np.testing.assert_allclose(ft.jacobian(q), rhi4.jacobian(q), atol=1e-12)
        np.testing.assert_allclose(ft.fk(q), rhi4.fk(q), atol=1e-12)
        assert ft.within(q) == bool(rhi4.within_limits(q))


def test_section_6_4_matches_are_where_the_null_space_flow_settles(rhi4, fmes):
    """At X₀ rhi's matches are where eqs. 6.2–6.6 settle from every start, the home configuration's included.

    From each of rhi's three starts and from q = 0 projected onto X₀ (the only configuration §6.4 names),
    the transcribed flow settles where rhi's `match_fme` does (1e-5 rad); from q = 0 at rhi's `best_match`,
    the lowest of them: ν = 0.2390 (M_Free^des) and 0.4655
    (M_Stiff^des) with rhi's joint-limit barrier, the minimum of the cost the controller descends, not a
    local one. Without the barrier (the thesis's law on hard stops) the flow from q = 0 slides along the
    stops to the minima of eq. 6.10 alone within the limits, ν = 0.2199 and 0.4537, a stop binding in each.
    """
    x0 = np.array(X0)
    home = ft.onto(x0, np.zeros(4))
    assert home is not None and ft.within(home)
    nus = {}
    for case, M_des in fmes.items():
        for limits, gain in ((True, 100.0), (False, 0.0)):
            obj = WeightedSum(controller_terms(M_des, rhi4.torque_max, limits=limits))
            cost = ft.matching_cost(M_des, limit_gain=gain)
            settled = []
            for s in [home, *start_configurations(rhi4, x0, 3)]:  # each start: the same basin, the same point
                q_tr = ft.null_space_flow(cost, rhi4.mass_matrix, x0, s)
                np.testing.assert_allclose(q_tr, match_fme(rhi4, x0, obj, s), atol=Q_TOL)
                settled.append(q_tr)
            q_rhi = best_match(rhi4, x0, obj, starts=3)
            np.testing.assert_allclose(settled[0], q_rhi, atol=Q_TOL)  # from q = 0: rhi's match
            assert cost(q_rhi) == pytest.approx(min(cost(q) for q in settled), abs=1e-8)
            nus[case, limits] = FMEMatching(M_des, rhi4.torque_max).value(rhi4, q_rhi)
            assert bool(np.min(ft.limit_distances(q_rhi)) < 1e-7) is (not limits)  # a stop binds without the barrier
    assert [round(nus[k], 4) for k in (("free", True), ("stiff", True), ("free", False), ("stiff", False))] == [
        0.239, 0.4655, 0.2199, 0.4537]


def test_a_planted_difference_moves_the_section_6_4_match(rhi4, fmes):
    """The same flow on the unweighted FME (JJᵀ)⁻¹ (W = I instead of eq. 6.9's diag(1/T)) settles elsewhere."""
    x0 = np.array(X0)
    q_rhi = best_match(rhi4, x0, WeightedSum(controller_terms(fmes["free"], rhi4.torque_max)), starts=3)
    cost = ft.matching_cost(fmes["free"], weights=np.ones(4))
    q_tr = ft.null_space_flow(cost, rhi4.mass_matrix, x0, ft.onto(x0, np.zeros(4)))
    assert np.max(np.abs(q_tr - q_rhi)) > 100 * Q_TOL


def _transcribed_ratio(dev, x, fmes, weights=ft.T):
    """F_max(M_Stiff)/F_max(M_Free) by force scaling, each matched from rhi's two starts, the lowest cost kept."""
    starts = start_configurations(dev, x, 2)
    f = {}
    for case, M_des in fmes.items():
        cost = ft.matching_cost(M_des, weights=weights)
        q = min((ft.null_space_flow(cost, dev.mass_matrix, x, s) for s in starts), key=cost)
        f[case] = ft.fmax_scaling(q, np.array(U))
    return f["stiff"] / f["free"]


def test_fig_6_10_map_equals_the_transcription(rhi4, fmes):
    """Fig. 6.10's F_max ratio from rhi's map = the transcription's at every reached point of a 3 × 3 grid (1e-6).

    The grid holds (0.5, 0.3) and (0.25, 0.3) m, where SLSQP alone (rhi's matching before this test) jumped to
    minima in other basins than the controller's flow reaches from the same starts (ratios 1.108 and 1.405
    instead of the flow's 1.095 and 1.148).
    """
    res = fmax_ratio_map(resolution=3, starts=2, executor="serial")
    xs, ys, ratio = res.arrays["x"], res.arrays["y"], res.arrays["ratio"]
    compared = 0
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            if not np.isfinite(ratio[j, i]):
                continue
            assert _transcribed_ratio(rhi4, np.array([x, y]), fmes) == pytest.approx(ratio[j, i], rel=1e-6)
            compared += 1
    assert compared >= 4 and np.isfinite(ratio[2, 1])  # (0.5, 0.3) m among them
    # planted difference: the unweighted FME gives another ratio at the §6.4 point
    assert abs(_transcribed_ratio(rhi4, np.array(X0), fmes, weights=np.ones(4))
               / _transcribed_ratio(rhi4, np.array(X0), fmes) - 1.0) > 1e-3
