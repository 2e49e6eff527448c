"""Shared fixtures: bundled devices (loaded once per session) and a seeded generator."""

from __future__ import annotations

import os

import numpy as np
import pytest

import rhi

os.environ.setdefault("MPLBACKEND", "Agg")  # tests write figures to files; never open a window


@pytest.fixture(scope="session")
def rhi4() -> rhi.Device:
    return rhi.device("rhi4")


@pytest.fixture(scope="session")
def phantom() -> rhi.Device:
    return rhi.device("phantom")


@pytest.fixture(scope="session")
def rehab() -> rhi.Device:
    return rhi.device("rehab")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20201)


def random_q(dev: rhi.Device, rng: np.random.Generator, n: int) -> np.ndarray:
    """Draw n configurations uniformly in the joint box, keeping those that satisfy the linear limits."""
    lo = np.where(np.isfinite(dev.q_min), dev.q_min, -np.pi)
    hi = np.where(np.isfinite(dev.q_max), dev.q_max, np.pi)
    out = np.empty((0, dev.n))
    while len(out) < n:
        q = rng.uniform(lo, hi, size=(4 * n, dev.n))
        out = np.vstack([out, q[dev.within_limits(q)]])
    return out[:n]


def fd_jacobian(f, q: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Central finite differences of f: (n,) -> (...) stacked on a last axis of size n."""
    cols = [(f(q + eps * e) - f(q - eps * e)) / (2 * eps) for e in np.eye(len(q))]
    return np.stack(cols, axis=-1)
