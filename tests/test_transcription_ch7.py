"""rhi's ASCM against a second, independent transcription of the thesis's Algorithm 1 (§7.3; issue 23).

`tests/ascm_transcription.py` is Algorithm 1 line by line in plain NumPy. With the plain pseudoinverse
the two are the same allocation; with §7.2's J# they differ while one joint is held (Algorithm 1's
null-space torque is (I − JᵀJ#ᵀ) applied to a τ_N on the held joints, eq. 7.8; rhi's `ascm` takes the
least-norm torque of the same null space) and agree once n − m joints are held; the static capability
along u, which §7.5 compares, is the same under both (each reaches the LP optimum of its null space).
"""

from __future__ import annotations

import ascm_transcription as tr
import numpy as np
import pytest
from conftest import random_q

from rhi.control.allocation import force_capability
from rhi.control.allocation.compensation import ascm
from rhi.control.saturation import null_basis

HI = np.array([3.0, 3.0, 1.0, 1.0])
LO = -HI
U = np.array([0.0, 1.0])
#: The contact configuration of `rhi.experiments.ch7.palpation` (quick run, start "optimum") [rad].
Q_CONTACT = np.array([-0.12091281, 0.07136757, 1.44736453, 1.28543857])


def _requests(J, rng, k):
    """K force requests along random directions, from just past the first saturation to 2.5× it [N]."""
    out = []
    for _ in range(k):
        u = rng.normal(size=2)
        u /= np.linalg.norm(u)
        f = tr.scaling_capability(J, u, LO, HI) * rng.uniform(1.02, 2.5)
        out.append(f * u)
    return out


def test_pseudoinverse_ascm_is_algorithm_1(rhi4, rng):
    """J⁺: rhi's `ascm` equals Algorithm 1 (most overloaded joint relative to its span) to 1e-9 N m.

    Compared wherever Algorithm 1's torque is within the bounds (its α is taken at joint k only).
    """
    compared = 0
    for q in random_q(rhi4, rng, 25):
        J = rhi4.jacobian(q)
        if np.linalg.svd(J, compute_uv=False)[-1] < 1e-2:
            continue
        Z = null_basis(J)
        for F in _requests(J, rng, 6):
            tau, alpha, S = tr.algorithm1(J, None, -F, np.zeros(2), LO, HI, overload="relative")
            if np.any(tau > HI + 1e-9) or np.any(tau < LO - 1e-9):
                continue
            al = ascm(J.T @ F, np.zeros(4), Z, torque_min=LO, torque_max=HI)
            np.testing.assert_allclose(al.tau, tau, atol=1e-9)
            assert al.alpha == pytest.approx(alpha, abs=1e-9)
            assert (al.saturated == S).all()
            compared += 1
    assert compared >= 60


def test_dynamic_ascm_differs_from_algorithm_1_while_one_joint_is_held(rhi4):
    """J#: with one joint held, Algorithm 1's τ_N (eq. 7.8, on the held joint) is not rhi's least-norm torque.

    Both hold joint 4 at its limit and render the same force J#ᵀτ; the free joints differ. Pinned so that a
    change of either shows; the §7.5 dossier reports the two readings.
    """
    J, M = rhi4.jacobian(Q_CONTACT), rhi4.mass_matrix(Q_CONTACT)
    f = 1.01 * tr.scaling_capability(J, U, LO, HI)
    tau, alpha, S = tr.algorithm1(J, M, -f * U, np.zeros(2), LO, HI)
    al = ascm(f * (J.T @ U), np.zeros(4), null_basis(J, M), torque_min=LO, torque_max=HI)
    assert S.tolist() == al.saturated.tolist() == [False, False, False, True]
    assert tau[3] == pytest.approx(HI[3]) and al.tau[3] == pytest.approx(HI[3])
    Jsh_T = tr.generalized_inverse(J, M).T
    np.testing.assert_allclose(Jsh_T @ tau, f * U, atol=1e-9)
    np.testing.assert_allclose(Jsh_T @ al.tau, f * U, atol=1e-9)
    assert np.abs(tau - al.tau).max() > 0.05


@pytest.mark.parametrize("projector", ["dynamic", "pseudoinverse"])
def test_static_capability_is_algorithm_1s(rhi4, projector):
    """§7.5's static measure: the peak of Algorithm 1 over a force ramp equals `force_capability(method="ascm")`.

    At the contact configuration, to 1e-3 N (the ramp's step), for J# (+2.4 % over scaling) and J⁺ (+101 %).
    """
    J, M = rhi4.jacobian(Q_CONTACT), rhi4.mass_matrix(Q_CONTACT)
    Mp = M if projector == "dynamic" else None
    f_s = tr.scaling_capability(J, U, LO, HI)
    ours = force_capability(J, U, torque_min=LO, torque_max=HI, method="ascm", projector=projector, M=Mp)
    theirs, _ = tr.capability(J, Mp, U, LO, HI, forces=np.linspace(f_s, 3.0 * f_s, 4001))
    assert ours == pytest.approx(theirs, abs=1e-3)
    gain = 100.0 * (theirs / f_s - 1.0)
    assert (gain < 5.0) if projector == "dynamic" else (gain > 90.0)


def test_fig_7_1_deficit_is_algorithm_1s():
    """Fig. 7.1: simple scaling's peak force below Algorithm 1's, transcribed, equals `ch7.example_3dof`'s rows.

    Planar 3R at [π/4, −π/3, −π/6], ±0.5 N m, F_e = [4 sin(πt/2), 0] N; F_out = J#ᵀ or J⁺ᵀ of the torques in the
    box; to 0.01 %: J⁺ 11.9 % (thesis 12 %), J# with rhi's planar3r masses 38.4 %.
    """
    import rhi
    from rhi.experiments import ch7

    dev = rhi.device("planar3r")
    q = np.array([np.pi / 4, -np.pi / 3, -np.pi / 6])
    J, M = dev.jacobian(q), dev.mass_matrix(q)
    lo, hi = dev.torque_limits
    t = np.linspace(0.0, 2.0, 401)
    Fe = np.stack([4.0 * np.sin(np.pi * t / 2.0), np.zeros_like(t)], axis=1)
    res = ch7.example_3dof(steps=401)
    rows = {r.quantity: r.ours for tb in res.tables for r in tb.rows}
    for Mp, name in ((None, "pseudoinverse"), (M, "dynamic")):
        Jsh_T = tr.generalized_inverse(J, Mp).T
        peak_ascm = max(np.linalg.norm(Jsh_T @ np.clip(tr.algorithm1(J, Mp, -F, np.zeros(2), lo, hi)[0], lo, hi))
                        for F in Fe)
        peak_scaling = max(min(np.linalg.norm(F), tr.scaling_capability(J, F, lo, hi)) for F in Fe[1:])
        ours = next(v for k, v in rows.items() if k.startswith(f"peak force deficit of scaling vs ASCM ({name}"))
        assert 100.0 * (1.0 - peak_scaling / peak_ascm) == pytest.approx(ours, abs=0.01)
