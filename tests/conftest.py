"""Shared fixtures and helpers: bundled devices, a seeded generator, a 3R arm's URDF, a child's env, a free UDP port."""

from __future__ import annotations

import os
import socket
from pathlib import Path

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


def row(result, start: str, table: int | None = None, *, unique: bool = False):
    """The first row of `result`'s tables (or of table `table` only) whose quantity starts with `start`.

    Fails naming `start` where there is none, or (``unique``) more than one.
    """
    tables = result.tables if table is None else [result.tables[table]]
    rows = [r for t in tables for r in t.rows if r.quantity.startswith(start)]
    assert rows, f"no row starting with {start!r}"
    assert not unique or len(rows) == 1, f"{len(rows)} rows start with {start!r}"
    return rows[0]


def arm3_urdf(name: str = "arm3", *, l1: str = "0.3", tip_com: float = 0.0, tip_inertia: float = 0.0) -> str:
    """A planar 3R arm (links l1, 0.25, 0.15 m; 1.0, 0.6, 0.2 kg), as a user's robot or a lab plugin's.

    Args:
        name: the robot's name.
        l1: the first link's length [m], as URDF text (a plugin puts a placeholder here and fills it in).
        tip_com: the tip's centre of mass along its link [m].
        tip_inertia: the tip's moments of inertia [kg m²]; 0 makes it a point mass, as exported URDFs often have.
    """
    i = repr(float(tip_inertia))
    return f"""<robot name="{name}">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.15 0 0"/><mass value="1.0"/>
    <inertia ixx="1e-4" ixy="0" ixz="0" iyy="0.008" iyz="0" izz="0.008"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.125 0 0"/><mass value="0.6"/>
    <inertia ixx="1e-4" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.003"/></inertial></link>
  <link name="tip"><inertial><origin xyz="{tip_com!r} 0 0"/><mass value="0.2"/>
    <inertia ixx="{"1e-4" if tip_inertia else "0"}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" effort="5" velocity="5"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="{l1} 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" effort="4" velocity="5"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="tip"/><origin xyz="0.25 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" effort="2" velocity="5"/></joint>
</robot>"""


def child_env(*paths) -> dict[str, str]:
    """This process's environment for a child Python process that imports this rhi (after `paths` on its path)."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join([*map(str, paths), str(Path(rhi.__file__).parents[1])])}


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that no socket holds now."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def assert_progress_complete(calls: list[tuple[int, int]]) -> None:
    """An experiment's progress calls (done, total): more than ten, increasing, one total, the last at it."""
    k, n = np.array(calls).T
    assert len(k) > 10 and np.all(np.diff(k) > 0) and np.all(n == n[0]) and k[-1] == n[0]


def assert_serialises_and_draws(result, *plots) -> None:
    """`result` turns into JSON, and each plot function draws it (a figure with axes)."""
    import json

    import matplotlib.pyplot as plt

    json.dumps(result.to_json())
    for plot in plots:
        fig = plot(result)
        assert fig.axes
        plt.close(fig)


def serial_equals_pool(experiment, resolution: int, keys: tuple[str, ...]):
    """`experiment(resolution=…)`'s map run here (workers=1) and on a 2-process `PoolExecutor`: the same arrays.

    Bit for bit, NaNs in the same places, for each of `keys`; the serial run's progress counts grid points, one tick
    per finished row. Returns the serial run's result.
    """
    from rhi.design import PoolExecutor

    ticks: list[tuple[int, int]] = []
    a = experiment(resolution=resolution, workers=1, progress=lambda k, n: ticks.append((k, n)))
    with PoolExecutor(2) as ex:
        b = experiment(resolution=resolution, executor=ex)
    for k in keys:
        np.testing.assert_array_equal(a.arrays[k], b.arrays[k])
    assert ticks == [(resolution * (j + 1), resolution**2) for j in range(resolution)]
    return a
