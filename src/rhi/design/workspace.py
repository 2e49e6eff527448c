"""Explicit samplings of a planar slave workspace W for the global indices (thesis eqs. 4.8, 4.10, 4.18).

A `Workspace` is a set of sample points with the area each one stands for, so a global
index ``∫_W v dW / ∫_W dW`` is the weighted mean ``Σ w_k v_k / Σ w_k``. The sampling is
explicit (kind and density are stored on the object), so a result can state exactly
which quadrature produced it and `convergence` can show it is resolved.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.stats import qmc

from rhi.errors import InfeasibleLimits, InvalidInput

KINDS = ("grid", "sobol")


@dataclasses.dataclass(frozen=True)
class Workspace:
    """Sample points of a planar workspace with their area weights.

    Attributes:
        points: (N, 2) sample positions in the slave (task) frame [m], ordered so that
            consecutive points are neighbours (serpentine), which lets IK warm-start.
        weights: (N,) area each sample stands for [m²]; they sum to the area of W.
        kind: "grid" (midpoint rule) or "sobol" (scrambled Sobol' points, seeded).
        density: samples per metre along each axis (grid) or sqrt(N / area) requested (sobol; N is rounded up
            to a power of 2) [1/m].
        description: human-readable summary.
    """

    points: np.ndarray
    weights: np.ndarray
    kind: str
    density: float
    description: str

    @property
    def area(self) -> float:
        """Area of W [m²] (sum of the weights)."""
        return float(self.weights.sum())

    def __len__(self) -> int:
        return len(self.points)


def _check_density(density: float, kind: str) -> None:
    if kind not in KINDS:
        raise InvalidInput(f"kind: expected one of {KINDS}, got {kind!r}")
    if not np.isfinite(density) or density <= 0:
        raise InvalidInput(f"density: must be a positive number of samples per metre, got {density}")


def _check_interval(name: str, lo: float, hi: float) -> None:
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise InvalidInput(f"{name}: bounds must be finite, got ({lo}, {hi})")
    if lo >= hi:
        raise InfeasibleLimits(f"{name}: lower bound {lo} is not below upper bound {hi}")


def _serpentine(ij: np.ndarray) -> np.ndarray:
    """Order of grid indices (N, 2) that walks rows alternately left-right and right-left."""
    i, j = ij[:, 0], ij[:, 1]
    key = i * (ij[:, 1].max() + 1) + np.where(i % 2 == 0, j, -j)
    return np.argsort(key, kind="stable")


def rectangle(
    xlim: tuple[float, float], ylim: tuple[float, float], *, density: float = 100.0, kind: str = "grid", seed: int = 0
) -> Workspace:
    """Rectangle ``[x0, x1] × [y0, y1]`` sampled on a midpoint grid or by scrambled Sobol' points.

    Args:
        xlim: (min, max) extent along x [m].
        ylim: (min, max) extent along y [m].
        density: samples per metre along each axis [1/m]; N ≈ area · density².
        kind: "grid" (cell centres, equal weights: midpoint rule, error O(h²)) or "sobol".
        seed: seed of the Sobol' scrambling.
    """
    _check_density(density, kind)
    _check_interval("xlim", *xlim)
    _check_interval("ylim", *ylim)
    (x0, x1), (y0, y1) = xlim, ylim
    area = (x1 - x0) * (y1 - y0)
    if kind == "grid":
        nx = max(1, int(round((x1 - x0) * density)))
        ny = max(1, int(round((y1 - y0) * density)))
        xs = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
        ys = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
        ij = np.stack(np.meshgrid(np.arange(ny), np.arange(nx), indexing="ij"), -1).reshape(-1, 2)
        ij = ij[_serpentine(ij)]
        pts = np.stack([xs[ij[:, 1]], ys[ij[:, 0]]], -1)
    else:
        n = max(4, int(round(area * density**2)))
        u = qmc.Sobol(2, scramble=True, seed=seed).random_base2(int(np.ceil(np.log2(n))))  # balanced: 2^k points
        pts = np.array([x0, y0]) + u * np.array([x1 - x0, y1 - y0])
        pts = pts[np.lexsort((pts[:, 0], np.floor((pts[:, 1] - y0) * density)))]
    w = np.full(len(pts), area / len(pts))
    desc = f"rectangle x∈[{x0:g}, {x1:g}] m, y∈[{y0:g}, {y1:g}] m, {kind}, {len(pts)} samples ({density:g}/m)"
    return Workspace(pts, w, kind, float(density), desc)


def annulus(
    center: tuple[float, float], r_in: float, r_out: float, *, density: float = 100.0, kind: str = "grid", seed: int = 0
) -> Workspace:
    """Annulus ``r_in <= |p − c| <= r_out`` sampled on a polar midpoint grid (exact cell areas) or by Sobol'.

    Args:
        center: (2,) centre [m].
        r_in: inner radius [m], 0 <= r_in < r_out.
        r_out: outer radius [m].
        density: samples per metre radially and along the mid-circle [1/m].
        kind: "grid" (polar cells, weight = exact cell area) or "sobol" (area-uniform, equal weights).
        seed: seed of the Sobol' scrambling.
    """
    _check_density(density, kind)
    if r_in < 0:
        raise InvalidInput(f"r_in: must be >= 0, got {r_in}")
    _check_interval("r_in/r_out", r_in, r_out)
    c = np.asarray(center, dtype=float)
    area = np.pi * (r_out**2 - r_in**2)
    if kind == "grid":
        nr = max(1, int(round((r_out - r_in) * density)))
        nt = max(3, int(round(np.pi * (r_in + r_out) * density)))
        edges = np.linspace(r_in, r_out, nr + 1)
        rm = 0.5 * (edges[1:] + edges[:-1])
        cell = (edges[1:] ** 2 - edges[:-1] ** 2) * np.pi / nt
        t = (np.arange(nt) + 0.5) * 2 * np.pi / nt
        R, T = np.meshgrid(rm, t, indexing="ij")
        W = np.broadcast_to(cell[:, None], R.shape)
        pts = c + np.stack([R * np.cos(T), R * np.sin(T)], -1).reshape(-1, 2)
        w = W.reshape(-1).copy()
    else:
        n = max(4, int(round(area * density**2)))
        u = qmc.Sobol(2, scramble=True, seed=seed).random_base2(int(np.ceil(np.log2(n))))  # balanced: 2^k points
        n = len(u)
        r = np.sqrt(r_in**2 + u[:, 0] * (r_out**2 - r_in**2))
        t = 2 * np.pi * u[:, 1]
        pts = c + np.stack([r * np.cos(t), r * np.sin(t)], -1)
        w = np.full(n, area / n)
    desc = f"annulus c={tuple(np.round(c, 4))} m, r∈[{r_in:g}, {r_out:g}] m, {kind}, {len(pts)} samples"
    return Workspace(pts, w, kind, float(density), desc)
