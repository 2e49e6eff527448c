"""§7.5 on the simulated rhi4: palpation with and without ASCM (and the per-tick LP optimum)."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest
from conftest import assert_progress_complete, assert_serialises_and_draws, row

from rhi.errors import InvalidInput
from rhi.experiments.ch7 import contact as ex
from rhi.plots import ch7_palpation as pl

matplotlib.use("Agg")

CASES = [("none", "dynamic"), ("ascm", "dynamic"), ("lp", "dynamic")]


PROGRESS: list[tuple[int, int]] = []


@pytest.fixture(scope="module")
def short():
    """Reduced run: start at the tertiary objective's optimum, a 2 cm push at 4 cm/s, three cases."""
    return ex.palpation(start="optimum", settle=0.3, depth=0.02, speed=0.04, hold=0.1, cases=CASES,
                        progress=lambda k, n: PROGRESS.append((k, n)))


def test_torques_stay_within_the_programmed_limits(short):
    for sat, proj in CASES:
        assert row(short, f"max |τ_i| / limit, {sat} ({proj}").ours <= 1.0 + 1e-12
        tau = short.arrays[f"{sat}_{proj}_tau"]
        assert np.all(np.abs(tau) <= np.asarray(ex.TORQUE_MAX) + 1e-12)
    # every case drives at least one joint to its limit: the push exceeds the force capability
    assert all(np.isfinite(short.arrays[f"{s}_{p}_events"][0]) for s, p in CASES)


def test_rendered_force_tracks_the_wall_until_saturation(short):
    """Before any joint saturates, the F/T force follows K_e δX up to the plant's uncompensated joint friction.

    That friction is Coulomb 0.02 N m on the rehab motors over ~0.2 m levers: ~0.1 N at the handle (§7.5 compensates
    none).
    """
    for sat, proj in CASES:
        err = row(short, f"max |F − K_e δX| in contact (K_e δX ≥ 1 N) before the first torque saturation, "
                          f"{sat} ({proj}")
        assert err.ours < 0.2
    a = short.arrays
    k = a["none_dynamic_t"] < a["none_dynamic_events"][0]
    assert a["none_dynamic_F_des"][k].max() > 4.0  # the check covered a real force range


def test_one_criterion_for_every_case_and_safe_self_motion(short):
    """Item 4/5 of issue 13: every case's peak force before a range limit, ASCM and LP against no compensation.

    With ASCM holding two joints, the null-space damping and limit barrier keep the self-motion <= 1 rad/s.
    """
    f = {c: row(short, f"max force before a joint reaches a range limit, {c[0]} ({c[1]}").ours for c in CASES}
    for sat in ("ascm", "lp"):
        g = row(short, f"peak force before a joint range limit, {sat} (dynamic) vs none (dynamic)")
        assert g.ours == pytest.approx(100.0 * (f[sat, "dynamic"] / f["none", "dynamic"] - 1.0))
    # without compensation the first clipped tick comes at the simple-scaling capability of the configuration
    assert f["none", "dynamic"] == pytest.approx(float(short.arrays["capability_scaling"]), rel=0.05)
    # the allocations render at least what scaling does (to the plant's uncompensated friction, ~0.1 N)
    assert f["ascm", "dynamic"] > f["none", "dynamic"] - 0.1 and f["lp", "dynamic"] > f["none", "dynamic"] - 0.1
    held = row(short, "share of the ticks after the first saturation with two joints held, ascm (dynamic").ours
    speed = row(short, "peak self-motion joint speed while the allocation holds two joints, ascm (dynamic").ours
    assert held > 0.5 and speed <= 1.0
    print(f"\npeak force before a range limit: none {f['none', 'dynamic']:.3f} N, ASCM {f['ascm', 'dynamic']:.3f} N, "
          f"LP {f['lp', 'dynamic']:.3f} N; ASCM holds two joints in {held:.0%} of the ticks after saturation, "
          f"self-motion peak {speed:.2f} rad/s")


def test_static_capabilities_are_ordered(short):
    a = short.arrays
    s = float(a["capability_scaling"])
    for proj in ("dynamic", "pseudoinverse"):
        ascm, lp = float(a[f"capability_ascm_{proj}"]), float(a[f"capability_lp_{proj}"])
        assert s <= ascm * (1 + 1e-9) and ascm <= lp * (1 + 1e-9)
    # the tertiary objective's configuration: with J⁺ the redistribution roughly doubles the capability,
    # with the dynamically consistent J# it adds only a few percent
    assert float(a["capability_ascm_pseudoinverse"]) > 1.5 * s
    assert float(a["capability_ascm_dynamic"]) < 1.2 * s


def test_contact_configuration_is_the_tertiary_optimum(short, rhi4):
    a = short.arrays
    np.testing.assert_allclose(a["q_contact"], a["q_optimum"], atol=2e-3)
    np.testing.assert_allclose(rhi4.fk(a["q_contact"]), ex.X0, atol=1e-9)
    assert row(short, "max handle drift while settling").ours < 0.5


def test_result_serialises_and_figures_draw(short):
    assert_serialises_and_draws(short, pl.fig7_6, pl.force_penetration, pl.settling)


def test_progress_reaches_the_total(short):
    assert_progress_complete(PROGRESS)


def test_bad_input():
    with pytest.raises(InvalidInput, match="depth"):
        ex.palpation(depth=0.0)
    with pytest.raises(InvalidInput, match="cases"):
        ex.palpation(cases=[("ascm", "sideways")])
    with pytest.raises(InvalidInput, match="start"):
        ex.palpation(start="anywhere")
    with pytest.raises(InvalidInput, match="hold"):
        ex.palpation(hold=-1.0)
