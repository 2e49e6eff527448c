"""The small thesis examples added to the headline: eqs. 3.16–3.19 (Figs 3.2–3.3) and the ASO of Fig. 6.6."""

from __future__ import annotations

import numpy as np
import pytest

from rhi.experiments.ch3.prismatic import a1, a2, apparent_inertia_example, simulated_a
from rhi.experiments.ch6.observer import LIMITS, S_6_6, aso_example


def test_eq_3_19_is_the_transfer_function_of_eq_3_18():
    """Eq. 3.19 from eq. 3.18 by hand (Laplace, X2 eliminated) and MuJoCo's steady state agree."""
    m1, b1, m2, b2, w = 0.05, 1.0, 0.5, 1.0, 20.0
    s = 1j * w
    # eq. 3.18: (M2 s² + (B1 + B2) s) X2 = B1 s X1;  F = M1 s² X1 + B1 s (X1 − X2)
    x2_over_x1 = b1 * s / (m2 * s**2 + (b1 + b2) * s)
    a_direct = (m1 * s**2 + b1 * s * (1 - x2_over_x1)) / s**2
    assert a2(np.array(s), m1, b1, m2, b2) == pytest.approx(a_direct, rel=1e-12)
    assert simulated_a(m1, b1, m2, b2, w) == pytest.approx(a_direct, rel=5e-3)
    assert simulated_a(m1, b1, None, b2, w) == pytest.approx(a1(np.array(s), m1, b1), rel=5e-3)


def test_prismatic_example_rows():
    res = apparent_inertia_example()
    rows = {r.quantity.split(" (")[0]: r.ours for r in res.tables[0].rows}
    assert rows["max |(B2/s + M2)/(B1/s + B2/s + M2)|"] <= 1.0  # the thesis's step holds ...
    assert rows["fraction with |A2 − M1| ≤ |A1 − M1|"] == 1.0
    assert rows["max |A2(jω)|/|A1(jω)|"] > 1.0  # ... but |A2| ≤ |A1| does not follow from it
    # at high ω: A2 ≈ M1 + B1²/(ω²M2) + B1/s has the larger modulus (by hand)
    m1, b1, m2, b2, w = 0.05, 1.0, 0.5, 1.0, 1e3
    assert abs(a2(np.array(1j * w), m1, b1, m2, b2)) > abs(a1(np.array(1j * w), m1, b1))


def test_aso_example_against_eq_6_14_in_numpy():
    res = aso_example(resolution=21)
    t1, t2, V = res.arrays["tau1"], res.arrays["tau2"], res.arrays["V"]
    n = 2
    for j, b in enumerate(t2):
        for i, a in enumerate(t1):
            tau = np.array([a, b])
            prod = np.prod((tau - LIMITS) * (tau + LIMITS) / (2 * LIMITS) ** 2)
            v = (1 - np.exp(-S_6_6 * (-1) ** n * prod)) / (1 - np.exp(-S_6_6 / 4**n))
            inside = np.all(np.abs(tau) < LIMITS)
            assert V[j, i] == pytest.approx(v if inside else 0.0, abs=1e-12)
    assert res.tables[0].rows[0].ours == 1.0
