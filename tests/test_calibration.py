"""The labelled thesis-fit parameter variant of rhi4 (issue 23, item 3): loads, differs, leaves the default alone."""

from __future__ import annotations

import numpy as np
import pytest

import rhi
from rhi.devices.spec import bundled_spec
from rhi.devices.variant import available_variants, read_variant
from rhi.errors import InvalidInput
from rhi.experiments import calibration as C

Q = np.array([0.3, 0.5, 0.4, 0.6])


def test_default_model_is_unchanged():
    default, none = rhi.device("rhi4"), rhi.device("rhi4", params="default")
    np.testing.assert_array_equal(default.mass_matrix(Q), none.mass_matrix(Q))
    # the default model's numbers (README.md): rehab link 1 0.6 kg, PHANToM rotor 1.355e-4 kg m²
    assert default.armature.tolist() == [0.0, 0.0, 1.355e-4, 1.355e-4]
    assert default.name == "rhi4"


def test_thesis_fit_variant_loads_with_the_same_kinematics_and_other_inertia():
    fit, default = rhi.device("rhi4", params="thesis-fit"), rhi.device("rhi4")
    assert fit.name == "rhi4:thesis-fit"
    np.testing.assert_array_equal(fit.jacobian(Q), default.jacobian(Q))
    assert np.abs(fit.mass_matrix(Q) - default.mass_matrix(Q)).max() > 1e-3
    for half in ("rehab", "phantom"):
        assert rhi.device(half, params="thesis-fit").name == f"{half}:thesis-fit"


def test_unknown_variant_is_named():
    assert "thesis-fit" in available_variants(bundled_spec("rhi4").folder)
    with pytest.raises(InvalidInput, match="params: .*'nope'.*thesis-fit"):
        rhi.device("rhi4", params="nope")
    with pytest.raises(InvalidInput, match="params"):
        read_variant(bundled_spec("planar3r").folder, "thesis-fit", "planar3r")


def test_stored_variant_is_the_fit_of_its_parameters_and_within_bounds():
    """thesis_fit.toml holds variant_of(p) of its own [fit] parameters, p within BOUNDS.

    The device built from it gives the Λ that `predict` computes (Table 3.1's RHI claim at
    (0.49, −0.22), no sensor mass).
    """
    import tomllib

    doc = tomllib.loads((bundled_spec("rhi4").folder / "thesis_fit.toml").read_text())
    p = np.array([doc["fit"][k] for k in C.NAMES])
    for k, v in zip(C.NAMES, p):
        assert C.BOUNDS[k][1] <= v <= C.BOUNDS[k][2], k
    var = C.variant_of(p)
    np.testing.assert_allclose(doc["armature"], var["armature"], rtol=1e-12)
    for link, values in var["links"].items():
        for key, v in values.items():
            assert doc["links"][link][key] == pytest.approx(v, rel=1e-12)
    dev = rhi.device("rhi4", params="thesis-fit")
    q = np.array([0.125, 0.022, 0.298, 0.175])
    item = {"device": "RHI", "q": q, "sensor": False}
    J, M = dev.jacobian(q), dev.mass_matrix(q)
    lam = 1.0 / float(C.U @ J @ np.linalg.solve(M, J.T @ C.U))
    assert C.predict(p, [item])[0] == pytest.approx(lam, rel=1e-9)


def test_fit_reports_held_out_errors():
    """A reduced fit (2 starts, precomputed Table 6.1 configurations) reports fit and held-out errors."""
    cfg = {"free": np.array([1.2566, 0.3754, -0.0983, 0.8113]), "stiff": np.array([0.0, 0.5, 0.4, -0.3])}
    items = C.claims(cfg)
    assert sum(c["fit"] for c in items) == sum(not c["fit"] for c in items) == 7
    f = C.fit(items, starts=2)
    th = np.array([c["thesis"] for c in items])
    fit_idx = [i for i, c in enumerate(items) if c["fit"]]
    err_fit = np.abs(f["pred_fit"][fit_idx] / th[fit_idx] - 1).mean()
    err_def = np.abs(f["pred_default"][fit_idx] / th[fit_idx] - 1).mean()
    assert err_fit < err_def  # the fit improves on what it was fitted to (held-out: reported, not asserted)


@pytest.mark.parametrize("name", ["rhi4", "rehab", "phantom"])
def test_thesis_fit_plant_has_the_variant_inertia(name):
    """The MuJoCo plant of the variant holds the variant's M (its physics is the calibrated model's)."""
    from rhi.sim import Plant

    dev = rhi.device(name, params="thesis-fit")
    plant = Plant(dev, handle_mass=0.0)  # the plant's own handle mass aside
    q = np.full(dev.n, 0.3)
    plant.reset(q)
    np.testing.assert_allclose(plant.motor_mass_matrix(), dev.mass_matrix(q), rtol=1e-6, atol=1e-8)
    assert np.abs(plant.motor_mass_matrix() - rhi.device(name).mass_matrix(q)).max() > 1e-4  # not the default's
    plant.apply(np.full(dev.n, 0.05))
    plant.step(50)
    assert np.all(np.isfinite(plant.q))
