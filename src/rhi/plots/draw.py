"""Drawing primitives: planar arms and ellipses."""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes


def ellipse(ax: Axes, center, A: np.ndarray, *, scale: float = 1.0, **style) -> None:
    """Draw the 2-D ellipse {center + scale·v : vᵀ A⁻¹ v = 1} of an SPD matrix A: (2, 2)."""
    w, V = np.linalg.eigh(A)
    t = np.linspace(0, 2 * np.pi, 100)
    pts = (V * np.sqrt(np.maximum(w, 0))) @ np.stack([np.cos(t), np.sin(t)]) * scale
    ax.plot(center[0] + pts[0], center[1] + pts[1], **style)


def chain(ax: Axes, points: np.ndarray, **style) -> None:
    """Draw a planar serial chain through joint positions points: (k, 2) [m]."""
    ax.plot(points[:, 0], points[:, 1], "-o", ms=3, **style)
