"""Linear-algebra formulas every layer shares (a foundation module: numpy only, below the layers).

`torque_null_projector` is the one implementation of the torque-level null-space projector
N = I − JᵀJ#ᵀ: `rhi.devices.terms.DeviceTerms.N` and `rhi.metrics.nullspace_projector` call it; the
compiled tick applies it to a torque as τ − Jᵀ(J#ᵀτ) (`rhi.control._compiled.step`).
"""

from __future__ import annotations

import numpy as np


def torque_null_projector(J: np.ndarray, J_inv: np.ndarray) -> np.ndarray:
    """N = I − Jᵀ J_invᵀ (thesis eqs. 3.20, 7.5): (..., n, n), with N Jᵀ = 0 and N N = N.

    Args:
        J: (..., m, n) Jacobian.
        J_inv: (..., n, m) a right inverse of J: J# = M⁻¹Jᵀ(JM⁻¹Jᵀ)⁻¹ (dynamically consistent) or J⁺.
    """
    return np.eye(J.shape[-1]) - np.swapaxes(J_inv @ J, -1, -2)


__all__ = ["torque_null_projector"]
