"""Figures of "Beyond the thesis: spatial RHIs" from `rhi.experiments.beyond.spatial` and `beyond.spatial_palpation` results."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from rhi.experiments.result import Result


def ellipsoid3d(ax, center, A: np.ndarray, *, scale: float = 1.0, **style) -> None:
    """Wireframe of the 3-D ellipsoid {center + scale·v : vᵀ A⁻¹ v = 1} of an SPD matrix A: (3, 3)."""
    w, V = np.linalg.eigh(A)
    s, t = np.meshgrid(np.linspace(0, np.pi, 13), np.linspace(0, 2 * np.pi, 25))
    sphere = np.stack([np.sin(s) * np.cos(t), np.sin(s) * np.sin(t), np.cos(s)], -1)
    pts = sphere @ (V * np.sqrt(np.maximum(w, 0))).T * scale + np.asarray(center)
    ax.plot_wireframe(pts[..., 0], pts[..., 1], pts[..., 2], linewidth=0.4, **style)


def chain3d(ax, points: np.ndarray, **style) -> None:
    """A serial chain through joint positions points: (k, 3) [m]."""
    ax.plot(points[:, 0], points[:, 1], points[:, 2], "-o", ms=3, **style)


def _equal(ax, pts: np.ndarray) -> None:
    c, r = 0.5 * (pts.min(0) + pts.max(0)), max(np.ptp(pts, axis=0).max() / 2, 1e-3)
    ax.set(xlim=(c[0] - r, c[0] + r), ylim=(c[1] - r, c[1] + r), zlim=(c[2] - r, c[2] + r),
           xlabel="x [m]", ylabel="y [m]", zlabel="z [m]")


def remark_maps(result: Result) -> Figure:
    """ρ_RHI/ρ_sub and Λ_RHI/Λ_sub over the common workspace, one row per device (3-D scatter)."""
    a = result.arrays
    devs = [k[: -len("_points")] for k in a if k.endswith("_points")]
    fig = plt.figure(figsize=(10, 4.2 * len(devs)))
    for i, d in enumerate(devs):
        P = a[f"{d}_points"]
        for j, (key, lab, cmap) in enumerate(((f"{d}_rho_ratio", "ρ ratio (Remark I: ≥ 1)", "viridis"),
                                              (f"{d}_lambda_ratio", "Λ ratio (Remark II: ≤ 1)", "magma"))):
            ax = fig.add_subplot(len(devs), 2, 2 * i + j + 1, projection="3d")
            sc = ax.scatter(P[:, 0], P[:, 1], P[:, 2], c=a[key], cmap=cmap, s=14)
            fig.colorbar(sc, ax=ax, shrink=0.6)
            ax.set(title=f"{d}: {lab}", xlabel="x [m]", ylabel="y [m]", zlabel="z [m]")
    fig.suptitle("Remarks I and II in 3-D: RHI at its VME optimum vs its non-redundant sub-chain")
    fig.tight_layout()
    return fig


def force_capability(result: Result) -> Figure:
    """F_max of ASCM and of the LP optimum against simple scaling, every (configuration, direction) case."""
    a = result.arrays
    devs = [k[: -len("_fmax")] for k in a if k.endswith("_fmax")]
    fig, axes = plt.subplots(1, len(devs), figsize=(5 * len(devs), 4.2), squeeze=False)
    for ax, d in zip(axes[0], devs):
        F = a[f"{d}_fmax"].reshape(-1, 3)
        ax.scatter(F[:, 0], F[:, 2], s=8, c="tab:gray", label="LP optimum")
        ax.scatter(F[:, 0], F[:, 1], s=8, c="tab:red", label="ASCM")
        lim = [0, F.max() * 1.05]
        ax.plot(lim, lim, "k:", lw=1, label="= scaling")
        ax.set(title=d, xlabel="F_max by simple scaling [N]", ylabel="F_max [N]", xlim=lim, ylim=lim)
        ax.legend(fontsize=8)
    fig.suptitle("Force capability along random 3-D directions")
    fig.tight_layout()
    return fig


def palpation(result: Result) -> Figure:
    """Force along u (sensor, solid; spring, dotted) per case, and the final configurations with their FMEs."""
    a = result.arrays
    cases = [k[len("force_"):] for k in a if k.startswith("force_")]
    fig = plt.figure(figsize=(12, 4.6))
    ax = fig.add_subplot(1, 2, 1)
    for c in cases:
        line, = ax.plot(a[f"t_{c}"], a[f"force_{c}"], label=c)
        ax.plot(a[f"t_{c}"], a[f"desired_{c}"], ":", color=line.get_color(), lw=0.8)
    ax.set(xlabel="t [s]", ylabel="force along u [N]", title="3-D palpation, K_e = 1000 N/m")
    ax.legend(fontsize=8)
    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    pts = [a["x0"][None]]
    for c, col in zip(cases, ("r", "m", "b", "g")):
        chain3d(ax3, a[f"skeleton_{c}"], color=col, label=c)
        ellipsoid3d(ax3, a[f"skeleton_{c}"][-1], a[f"fme_{c}"], scale=0.01, color=col)
        pts.append(a[f"skeleton_{c}"])
    u = a["u"]
    ax3.quiver(*a["x0"], *(0.05 * u), color="k")
    _equal(ax3, np.vstack(pts))
    ax3.set_title("final configurations, FMEs ×0.01 m/√(N²/(N m)²); u: arrow")
    ax3.legend(fontsize=7)
    fig.tight_layout()
    return fig


def ellipsoids(result: Result) -> Figure:
    """The RHI (red) and its sub-chain (blue) at one point with velocity (left) and force (right) ellipsoids."""
    a = result.arrays
    fig = plt.figure(figsize=(11, 5))
    for k, (kind, scale) in enumerate((("vme", 0.25), ("fme", 0.01))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        for tag, col, sk in (("RHI", "r", "skeleton"), ("sub-chain", "b", "skeleton_sub")):
            chain3d(ax, a[sk], color=col, label=tag)
            ellipsoid3d(ax, a["x"], a[f"{kind}_{tag}"], scale=scale, color=col)
        ax.quiver(*a["x"], *(0.08 * a["u"]), color="k")
        _equal(ax, np.vstack([a["skeleton"], a["skeleton_sub"]]))
        ax.set_title({"vme": f"velocity ellipsoids JJᵀ (×{scale} m per m/s)",
                      "fme": f"force ellipsoids (JW²Jᵀ)⁻¹ (×{scale})"}[kind])
        ax.legend(fontsize=8)
    fig.suptitle(result.title)
    fig.tight_layout()
    return fig


def vme_convergence(result: Result) -> Figure:
    """ν (eq. 3.22) along the run, with the static optimum."""
    a = result.arrays
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(a["t"], a["nu"], label="null-space controller")
    opt = next(r.ours for r in result.tables[0].rows if "static optimum" in r.quantity and r.quantity.startswith("ν"))
    ax.axhline(opt, color="k", ls=":", label="static optimum")
    ax.set(xlabel="t [s]", ylabel="ν (JBLD)", title="VME matching along a 3-D u on srhi5 (handle held)")
    ax.legend()
    fig.tight_layout()
    return fig
