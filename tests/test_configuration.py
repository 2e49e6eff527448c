"""Static redundancy resolution (rhi.control.configuration): the self-motion optimum of an objective."""

from __future__ import annotations

import numpy as np
import pytest

import rhi
from rhi.control import VMEMatching
from rhi.control.configuration import optimal_configuration
from rhi.errors import InvalidInput, Unreachable


@pytest.fixture(scope="module")
def setup():
    dev = rhi.device("rhi4")
    q0 = np.array([0.5, 0.95, 0.38, -0.29])
    return dev, dev.fk(q0), VMEMatching((0.0, 1.0), 0.01), q0


@pytest.mark.parametrize("start, held", [([0.5, 0.95, 0.38, -0.29], 0), ([0.3, 0.5, 0.2, 0.4], 1)])
def test_optimum_is_a_kkt_point_on_the_self_motion(setup, start, held):
    """ν's gradient vanishes along every self-motion that keeps the joints held on a bound (interior and held case)."""
    dev, _, vme, _ = setup
    q0 = np.array(start)
    x = dev.fk(q0)
    q = optimal_configuration(dev, x, vme, q0)
    assert np.linalg.norm(dev.fk(q) - x) < 1e-9 and dev.within_limits(q)
    assert vme.value(dev, q) < vme.value(dev, q0)
    on = np.flatnonzero((q - dev.q_min < 1e-8) | (dev.q_max - q < 1e-8))
    assert len(on) == held
    C = np.vstack([dev.jacobian(q), np.eye(dev.n)[on]])
    Z = np.linalg.svd(C)[2][len(C):]  # self-motion directions that keep the held joints on their bounds
    assert len(Z) > 0
    assert np.linalg.norm(Z @ vme.gradient(dev, q)) < 1e-4 * np.linalg.norm(vme.gradient(dev, q0))


def test_exact_start_keeps_a_local_minimum_and_improves_elsewhere(setup):
    dev, x, vme, q0 = setup
    q = optimal_configuration(dev, x, vme, q0)
    again = optimal_configuration(dev, x, vme, q, tol=1e-10, max_iter=300, exact_start=True)
    assert np.linalg.norm(again - q) < 1e-6  # already a constrained local minimum
    drifted = q0 + np.array([1e-9, 0.0, 0.0, 0.0])  # a simulated end configuration, slightly off f(q) = x
    better = optimal_configuration(dev, x, vme, drifted, exact_start=True)
    assert vme.value(dev, better) < vme.value(dev, drifted) and np.linalg.norm(dev.fk(better) - x) < 1e-7


def test_bad_input(setup):
    dev, x, vme, q0 = setup
    with pytest.raises(InvalidInput, match="q0"):
        optimal_configuration(dev, x, vme, q0[:3])
    with pytest.raises(InvalidInput, match="x"):
        optimal_configuration(dev, [np.nan, 0.0], vme, q0)
    with pytest.raises(Unreachable):
        optimal_configuration(dev, x + 10.0, vme, q0)
