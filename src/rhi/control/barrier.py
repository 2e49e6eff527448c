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

    Sampled-exact form (``hold`` = ΔT > 0, `sampled_gradient`): a torque held over a sample does the work
    −∇ν(q(k))ᵀΔq, and on a steep barrier that exceeds the potential's drop by ½ΔqᵀHΔq (the energy a
    sample-and-hold spring generates). The controller then uses, in place of ∇ν(q), the discrete gradient
    of ν along the predicted step Δq̂ = ΔT q̇: row by row the divided difference
    (φ(d_r + Δd̂_r) − φ(d_r))/Δd̂_r of each side's φ(d_r), so ∇̄νᵀΔq̂ = ν(q + Δq̂) − ν(q) exactly (ν is a
    sum over rows of functions of one distance each). Where the plant moves as predicted the held torque's
    work is exactly −Δν: the barrier stores and returns energy and generates none; the prediction's error
    is second order in ΔT (Δq − ΔT q̇ = ½ΔT² q̈ + …) instead of first.

    Attributes:
        margin: δ, distance from a limit where the objective starts [rad], > 0.
        weight: w, scale of ν_lim (dimensionless), > 0.
        kind: "quadratic" or "inverse".
        hold: ΔT [s] of the sampled-exact form (the controller's sample period); 0: the gradient at q
            (sample-and-hold).

    Raises:
        InvalidInput: margin or weight not finite and positive, hold not finite and ≥ 0, or an unknown kind.
    """

    margin: float
    weight: float = 1.0
    kind: Literal["quadratic", "inverse"] = "quadratic"
    hold: float = 0.0
    #: part of the safety torque τ_s (acts whatever the allocation holds), not of the objectives' τ_to
    safety: ClassVar[bool] = True

    def __post_init__(self) -> None:
        for name in ("margin", "weight"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v > 0):
                raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        h = self.hold
        if isinstance(h, bool) or not (isinstance(h, (int, float, np.floating)) and math.isfinite(h) and h >= 0):
            raise InvalidInput(f"hold: must be finite and >= 0 [s], got {h!r}")
        object.__setattr__(self, "hold", float(h))
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

    def side_values(self, d: np.ndarray) -> np.ndarray:
        """φ(d) of each limit side at the distances d [rad] (any shape): ν = Σ_r φ(d_r)."""
        if self.kind == "quadratic":
            p = np.maximum(0.0, self.margin - d)
            return self.weight * 0.5 * p * p
        r = self.margin / np.maximum(d, 1e-3 * self.margin)
        return np.where(d < self.margin, self.weight * (r - 1.0) ** 2, 0.0)

    def sampled_gradient(self, device: DeviceModel, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """The discrete gradient ∇̄ν (n,) [1/rad] along Δq̂ = ``hold`` q̇: ∇̄νᵀΔq̂ = ν(q + Δq̂) − ν(q) exactly.

        Each side's slope is the divided difference (φ(d + Δd̂) − φ(d))/Δd̂ of its distance d, and φ'
        at d + Δd̂/2 where |Δd̂| ≤ 1e-9 δ (the limit of the quotient; no cancellation).

        Args:
            device: the device (its limit rows).
            q: (n,) joint positions [rad].
            dq: (n,) joint velocities [rad/s].
        """
        C = limit_rows(device)[0]
        k = C.shape[0]
        step = self.hold * (C @ np.asarray(dq, dtype=float))
        g = self.side_divided(self.distances(device, q), np.concatenate([step, -step]))
        return C.T @ (g[:k] - g[k:])

    def side_divided(self, d: np.ndarray, dd: np.ndarray) -> np.ndarray:
        """(φ(d + dd) − φ(d))/dd of each side, φ'(d + dd/2) where |dd| ≤ 1e-9 δ; d, dd [rad] of any one shape."""
        small = np.abs(dd) <= 1e-9 * self.margin
        safe = np.where(small, 1.0, dd)
        return np.where(small, self.side_slopes(d + 0.5 * dd),
                        (self.side_values(d + dd) - self.side_values(d)) / safe)

    def side_slopes(self, d: np.ndarray) -> np.ndarray:
        """φ'(d) of each side at the distances d [rad] (any shape) [1/rad] (as `gradient`)."""
        if self.kind == "quadratic":
            return -self.weight * np.maximum(0.0, self.margin - d)
        a = d < self.margin
        g = np.zeros_like(d)
        dd = np.maximum(d[a], 1e-3 * self.margin)
        r = self.margin / dd
        g[a] = -2.0 * self.weight * (r - 1.0) * r / dd
        return g

    def gradient_at(self, terms: DeviceTerms) -> np.ndarray:
        """The torque's gradient from a terms snapshot (n,): `gradient`, or `sampled_gradient` where ``hold`` > 0.

        Terms without q̇ (a static snapshot) give the gradient: the discrete gradient along a zero step.
        """
        if self.hold > 0.0 and terms.dq is not None:
            return self.sampled_gradient(terms.device, terms.q, terms.dq)
        return self.gradient(terms.device, terms.q)

    def compiled(self, device: Device) -> CompiledObjective | None:
        """The barrier computed by the whole compiled tick (None for a subclass: its own gradient in Python)."""
        if type(self) is not JointLimitBarrier:
            return None
        return CompiledObjective("barrier", barrier=(self.kind, self.margin, self.weight, self.hold))



register(ObjectiveType("joint_limits", lambda device, torque_max, *, margin, weight, kind, hold: JointLimitBarrier(
    margin, weight, kind=kind, hold=hold), {"margin": (Key("number", low=0.0, strict=True, high=math.pi), REQUIRED),
                                            "weight": (POSITIVE, 1.0),
                                            "kind": (Key("choice", options=("quadratic", "inverse")), "quadratic"),
                                            "hold": (Key("number", low=0.0), 0.0)}))


__all__ = ["JointLimitBarrier", "limit_rows"]
