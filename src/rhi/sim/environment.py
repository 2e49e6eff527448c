"""Environments: force fields of the end-effector position and velocity.

An environment maps the handle's position x: (..., m) [m] and velocity ẋ: (..., m) [m/s]
to the force it exerts on the handle, (..., m) [N]. The same objects serve as *virtual*
environments (the haptic rendering computes F_e from the measured position and the
controller renders it through `sensors["force"]`) and as *physical* ones (applied to the
plant's handle directly, like the 8 cm stop of §3.5).

Stiffness ranges of the thesis: 50 N/m (soft brain tissue, §3.5) … 2000 N/m (bone-like,
ch. 6); the palpation experiments use K_e = 1000 N/m.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from rhi._validate import as_array, scalar, unit_vector
from rhi.errors import InvalidInput


def _gain(name: str, v: float) -> float:
    return scalar(name, v, nonnegative=True)


def _finite(name: str, v: np.ndarray) -> list[float]:
    """The values of v as Python floats; InvalidInput naming `name` if one is NaN or infinite."""
    values = v.tolist()
    if not math.isfinite(sum(values)) and not all(map(math.isfinite, values)):
        raise InvalidInput(f"{name}: contains NaN or inf: {values}")
    return values


def _point(name: str, v) -> np.ndarray:
    """A non-empty (m,) point [m]."""
    p = as_array(name, v, ndim_min=1)
    if p.ndim != 1 or p.size == 0:
        raise InvalidInput(f"{name}: expected an (m,) point with m >= 1, got shape {p.shape}")
    return p


@dataclasses.dataclass(frozen=True)
class Wall:
    """A one-sided spring–damper along `normal`: F = −(K d + B ḋ) n while d = nᵀ(x − point) > 0.

    Attributes:
        point: (m,) surface point [m] (the palpation start X₀).
        normal: (m,) direction *into* the environment (normalised).
        stiffness: K_e [N/m].
        damping: B_e [N s/m] (acts only while pushing in; a wall never pulls).
    """

    point: np.ndarray
    normal: np.ndarray
    stiffness: float
    damping: float = 0.0
    _p: list[float] = dataclasses.field(init=False, repr=False, compare=False)  # point and normal as floats
    _n: list[float] = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        p = _point("point", self.point)
        object.__setattr__(self, "point", p)
        object.__setattr__(self, "normal", unit_vector("normal", self.normal, p.shape[-1]))
        object.__setattr__(self, "stiffness", _gain("stiffness", self.stiffness))
        object.__setattr__(self, "damping", _gain("damping", self.damping))
        object.__setattr__(self, "_p", p.tolist())
        object.__setattr__(self, "_n", self.normal.tolist())

    def force(self, x, xdot) -> np.ndarray:
        """Force on the handle: (..., m) [N] at positions x: (..., m) [m] moving at ẋ: (..., m) [m/s]."""
        x = np.asarray(x)
        if x.shape == self.point.shape:  # one point: the simulation loop's case, on plain floats
            n = self._n
            d = 0.0
            for a, b, c in zip(_finite("x", x), self._p, n):
                d += (a - b) * c
            push = 0.0
            if d > 0:
                v = np.asarray(xdot)
                if v.shape != x.shape:
                    raise InvalidInput(f"xdot: expected shape {x.shape} like x, got {v.shape}")
                dd = 0.0
                for a, c in zip(_finite("xdot", v), n):
                    dd += a * c
                push = max(self.stiffness * d + self.damping * dd, 0.0)
            return np.array([-push * c for c in n])
        x = as_array("x", x, shape_tail=self.point.shape)
        depth = (x - self.point) @ self.normal
        rate = as_array("xdot", xdot, shape_tail=self.point.shape) @ self.normal
        pushes = np.where(depth > 0, self.stiffness * depth + self.damping * rate, 0.0)
        return -np.maximum(pushes, 0.0)[..., None] * self.normal


def stop(point, normal, *, stiffness: float = 2.0e4, damping: float = 50.0) -> Wall:
    """A rigid physical stop (§3.5: the 8 cm stop of the palpation box): a very stiff wall."""
    return Wall(point, normal, stiffness, damping)


@dataclasses.dataclass(frozen=True)
class Spring:
    """A two-sided spring–damper to a point, optionally only along a direction u.

    F = −K P (x − point) − B P ẋ with P = u uᵀ (or I).

    Attributes:
        point: (m,) rest point [m].
        stiffness: K [N/m].
        damping: B [N s/m].
        direction: (m,) u, or None for every direction.
    """

    point: np.ndarray
    stiffness: float
    damping: float = 0.0
    direction: np.ndarray | None = None
    _P: np.ndarray = dataclasses.field(init=False, repr=False, compare=False)  # the projector P

    def __post_init__(self) -> None:
        p = _point("point", self.point)
        object.__setattr__(self, "point", p)
        object.__setattr__(self, "stiffness", _gain("stiffness", self.stiffness))
        object.__setattr__(self, "damping", _gain("damping", self.damping))
        m = p.shape[-1]
        P = np.eye(m) if self.direction is None else np.outer(*(2 * [unit_vector("direction", self.direction, m)]))
        object.__setattr__(self, "_P", P)

    def force(self, x, xdot) -> np.ndarray:
        """Force on the handle: (..., m) [N] at positions x: (..., m) [m] moving at ẋ: (..., m) [m/s]."""
        return -(self.stiffness * (np.asarray(x) - self.point) + self.damping * np.asarray(xdot)) @ self._P


@dataclasses.dataclass(frozen=True)
class Fixture:
    """A virtual fixture keeping the hand on the line through `point` along `direction` (§3.5).

    F = −(I − u uᵀ)(K (x − point) + B ẋ).

    Attributes:
        point: (m,) a point of the line [m].
        direction: (m,) u, the allowed direction.
        stiffness: K [N/m].
        damping: B [N s/m].
    """

    point: np.ndarray
    direction: np.ndarray
    stiffness: float = 1000.0
    damping: float = 5.0
    _P: np.ndarray = dataclasses.field(init=False, repr=False, compare=False)  # the projector I − u uᵀ

    def __post_init__(self) -> None:
        p = _point("point", self.point)
        object.__setattr__(self, "point", p)
        u = unit_vector("direction", self.direction, p.shape[-1])
        object.__setattr__(self, "direction", u)
        object.__setattr__(self, "stiffness", _gain("stiffness", self.stiffness))
        object.__setattr__(self, "damping", _gain("damping", self.damping))
        object.__setattr__(self, "_P", np.eye(p.shape[-1]) - np.outer(u, u))

    def force(self, x, xdot) -> np.ndarray:
        """Force on the handle: (..., m) [N] at positions x: (..., m) [m] moving at ẋ: (..., m) [m/s]."""
        return -(self.stiffness * (np.asarray(x) - self.point) + self.damping * np.asarray(xdot)) @ self._P


@dataclasses.dataclass(frozen=True)
class Compose:
    """The sum of several environments."""

    parts: tuple

    def force(self, x, xdot) -> np.ndarray:
        """Force on the handle: (..., m) [N] at positions x: (..., m) [m] moving at ẋ: (..., m) [m/s]."""
        F: float | np.ndarray = 0.0
        for p in self.parts:
            F = F + p.force(x, xdot)
        return np.broadcast_to(F, np.shape(x)).copy() if np.ndim(F) == 0 else np.asarray(F)


def compose(*parts) -> Compose:
    """Sum of environments (e.g. a wall plus a fixture)."""
    for i, p in enumerate(parts):
        if not callable(getattr(p, "force", None)):
            raise InvalidInput(f"parts[{i}]: {type(p).__name__} has no force(x, xdot) method")
    return Compose(tuple(parts))


_KINDS = {"wall": Wall, "spring": Spring, "fixture": Fixture}


def describe(env) -> list[dict] | None:
    """A JSON description of a `Wall`, `Spring`, `Fixture` or a `compose` of them (stored in a log's header).

    Returns None for an environment of another type (a user's own: not describable).
    """
    if env is None:
        return None
    parts = env.parts if isinstance(env, Compose) else (env,)
    out = []
    for p in parts:
        kind = {Wall: "wall", Spring: "spring", Fixture: "fixture"}.get(type(p))
        if kind is None:
            return None
        d = {f.name: getattr(p, f.name) for f in dataclasses.fields(p) if f.init}
        out.append({"type": kind, **{k: (None if v is None else np.asarray(v, dtype=float).tolist())
                                     for k, v in d.items()}})
    return out


def from_description(items) -> Wall | Spring | Fixture | Compose | None:
    """The environment `describe` described (None for None or an empty list).

    Raises:
        InvalidInput: a malformed description (named by its index and key).
    """
    if not items:
        return None
    if not isinstance(items, list):
        raise InvalidInput(f"environment: expected a list of parts, got {type(items).__name__}")
    parts = []
    for i, d in enumerate(items):
        if not isinstance(d, dict) or d.get("type") not in _KINDS:
            raise InvalidInput(f"environment[{i}]: expected a table with type in {sorted(_KINDS)}, got {d!r}")
        cls = _KINDS[d["type"]]
        names = {f.name for f in dataclasses.fields(cls) if f.init}
        extra = sorted(set(d) - names - {"type"})
        if extra:
            raise InvalidInput(f"environment[{i}]: unknown key(s) {extra} for a {d['type']}")
        try:
            parts.append(cls(**{k: v for k, v in d.items() if k != "type"}))
        except TypeError as exc:
            raise InvalidInput(f"environment[{i}]: {exc}") from None
    return parts[0] if len(parts) == 1 else compose(*parts)
