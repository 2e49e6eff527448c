"""Objective types by name: how a configuration file (``[[controller.objectives]]``) builds each objective.

Each bundled objective registers its type beside its class (``register(ObjectiveType(...))`` at the end of
its module): the name a configuration's ``type`` key gives, a builder ``build(device, torque_max, **keys)``
and its keys with their kinds and defaults. `rhi.runtime.config` reads any registered type, so a new bundled
objective needs no line there; an installed plugin's objective comes by entry point instead
(`rhi.runtime.objective_plugins`).

A builder raises `rhi.errors.InvalidInput` whose message starts with the key it refuses (``"u: ..."``); the
configuration reader puts the key path before it (``controller.objectives[0].u: ...``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Literal

import numpy as np

from rhi.errors import InvalidInput

#: The default of a key that must be given.
REQUIRED = object()


@dataclasses.dataclass(frozen=True)
class Key:
    """The kind of value a key takes (the configuration reader checks and converts it).

    Attributes:
        kind: "number" (a float within `low`/`high`), "vector" (a list of numbers), "matrix" (a list of equally
            long lists), "boolean", "string", "choice" (one of `options`) or "numbers" (a table of numbers).
        low: smallest number allowed (> `low` with `strict`), or None.
        strict: `low` itself is refused.
        high: largest number allowed (a plausibility bound), or None.
        options: the strings a "choice" takes.
    """

    kind: Literal["number", "vector", "matrix", "boolean", "string", "choice", "numbers"]
    low: float | None = None
    strict: bool = False
    high: float | None = None
    options: tuple[str, ...] = ()


VECTOR, MATRIX, BOOLEAN, STRING, NUMBERS = Key("vector"), Key("matrix"), Key("boolean"), Key("string"), Key("numbers")
#: A number > 0.
POSITIVE = Key("number", low=0.0, strict=True)


@dataclasses.dataclass(frozen=True)
class ObjectiveType:
    """An objective as a configuration file names it.

    Attributes:
        name: the ``type`` of its ``[[controller.objectives]]`` table.
        build: ``build(device, torque_max, **keys) -> Objective``; torque_max (n,) [N m] the controller's limits.
        keys: its keys (besides ``type`` and ``gain``): name → (`Key`, default or `REQUIRED`).
    """

    name: str
    build: Callable[..., object]
    keys: Mapping[str, tuple[Key, object]]


_TYPES: dict[str, ObjectiveType] = {}


def register(kind: ObjectiveType) -> ObjectiveType:
    """Make `kind` usable by its name in configuration files; returns it.

    Raises:
        InvalidInput: another type has that name.
    """
    if kind.name in _TYPES and _TYPES[kind.name] is not kind:
        raise InvalidInput(f"name: an objective type {kind.name!r} is registered already")
    _TYPES[kind.name] = kind
    return kind


def objective_type(name: str) -> ObjectiveType | None:
    """The registered objective type `name`, or None."""
    return _TYPES.get(name)


def objective_types() -> dict[str, ObjectiveType]:
    """Every registered objective type by name, in registration order."""
    return dict(_TYPES)


def shaped(key: str, v, shape: tuple[int, ...]) -> np.ndarray:
    """`v` as an array of `shape` (the device's dimensions), else InvalidInput naming `key`."""
    a = np.asarray(v, dtype=float)
    if a.shape != shape:
        raise InvalidInput(f"{key}: expected shape {shape} for this device, got {a.shape}")
    return a


__all__ = ["BOOLEAN", "MATRIX", "NUMBERS", "POSITIVE", "REQUIRED", "STRING", "VECTOR", "Key", "ObjectiveType",
           "objective_type", "objective_types", "register", "shaped"]
