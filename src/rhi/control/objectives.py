"""Secondary objectives ν(q) with analytic gradients (gradient projection, thesis eq. 3.21).

An objective provides `value(device, q)` and `gradient(device, q)`; controllers and
configuration optimisers compose objectives without special-casing them.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol

import numpy as np

from rhi.device import Device
from rhi.metrics import desired_vme, jbld


class Objective(Protocol):
    """A scalar cost ν(q) to decrease in the null space of the primary task."""

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν(q) for q: (n,)."""
        ...

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q: (n,)."""
        ...


@dataclasses.dataclass(frozen=True)
class VMEMatching:
    """Match the velocity manipulability ellipsoid JJᵀ to M_des by the JBLD (thesis eq. 3.22–3.23).

    ν(q) = logdet((M_des + JJᵀ)/2) − ½ logdet(M_des JJᵀ), with M_des = u uᵀ + β (I − u uᵀ)
    built from the desired direction of motion u (eq. 3.23).

    Attributes:
        u: (m,) desired direction of motion (normalised internally).
        beta: minor-axis scale β of M_des (thesis: 0.01).
    """

    u: tuple[float, ...]
    beta: float = 0.01

    def desired(self) -> np.ndarray:
        """M_des: (m, m)."""
        return desired_vme(np.asarray(self.u, dtype=float), self.beta)

    def value(self, device: Device, q: np.ndarray) -> float:
        J = device.jacobian(q)
        return float(jbld(self.desired(), J @ J.T))

    def gradient(self, device: Device, q: np.ndarray) -> np.ndarray:
        """∂ν/∂q_k = tr((½ M̄⁻¹ − ½ M⁻¹) ∂M/∂q_k), M = JJᵀ, M̄ = (M_des + M)/2, ∂M = ∂J Jᵀ + J ∂Jᵀ."""
        J = device.jacobian(q)
        dJ = device.jacobian_derivative(q)  # (m, n, n): [i, j, k] = ∂J_ij/∂q_k
        M = J @ J.T
        G = 0.5 * (np.linalg.inv(0.5 * (self.desired() + M)) - np.linalg.inv(M))
        # tr(G (dJ_k Jᵀ + J dJ_kᵀ)) = 2 tr(G dJ_k Jᵀ) since G is symmetric
        return 2.0 * np.einsum("ab,ajk,bj->k", G, dJ, J)
