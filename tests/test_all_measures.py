"""`rhi.all_measures` (one factorisation of J and M per call) equals the individual public measure functions."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_q

import rhi
import rhi.metrics as rm


def _individual(dev: rhi.Device, q: np.ndarray, u: np.ndarray, lp: bool) -> dict[str, object]:
    """Every measure of `rhi.all_measures`, each from its own public function (the reference)."""
    J, M = dev.jacobian(q), dev.mass_matrix(q)
    lo, hi = dev.torque_limits
    tmax = np.maximum(np.abs(lo), np.abs(hi))

    def full_rank(fn):
        try:
            return fn()
        except rhi.errors.Singular:
            return None

    out: dict[str, object] = {
        "x [m]": dev.fk(q), "J": J, "rank J": int(np.linalg.matrix_rank(J)),
        "within_limits": bool(dev.within_limits(q)),
        "velocity_ellipsoid JJᵀ (3.5)": rm.velocity_ellipsoid(J),
        "effective_manipulability ρ (3.6)": rm.effective_manipulability(J, u),
        "effective_inertia Λ [kg] (3.13)": rm.effective_inertia(J, M, u),
        "apparent_inertia M_x [kg] (3.12)": full_rank(lambda: rm.apparent_inertia(J, M)),
        "manipulability μ (4.7)": rm.manipulability(J),
        "isotropy 1/κ (4.9)": rm.isotropy(J),
        "velocity_transmission σ (4.4)": rm.velocity_transmission(J, u),
        "reflected_friction λ (4.6)": rm.reflected_friction(J, u),
        "force_ellipsoid M̂ (6.9)": full_rank(lambda: rm.force_ellipsoid(J, tmax)),
        "directional_manipulability DM [N] (A.8)": rm.directional_manipulability(J, u, tmax),
        "max_force_scaling [N]": rm.max_force_scaling(J, u, torque_min=lo, torque_max=hi),
    }
    if lp:
        out["max_force (LP, dynamic projector) [N]"] = full_rank(
            lambda: rm.max_force(J, u, torque_min=lo, torque_max=hi, projector="dynamic", M=M))
    return out


def _assert_close(got, want, key: str) -> None:
    if want is None:
        assert got is None, key
        return
    want = np.asarray(want, dtype=float)
    got = np.asarray(got, dtype=float)
    assert got.shape == want.shape, key
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * max(float(np.abs(want).max(initial=0.0)), 1e-300),
                               err_msg=key)


@pytest.mark.parametrize("name", ["rhi4", "planar3r", "phantom", "gen3", "srhi5"])
def test_all_measures_equal_the_individual_functions(name, rng):
    dev = rhi.device(name)
    for k, q in enumerate(random_q(dev, rng, 6)):
        u = rng.normal(size=dev.m)
        lp = k == 0 and dev.n > dev.m
        res = rhi.all_measures(dev, q, u, exact_force=lp)
        ref = _individual(dev, q, u, lp)
        assert np.allclose(res["u"], u / np.linalg.norm(u), rtol=0, atol=1e-15)
        assert res["singular"] is (ref["rank J"] < dev.m)
        for key, want in ref.items():
            _assert_close(res[key], want, key)
        assert set(res) == set(ref) | {"device", "q", "u", "singular", "undefined (singular J)"}


def test_all_measures_at_a_singular_configuration():
    dev = rhi.device("gen3")
    q = np.zeros(dev.n)
    u = np.array([0.0, 0.0, 1.0])
    res = rhi.all_measures(dev, q, u)
    ref = _individual(dev, q, u, True)
    assert res["singular"] is True and res["rank J"] == ref["rank J"] < 3
    assert res["undefined (singular J)"] == ["apparent_inertia M_x [kg] (3.12)", "force_ellipsoid M̂ (6.9)",
                                             "max_force (LP, dynamic projector) [N]"]
    for key, want in ref.items():
        _assert_close(res[key], want, key)


def test_measure_all_refuses_a_batch():
    J, M = np.ones((5, 2, 3)), np.broadcast_to(np.eye(3), (5, 3, 3))
    with pytest.raises(rhi.errors.InvalidInput, match="^J: "):
        rm.measure_all(J, M, [1.0, 0.0], torque_min=-np.ones(3), torque_max=np.ones(3))
    with pytest.raises(rhi.errors.InvalidInput, match="^q: "):
        rhi.all_measures(rhi.device("rhi4"), np.zeros((2, 4)))
