"""Chapter 3's claims not reproduced, recomputed in plain NumPy from the thesis's own formulas (issue 23, item 2).

Eq. 3.6 with the closed-form Jacobian the thesis prints for the same RHI (eq. 5.12a) at Table 3.1's printed
configurations, and eqs. 3.17 and 3.19 of the prismatic example. Nothing of rhi's kinematics or metrics is used
in the transcription; rhi's numbers are compared with it.
"""

from __future__ import annotations

import numpy as np
import pytest

from rhi import metrics, thesis as T
from rhi.experiments import ch3

D = (0.254, 0.141, 0.21, 0.181)  # the RHI's links [m] (§3.5; eq. 5.12a's d_i with ch. 3's d2)


def j_rhi(q: np.ndarray) -> np.ndarray:
    """Eq. 5.12a (2, 4)."""
    q1, q2, q3, q4 = q
    d1, d2, d3, d4 = D
    return np.array([
        [-d1 * np.sin(q1), d2 * np.cos(q2) - d3 * np.sin(q2 + q3) + d4 * np.cos(q2 + q4), -d3 * np.sin(q2 + q3),
         d4 * np.cos(q2 + q4)],
        [d1 * np.cos(q1), d2 * np.sin(q2) + d3 * np.cos(q2 + q3) + d4 * np.sin(q2 + q4), d3 * np.cos(q2 + q3),
         d4 * np.sin(q2 + q4)]])


def rho(J: np.ndarray, u: np.ndarray) -> float:
    """Eq. 3.6: (uᵀ(JJᵀ)†u)^(−1/2)."""
    return float(u @ np.linalg.pinv(J @ J.T) @ u) ** -0.5


def test_table_3_1_rho_at_the_printed_configurations():
    """ρ_RHI of rhi = eq. 3.6 on eq. 5.12a at the printed q (1e-12); the printed q reach their points within 1 mm.

    The transcription pins the thesis's inconsistency: at (0.49, −0.14) the printed q gives the printed 0.387, at
    (0.49, −0.22) it gives 0.3752, not the printed 0.371.
    """
    dev = ch3.measures.devices()["RHI"]
    u = np.asarray(ch3.measures.U, dtype=float)
    ours, theirs = [], []
    for q, x in zip(ch3.measures.THESIS_Q, ch3.measures.POINTS, strict=True):
        q = np.asarray(q, dtype=float)
        np.testing.assert_allclose(dev.fk(q), x, atol=1e-3)
        np.testing.assert_allclose(dev.jacobian(q), j_rhi(q), atol=1e-12)
        ours.append(float(metrics.effective_manipulability(dev.jacobian(q), u)))
        theirs.append(rho(j_rhi(q), u))
    np.testing.assert_allclose(ours, theirs, rtol=1e-12)
    assert T.TABLE_3_1_RHO["RHI"][1].within(theirs[1])
    assert not T.TABLE_3_1_RHO["RHI"][0].within(theirs[0]) and theirs[0] == pytest.approx(0.3752, abs=1e-4)


def test_table_3_1_lambda_is_eq_3_13():
    """Λ_RHI of rhi = (uᵀ J M⁻¹ Jᵀ u)⁻¹ (eq. 3.13) on eq. 5.12a at the printed q, rhi's M(q) as data (1e-12)."""
    dev = ch3.measures.devices()["RHI"]
    u = np.asarray(ch3.measures.U, dtype=float)
    for q in ch3.measures.THESIS_Q:
        q = np.asarray(q, dtype=float)
        J, M = j_rhi(q), dev.mass_matrix(q)
        lam = 1.0 / float(u @ J @ np.linalg.solve(M, J.T) @ u)
        assert float(metrics.effective_inertia(dev.jacobian(q), M, u)) == pytest.approx(lam, rel=1e-12)


