"""The joint-limit barrier: a null-space objective that keeps the joints off their range limits."""

from __future__ import annotations

import dataclasses
import math
import weakref
from typing import ClassVar, Literal

import numpy as np

from rhi.control.compiled import CompiledObjective
from rhi.control.registry import POSITIVE, REQUIRED, Key, ObjectiveType, register
from rhi.devices.model import Device, DeviceTerms
from rhi.devices.terms import DeviceModel
from rhi.errors import InvalidInput

_LIMIT_ROWS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def limit_rows(device: DeviceModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(C, lower, upper) with lower ≤ C q ≤ upper for every limited row: (k, n), (k,), (k,); cached per device.

    Rows: the box limits q_min ≤ q ≤ q_max (joints with at least one finite bound), then the
    device's linear limits. Unlimited sides are ±inf.
    """
    cached = _LIMIT_ROWS.get(device)
    if cached is not None:
        return cached
    rows, lo, hi = [np.eye(device.n)], [device.q_min], [device.q_max]
    if device.linear_limits is not None:
        L = device.linear_limits
        rows.append(np.asarray(L.C, dtype=float))
        lo.append(np.asarray(L.lower, dtype=float))
        hi.append(np.asarray(L.upper, dtype=float))
    C, lower, upper = np.vstack(rows), np.concatenate(lo), np.concatenate(hi)
    keep = np.isfinite(lower) | np.isfinite(upper)
    out = (C[keep], lower[keep], upper[keep])
    _LIMIT_ROWS[device] = out
    return out


@dataclasses.dataclass(frozen=True)
class JointLimitBarrier:
    """Keep the joints off their range limits: a null-space objective that is zero farther than δ from every limit.

    With d_r(q) the distance of q to limit r (box limits q_min ≤ q ≤ q_max and the device's
    linear limits lower ≤ C q ≤ upper, each side a separate r), two shapes:

    - ``kind="quadratic"``: ν_lim = w ½ Σ_r max(0, δ − d_r)², a penalty that stays finite past
      a limit (the rhi4 palpation controller of chapter 6).
    - ``kind="inverse"``: ν_lim = w Σ_{d_r < δ} (δ/d_r − 1)², a barrier that grows without bound
      at the limit; d_r is floored at 10⁻³ δ so ν stays finite if a plant penetrates a soft
      stop (the chapter 3/7 null-space runs).

    Both are continuously differentiable and leave minima of other objectives away from the
    limits unchanged. Not a thesis equation: the thesis assumes no joint is at its range limit;
    this objective enforces that assumption in simulation.

    Attributes:
        margin: δ, distance from a limit where the objective starts [rad], > 0.
        weight: w, scale of ν_lim (dimensionless), > 0.
        kind: "quadratic" or "inverse".

    Raises:
        InvalidInput: margin or weight not finite and positive, or an unknown kind.
    """

    margin: float
    weight: float = 1.0
    kind: Literal["quadratic", "inverse"] = "quadratic"
    #: part of the safety torque τ_s (acts whatever the allocation holds), not of the objectives' τ_to
    safety: ClassVar[bool] = True

    def __post_init__(self) -> None:
        for name in ("margin", "weight"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v > 0):
                raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.kind not in ("quadratic", "inverse"):
            raise InvalidInput(f"kind: expected 'quadratic' or 'inverse', got {self.kind!r}")

    def distances(self, device: DeviceModel, q: np.ndarray) -> np.ndarray:
        """Distances (2k,) of q: (n,) [rad] to every lower then every upper limit [rad] (inf where unlimited)."""
        C, lower, upper = limit_rows(device)
        c = C @ np.asarray(q, dtype=float)
        return np.concatenate([c - lower, upper - c])

    def value(self, device: Device, q: np.ndarray) -> float:
        """ν_lim(q) for q: (n,) [rad]."""
        d = self.distances(device, q)
        if self.kind == "quadratic":
            p = np.maximum(0.0, self.margin - d.reshape(2, -1).T.ravel())  # summed row by row: lower, upper
            return float(self.weight * (0.5 * p @ p))
        a = d < self.margin
        r = self.margin / np.maximum(d[a], 1e-3 * self.margin)
        return float(self.weight * np.sum((r - 1.0) ** 2))

    def gradient(self, device: DeviceModel, q: np.ndarray) -> np.ndarray:
        """∂ν_lim/∂q = Cᵀ (∂ν/∂d_lo − ∂ν/∂d_hi): (n,) [1/rad]."""
        d = self.distances(device, q)
        if self.kind == "quadratic":
            g = -np.maximum(0.0, self.margin - d)  # ∂/∂d of ½ max(0, δ − d)²
            if self.weight != 1.0:
                g = self.weight * g
        else:
            a = d < self.margin
            g = np.zeros_like(d)
            dd = np.maximum(d[a], 1e-3 * self.margin)
            r = self.margin / dd
            g[a] = -2.0 * self.weight * (r - 1.0) * r / dd  # ∂/∂d of w (δ/d − 1)²
        C = limit_rows(device)[0]
        k = C.shape[0]
        return C.T @ (g[:k] - g[k:])  # ∂d_lo/∂q = C, ∂d_hi/∂q = −C

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """`gradient` from a terms snapshot: (n,)."""
        return self.gradient(terms.device, terms.q)

    def compiled(self, device: Device) -> CompiledObjective | None:
        """The barrier computed by the whole compiled tick (None for a subclass: its own gradient in Python)."""
        if type(self) is not JointLimitBarrier:
            return None
        return CompiledObjective("barrier", barrier=(self.kind, self.margin, self.weight))



register(ObjectiveType("joint_limits", lambda device, torque_max, *, margin, weight, kind: JointLimitBarrier(
    margin, weight, kind=kind), {"margin": (Key("number", low=0.0, strict=True, high=math.pi), REQUIRED),
                                 "weight": (POSITIVE, 1.0), "kind": (Key("choice", options=("quadratic", "inverse")),
                                                                     "quadratic")}))


__all__ = ["JointLimitBarrier", "limit_rows"]
