"""Online estimators of the user's intended task direction u from the handle's F/T reading and velocity.

The thesis assumes the direction of motion u of its VME (eq. 3.23) and FME (eqs.
6.12–6.13) objectives is known; §8.2 proposes estimating it from the user's force and
motion. Both objectives depend on u only through u uᵀ, so an estimator needs the *axis*
of the motion, not its sign; errors are axial angles arccos|û·u| ∈ [0°, 90°].

Each tick an estimator receives the hand force F_h (m,) [N] (the F/T reading on the task
axes) and the handle velocity ẋ (m,) [m/s] and combines them into one evidence vector

    d = F_h / f_s + ẋ / v_s        (f_s [N] and v_s [m/s] make both dimensionless),

which is used only when |d| ≥ `min_evidence` (at rest the estimate is held).

- `FilteredIntent` (baseline): an exponentially weighted structure tensor T of the unit
  evidence (time constant τ), u = its principal eigenvector, confidence c = λ₁ − λ₂ ∈ [0, 1];
  hysteresis: the output follows once c ≥ `c_on`, is held once c < `c_off`, and only moves
  when it turns by more than `deadband` [rad].
- `HMMIntent` (learned): a hidden Markov model over K motion primitives (axes e_k spread
  over the half-circle / hemisphere), sticky transitions and axial Watson emissions
  p(d̂ | k) ∝ exp(κ (d̂·e_k)²); `HMMIntent.fit` learns κ (maximum likelihood) and the
  switching rate from labelled strokes (`rhi.sim.strokes`). u is the principal axis of the
  posterior-weighted primitives, confidence its λ₁ − λ₂.
- `KnownIntent`: a constant u (the thesis's assumption).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import brentq
from scipy.special import i0e, i1e

from rhi._validate import scalar, unit_vector
from rhi.control.compiled import CompiledIntent
from rhi.errors import InvalidInput


def _unit(name: str, u, m: int | None = None) -> np.ndarray:
    """One direction: `u` normalised, a (m,) vector (`unit_vector` also takes batches)."""
    v = unit_vector(name, u, m)
    if v.ndim != 1:
        raise InvalidInput(f"{name}: expected one ({m or 'm'},) vector, got shape {v.shape}")
    return v


def axial_error(u_est, u_true) -> np.ndarray:
    """Axial angle between directions, arccos |û·u| [rad] ∈ [0, π/2]: (...,) for (..., m) inputs (normalised)."""
    a = np.asarray(u_est, dtype=float)
    b = np.asarray(u_true, dtype=float)
    c = np.abs(np.sum(a * b, -1)) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1))
    return np.arccos(np.clip(c, 0.0, 1.0))


def primitives(m: int, k: int) -> np.ndarray:
    """K axes spread over the half-circle (m = 2) or a Fibonacci hemisphere (m = 3): (k, m) unit vectors."""
    if m == 2:
        a = np.pi * np.arange(k) / k
        return np.stack([np.cos(a), np.sin(a)], 1)
    if m == 3:
        i = np.arange(k) + 0.5
        z = i / k  # upper hemisphere z ∈ (0, 1)
        phi = np.pi * (1 + 5**0.5) * i
        r = np.sqrt(1 - z**2)
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    raise InvalidInput(f"m: primitives exist for m = 2 or 3, got {m}")


@dataclasses.dataclass
class _Evidence:
    """Common evidence model: d = F_h/f_s + ẋ/v_s, used when |d| ≥ min_evidence."""

    m: int
    u0: np.ndarray
    force_scale: float = 1.0
    speed_scale: float = 0.02
    min_evidence: float = 0.3

    def _check(self) -> None:
        if self.m not in (2, 3):
            raise InvalidInput(f"m: expected 2 or 3 task dimensions, got {self.m!r}")
        self.u0 = _unit("u0", self.u0, self.m)
        scalar("force_scale", self.force_scale, positive=True)
        scalar("speed_scale", self.speed_scale, positive=True)
        scalar("min_evidence", self.min_evidence, nonnegative=True)

    def _evidence_settings(self) -> dict[str, float]:
        return {"force_scale": self.force_scale, "speed_scale": self.speed_scale, "min_evidence": self.min_evidence}

    def evidence(self, force, xdot) -> np.ndarray | None:
        """Unit evidence d̂ (m,) or None when the hand is (nearly) at rest."""
        f, v = np.asarray(force, dtype=float), np.asarray(xdot, dtype=float)
        if f.shape != (self.m,) or v.shape != (self.m,):
            raise InvalidInput(f"force/xdot: expected ({self.m},) vectors, got {f.shape} and {v.shape}")
        d = f * (1.0 / self.force_scale) + v * (1.0 / self.speed_scale)
        s = math.sqrt(d.dot(d))
        if not math.isfinite(s):
            raise InvalidInput(f"force/xdot: non-finite reading {d.tolist()}")
        return d / s if s >= self.min_evidence and s > 0 else None


def _principal(T: np.ndarray) -> tuple[np.ndarray, float]:
    w, V = np.linalg.eigh(T)
    tr = float(w.sum())
    return V[:, -1], float((w[-1] - w[-2]) / tr) if tr > 0 else 0.0


@dataclasses.dataclass
class FilteredIntent(_Evidence):
    """Baseline estimator: filtered structure tensor with confidence and hysteresis (module docstring).

    Attributes:
        m: task dimensions (2 or 3). u0: (m,) output before any evidence.
        force_scale [N], speed_scale [m/s], min_evidence: the evidence model.
        tau: time constant of the filter [s]. dt: tick period [s].
        c_on, c_off: confidence thresholds of the hysteresis (0 <= c_off <= c_on <= 1).
        deadband: smallest output turn [rad].
    """

    tau: float = 0.15
    dt: float = 1e-3
    c_on: float = 0.6
    c_off: float = 0.3
    deadband: float = math.radians(3.0)

    def __post_init__(self) -> None:
        self._check()
        scalar("tau", self.tau, positive=True)
        scalar("dt", self.dt, positive=True)
        scalar("deadband", self.deadband, nonnegative=True)
        if not 0.0 <= self.c_off <= self.c_on <= 1.0:
            raise InvalidInput(f"c_off/c_on: need 0 <= c_off <= c_on <= 1, got {self.c_off}, {self.c_on}")
        self._cos_deadband = math.cos(self.deadband)
        self._a = 1.0 - math.exp(-self.dt / self.tau)
        self.reset()

    def reset(self) -> None:
        """Forget the evidence; the output returns to u0."""
        self.T = np.outer(self.u0, self.u0) * 0.0
        self.u = self.u0.copy()
        self.confidence = 0.0
        self.active = False

    def compiled(self) -> CompiledIntent | None:
        """Its tick in compiled code (m = 2; None otherwise)."""
        return None if self.m != 2 else CompiledIntent("filtered", {
            **self._evidence_settings(), "a": self._a, "c_on": self.c_on, "c_off": self.c_off,
            "cos_deadband": self._cos_deadband})

    def update(self, force, xdot) -> np.ndarray:
        """One tick: F_h (m,) [N], ẋ (m,) [m/s] -> the current estimate u (m,) (unit)."""
        d = self.evidence(force, xdot)
        if d is not None:
            self.T += self._a * (np.outer(d, d) - self.T)
            e, c = _principal(self.T)
            self.confidence = c
            if c >= self.c_on:
                self.active = True
            elif c < self.c_off:
                self.active = False
            if self.active and abs(e.dot(self.u)) < self._cos_deadband:
                self.u = e if e.dot(d) >= 0 else -e
        return self.u


@dataclasses.dataclass
class HMMIntent(_Evidence):
    """Learned estimator: an HMM over motion primitives with axial Watson emissions (module docstring).

    Attributes:
        m, u0, force_scale, speed_scale, min_evidence: as `FilteredIntent`.
        kappa: Watson concentration of the emissions (learned by `fit`).
        switch: probability per evidence tick of leaving the current primitive (learned by `fit`).
        k: number of primitives (None: 90 for m = 2, 400 for m = 3).
    """

    kappa: float = 10.0
    switch: float = 1e-3
    k: int | None = None

    def __post_init__(self) -> None:
        self._check()
        scalar("kappa", self.kappa, positive=True)
        if not 0.0 < self.switch < 1.0:
            raise InvalidInput(f"switch: must be in (0, 1), got {self.switch!r}")
        if self.k is None:
            self.k = 90 if self.m == 2 else 400  # about 2° (m = 2) and 7° (m = 3) between neighbouring axes
        if not isinstance(self.k, (int, np.integer)) or self.k < 2:
            raise InvalidInput(f"k: expected an integer >= 2, got {self.k!r}")
        self.E = primitives(self.m, int(self.k))
        self._stay, self._jump = 1.0 - self.switch, self.switch / int(self.k)
        self.reset()

    def reset(self) -> None:
        """Posterior back to the prior peaked on u0."""
        p = np.exp(self.kappa * (self.E @ self.u0) ** 2 - self.kappa)
        self.p = p / p.sum()
        self.u = self.u0.copy()
        self.confidence = 0.0

    def compiled(self) -> CompiledIntent | None:
        """Its tick in compiled code (m = 2; None otherwise)."""
        return None if self.m != 2 else CompiledIntent("hmm", {
            **self._evidence_settings(), "stay": self._stay, "jump": self._jump, "kappa": self.kappa},
            table=self.E)

    def update(self, force, xdot) -> np.ndarray:
        """One tick: F_h (m,) [N], ẋ (m,) [m/s] -> the current estimate u (m,) (unit)."""
        d = self.evidence(force, xdot)
        if d is not None:
            prior = self._stay * self.p + self._jump
            c = self.E.dot(d)
            post = prior * np.exp(self.kappa * (c * c - 1.0))
            self.p = post * (1.0 / post.sum())
            e, self.confidence = _principal((self.E.T * self.p).dot(self.E))
            self.u = e if e.dot(d) >= 0 else -e
        return self.u

    @classmethod
    def fit(cls, force: np.ndarray, xdot: np.ndarray, u_true: np.ndarray, *, dt: float = 1e-3, **kw) -> HMMIntent:
        """Learn κ and the switching rate from labelled strokes.

        κ: maximum likelihood of the axial Watson distribution of the evidence d̂ about the true
        axis (mean (d̂·u)² = A(κ), solved by root finding). Switching rate: the number of
        changes of the true axis per evidence tick.

        Args:
            force: (N, m) hand forces [N].
            xdot: (N, m) handle velocities [m/s].
            u_true: (N, m) true task directions (unit vectors).
            dt: tick period [s] (for the record only).
            **kw: the evidence model and k.
        """
        force, xdot, u_true = (np.asarray(a, dtype=float) for a in (force, xdot, u_true))
        if force.ndim != 2 or force.shape != xdot.shape or force.shape != u_true.shape:
            raise InvalidInput(f"force/xdot/u_true: expected equal (N, m) arrays, got {force.shape}, {xdot.shape}, "
                               f"{u_true.shape}")
        m = force.shape[1]
        probe = cls(m=m, u0=np.eye(m)[0], **kw)
        d = force / probe.force_scale + xdot / probe.speed_scale
        s = np.linalg.norm(d, axis=1)
        use = s >= max(probe.min_evidence, 1e-12)
        if use.sum() < 10:
            raise InvalidInput("force/xdot: fewer than 10 ticks with evidence; cannot fit")
        dh = d[use] / s[use, None]
        ut = u_true[use] / np.linalg.norm(u_true[use], axis=1, keepdims=True)
        c2 = float(np.mean(np.sum(dh * ut, 1) ** 2))
        kappa = _watson_kappa(c2, m)
        changes = np.sum(axial_error(ut[1:], ut[:-1]) > 1e-6)
        switch = float(np.clip((changes + 1) / len(ut), 1e-5, 0.5))
        return cls(m=m, u0=np.eye(m)[0], kappa=kappa, switch=switch, **kw)


def _watson_mean(kappa: float, m: int) -> float:
    """E[(x·μ)²] of the axial Watson distribution with concentration κ in m = 2 or 3 dimensions."""
    if m == 2:  # density ∝ exp(κ cos²θ) on the circle: E = ½(1 + I1(κ/2)/I0(κ/2))
        return 0.5 * (1.0 + i1e(kappa / 2) / i0e(kappa / 2))
    # m = 3: E = 1/(2κ)·(e^κ/∫₀¹e^{κt²}dt − 1) via Dawson's function: ∫₀¹ e^{κt²} dt = e^κ D(√κ)/√κ
    from scipy.special import dawsn

    r = math.sqrt(kappa)
    return 0.5 * (r / dawsn(r) - 1.0) / kappa


def _watson_kappa(c2: float, m: int) -> float:
    """κ > 0 with E[(x·μ)²] = c2 (maximum likelihood of the Watson concentration)."""
    lo = 1.0 / m
    if c2 <= lo + 1e-6:
        return 1e-3
    c2 = min(c2, 1.0 - 1e-6)
    return float(brentq(lambda k: _watson_mean(k, m) - c2, 1e-6, 1e6))


@dataclasses.dataclass
class KnownIntent:
    """A known, constant task direction (the thesis's assumption): `update` returns u."""

    u0: np.ndarray

    def __post_init__(self) -> None:
        _unit("u0", self.u0)  # validated; kept as given, so the objectives see exactly this u
        self.u0 = np.asarray(self.u0, dtype=float)
        self.u = self.u0
        self.confidence = 1.0

    def reset(self) -> None:
        """Back to the fixed direction u0."""
        self.u = self.u0

    def update(self, force=None, xdot=None) -> np.ndarray:
        """The fixed direction u: (m,) whatever the readings."""
        return self.u

    def compiled(self) -> CompiledIntent:
        """Its tick in compiled code: nothing to compute."""
        return CompiledIntent("known")