def test_eq_3_19_bounds_the_part_beyond_m1_not_the_modulus():
    """Eqs. 3.17 and 3.19 at s = jω bound |A2 − M1| by |A1 − M1|, not |A2| by |A1|.

    |A2 − M1| ≤ |A1 − M1| always (line 550's factor ≤ 1), but |A2| > |A1| where B1/ω is small against M2 (e.g.
    M1 = M2 = 1 kg, B1 = 0.1 N s/m, B2 = 0, ω = 1 rad/s), as rhi's grid finds.
    """
    rng = np.random.default_rng(3)
    M1, M2, B1, B2, w = (10.0 ** rng.uniform(-2, 2, 2000) for _ in range(5))
    s = 1j * w
    A1 = M1 + B1 / s
    A2 = M1 + (B1 / s) * (B2 / s + M2) / (B1 / s + (B2 / s + M2))
    assert np.all(np.abs(A2 - M1) <= np.abs(A1 - M1) * (1 + 1e-12))
    assert np.any(np.abs(A2) > np.abs(A1))
    a1 = 1.0 + 0.1 / 1j
    a2 = 1.0 + (0.1 / 1j) * 1.0 / (0.1 / 1j + 1.0)
    assert abs(a2) > abs(a1)
    res = ch3.apparent_inertia_example()
    rows = {r.quantity: r.ours for t in res.tables for r in t.rows}
    frac = next(v for k, v in rows.items() if k.startswith("fraction of (M1, M2, B1, B2, ω)"))
    assert 0.0 < frac < 1.0


def _newton(fk, jac, x: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Q with fk(q) = x (1e-12 m) by Newton steps from q."""
    for _ in range(100):
        e = x - fk(q)
        if np.linalg.norm(e) < 1e-12:
            return q
        q = q + np.linalg.solve(jac(q), e)
    raise AssertionError(f"no convergence to {x}")


def test_table_3_1_lambda_order_is_eq_3_13_for_all_three_interfaces():
    """Λ of the PHANToM and the Rehab (eq. 3.13) on their closed forms = rhi's (1e-7, IK); the order follows from it.

    The PHANToM is eq. 5.12a's last two columns at q1 = q2 = 0 (its base at (d1, −d2)), the Rehab its first two at
    q3 = q4 = 0 (the PHANToM locked at its zero), each reaching the point by its own Newton IK from q = 0.3 rad;
    rhi's M(q) is data. The RHI is at the printed q (as the literal reading). A transcription with the Rehab's d2
    swapped for the PHANToM's d3 disagrees (the comparison can fail).
    """
    u = np.asarray(ch3.measures.U, dtype=float)
    devs = ch3.measures.devices()
    d1, d2, d3, d4 = D
    closed = {
        "PHANToM": (lambda q: np.array([d1 + d3 * np.cos(q[0]) + d4 * np.sin(q[1]),
                                        -d2 + d3 * np.sin(q[0]) - d4 * np.cos(q[1])]),
                    lambda q: j_rhi(np.array([0.0, 0.0, q[0], q[1]]))[:, 2:]),
        "Rehab": (lambda q: np.array([d1 * np.cos(q[0]) + d2 * np.sin(q[1]) + d3 * np.cos(q[1]) + d4 * np.sin(q[1]),
                                      d1 * np.sin(q[0]) - d2 * np.cos(q[1]) + d3 * np.sin(q[1]) - d4 * np.cos(q[1])]),
                  lambda q: j_rhi(np.array([q[0], q[1], 0.0, 0.0]))[:, :2]),
    }

    def lam(J, M):
        return 1.0 / float(u @ J @ np.linalg.solve(M, J.T) @ u)

    for i, x in enumerate(ch3.measures.POINTS):
        x = np.asarray(x, dtype=float)
        q_rhi = np.asarray(ch3.measures.THESIS_Q[i], dtype=float)
        ours = {"RHI": ch3.measures.measures(devs["RHI"], q_rhi)[1]}
        theirs = {"RHI": lam(j_rhi(q_rhi), devs["RHI"].mass_matrix(q_rhi))}
        for name, (fk, jac) in closed.items():
            dev = devs[name]
            q = _newton(fk, jac, x, np.full(2, 0.3))
            np.testing.assert_allclose(dev.fk(q), x, atol=1e-12)
            ours[name] = ch3.measures.measures(dev, dev.ik(x, np.full(dev.n, 0.3)))[1]
            theirs[name] = lam(jac(q), dev.mass_matrix(q))
            assert ours[name] == pytest.approx(theirs[name], rel=1e-7), (name, i)  # rhi's IK stops at 1e-9 m
            if name == "Rehab":  # planted difference
                J_bad = jac(q).copy()
                J_bad[:, 1] *= d3 / d2
                assert abs(lam(J_bad, dev.mass_matrix(q)) / theirs[name] - 1.0) > 1e-3
        assert (ours["RHI"] < ours["PHANToM"] < ours["Rehab"]) is (theirs["RHI"] < theirs["PHANToM"] < theirs["Rehab"])
