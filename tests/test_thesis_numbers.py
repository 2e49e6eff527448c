"""Thesis numbers computed through the bundled devices (not hand-written Jacobians)."""

from __future__ import annotations

import numpy as np
import pytest

import rhi
from rhi import metrics, thesis as T


def test_planar3r_scaling_is_12_percent_below_optimum():
    """§7.3: at q = [π/4, −π/3, −π/6], u = [1, 0], ±0.5 N·m, simple scaling gives 12 % less force."""
    dev = rhi.device("planar3r")
    J = dev.jacobian([np.pi / 4, -np.pi / 3, -np.pi / 6])
    lo, hi = dev.torque_limits
    f_scale = float(metrics.max_force_scaling(J, [1, 0], torque_min=lo, torque_max=hi))
    f_opt, tau = metrics.max_force(J, [1, 0], torque_min=lo, torque_max=hi, projector="pseudoinverse", return_torque=True)
    print(f"planar3r §7.3: scaling {f_scale:.4f} N, pseudoinverse-projector optimum {float(f_opt):.4f} N")
    assert T.SCALING_GAP.within(100 * (1 - f_scale / float(f_opt)))
    assert np.sum(np.isclose(np.abs(tau), 0.5, atol=1e-7)) == 2  # two joints saturated (Fig. 7.1c)


def test_planar3r_home_ellipsoid_weights():
    """§6.3.1: torque bounds 0.5 N·m give the FME scaling W = diag(2, 2, 2)."""
    dev = rhi.device("planar3r")
    J = dev.jacobian([np.pi / 6, -np.pi / 3, -3 * np.pi / 4])
    np.testing.assert_allclose(metrics.force_ellipsoid(J, dev.torque_limits[1]), np.linalg.inv(4 * J @ J.T), rtol=1e-12)


def test_gen3_start_position():
    """§A.4.1: q0 puts the end-effector at x0 = [0.65, −0.0246, 0.4921] m."""
    x = rhi.device("gen3").fk(np.array([0, np.pi / 6, 0, np.pi / 2, 0, -np.pi / 6, 0]))
    np.testing.assert_allclose(x, [0.65, -0.0246, 0.4921], atol=5e-5)  # the thesis's rounding


@pytest.mark.xfail(strict=True, reason="rhi's Gen3 model (Kinova's published link lengths, models/gen3) gives DM "
                                      "1.1244 along z and 3.8240 along x: 0.05 % and 0.03 % below the printed 1.125 "
                                      "and 3.825, beyond their last digit; the thesis's model is not published")
def test_gen3_directional_manipulability():
    """App. A.4.3: DM with W_τ = diag(1, 1, 1, 1, 2.5, 2.5, 2.5) is 1.125 along z and 3.825 along x."""
    dev = rhi.device("gen3")
    q = np.array([0, np.pi / 6, 0, np.pi / 2, 0, -np.pi / 6, 0])
    J = dev.jacobian(q)
    weights = 1 / np.array([1, 1, 1, 1, 2.5, 2.5, 2.5])  # torque_max whose inverse is the thesis's W_τ
    assert T.DM_Z[0].within(metrics.directional_manipulability(J, [0, 0, 1], weights))
    assert T.DM_X[0].within(metrics.directional_manipulability(J, [1, 0, 0], weights))
