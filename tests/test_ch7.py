"""Chapter 7 experiments: Fig. 7.1 (3-DoF example) and Fig. 7.5 (percent deficiency map)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import row, serial_equals_pool

from rhi.errors import InvalidInput
from rhi.experiments import ch7


@pytest.fixture(scope="module")
def fig71():
    return ch7.example_3dof(steps=101)


def test_fig7_1_scaling_gap_matches_thesis(fig71):
    # thesis §7.3: simple scaling's peak force is 12 % lower than ASCM's (rounded to 1 %)
    gap = row(fig71, "peak force deficit of scaling vs ASCM (pseudoinverse")
    assert gap.ours == pytest.approx(12.0, abs=0.5)
    # the dynamically consistent J# of eq. 7.5 (planar3r link masses) does not give the thesis's 12 %:
    # the independent check of issue 13 found 38.4 %
    assert row(fig71, "peak force deficit of scaling vs ASCM (dynamic").ours == pytest.approx(38.4, abs=0.05)
    print(f"\nFig 7.1 peaks (pseudoinverse): none {row(fig71, 'peak |F_out|, none (pse').ours:.3f} N, "
          f"scaling {row(fig71, 'peak |F_out|, scaling (pse').ours:.3f} N, "
          f"ASCM {row(fig71, 'peak |F_out|, ascm (pse').ours:.3f} N; gap {gap.ours:.2f} %")


def test_fig7_1_shapes(fig71):
    a = fig71.arrays
    Fe = a["Fe"]
    # no compensation distorts the direction; scaling and ASCM keep F_out parallel to F_e
    assert np.abs(a["force_none"][:, 1]).max() > 0.05
    for meth in ("scaling", "ascm", "lp"):
        assert np.abs(a[f"force_{meth}"][:, 1]).max() < 1e-9
        assert np.all(np.abs(a[f"tau_{meth}"]) <= 0.5 + 1e-12)
    # ASCM renders the full force until two joints are at their limits (α = 1 before that)
    full = a["alpha_ascm"] >= 1 - 1e-12
    np.testing.assert_allclose(a["force_ascm"][full], Fe[full], atol=1e-9)
    assert row(fig71, "joints at a torque limit when ASCM first scales").ours == 2
    # ASCM's peak equals the LP optimum here and beats scaling
    assert row(fig71, "peak |F_out|, ascm (pse").ours == pytest.approx(row(fig71, "LP optimum").ours, rel=1e-9)
    assert row(fig71, "peak |F_out|, ascm (dyn").ours > row(fig71, "peak |F_out|, scaling (dyn").ours


def test_fig7_5_deficiency_map_reduced():
    res = ch7.deficiency_map(resolution=5)
    a = res.arrays
    ok = np.isfinite(a["pd"])
    assert ok.sum() >= 8
    assert np.all(a["pd"][ok] >= -1e-9)  # ASCM is never worse than scaling (thesis Fig. 7.5)
    assert np.all(a["f_ascm"][ok] <= a["f_lp"][ok] * (1 + 1e-7))
    assert np.all(a["pd_lp"][ok] >= a["pd"][ok] - 1e-9)
    okd = np.isfinite(a["pd_dynamic"])  # the dynamically consistent J# map beside the J⁺ one
    assert np.array_equal(okd, ok) and np.all(a["pd_dynamic"][ok] >= -1e-9)
    assert np.all(a["f_ascm_dynamic"][ok] <= a["f_lp_dynamic"][ok] * (1 + 1e-7))


def test_deficiency_map_serial_equals_local_pool():
    a = serial_equals_pool(ch7.deficiency_map, 4, ("pd", "pd_lp", "f_wo", "f_ascm", "f_lp"))
    assert np.isfinite(a.arrays["pd"]).sum() >= 4
    with pytest.raises(InvalidInput, match="projector"):
        ch7.deficiency_map(resolution=3, projectors=("kinematik",), workers=1)


def test_ch7_figures_draw(fig71):
    import matplotlib

    matplotlib.use("Agg")
    from rhi.plots import ch7 as pl7

    fig = pl7.example_3dof(fig71)
    assert len(fig.axes) == 4
    res = ch7.deficiency_map(resolution=3)
    assert pl7.deficiency_map(res) is not None


def test_vme_values_equal_the_objectives_one_configuration_at_a_time():
    """The batched ν of a VME-matching objective along a log equals its `value` per configuration."""
    from rhi.control import EllipsoidMatching, JointLimitBarrier, VMEMatching
    from rhi.devices.model import device
    from rhi.experiments.setups import vme_values

    dev = device("rhi4")
    Q = np.random.default_rng(3).uniform(dev.q_min, dev.q_max, size=(40, dev.n))
    M = np.array(ch7.contact.M_DES)
    for objective in (VMEMatching((1.0, 0.0)), EllipsoidMatching(M), EllipsoidMatching(M, H=np.diag([1.0, 2.0]))):
        one = np.array([objective.value(dev, q) for q in Q])
        np.testing.assert_allclose(vme_values(dev, objective, Q), one, rtol=1e-12, atol=1e-12)
    with pytest.raises(InvalidInput, match="objective"):
        vme_values(dev, JointLimitBarrier(0.1, 0.01), Q)
