"""A small, explicit schema for configuration tables (TOML): allowed keys, their types, defaults.

A *spec* maps each allowed key to ``(check, default)``: ``check(path, value)`` validates one
value and returns it converted (floats, NumPy arrays, nested dicts); ``default`` is used when
the key is absent, `REQUIRED` makes it mandatory. Every error is an `InvalidInput` naming the
full key path, e.g. ``controller.objectives[1].gain: expected a number, got 'x'``. Nothing is
evaluated: values are only type-checked and converted.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection, Mapping
from typing import cast

import numpy as np

from rhi.errors import InvalidInput, RhiError

REQUIRED = object()
Check = Callable[[str, object], object]
Spec = Mapping[str, tuple[Check, object]]


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _fail(path: str, want: str, v) -> InvalidInput:
    return InvalidInput(f"{path}: expected {want}, got {v!r}")


def number(*, low: float | None = None, strict: bool = False, high: float | None = None) -> Check:
    """A finite number (int or float), optionally ≥ `low` (> `low` with `strict`) and ≤ `high`, as a float."""
    bound = ("" if low is None else f" {'>' if strict else '>='} {low:g}") + ("" if high is None else
                                                                            f" and <= {high:g} (plausibility bound)")

    def check(path: str, v) -> float:
        if not _is_num(v) or not math.isfinite(v):
            raise _fail(path, "a number" + bound, v)
        if (low is not None and (v < low or (strict and v == low))) or (high is not None and v > high):
            raise _fail(path, "a number" + bound, v)
        return float(v)

    return check


def integer(*, low: int | None = None, high: int | None = None) -> Check:
    """An integer, optionally ≥ `low` and ≤ `high`."""

    def check(path: str, v) -> int:
        if not isinstance(v, int) or isinstance(v, bool) or (low is not None and v < low) or (
                high is not None and v > high):
            raise _fail(path, "an integer" + ("" if low is None else f" >= {low}")
                        + ("" if high is None else f" and <= {high} (plausibility bound)"), v)
        return v

    return check


def boolean(path: str, v) -> bool:
    """True or false."""
    if not isinstance(v, bool):
        raise _fail(path, "true or false", v)
    return v


def choice(*options: str) -> Check:
    """One of the given strings."""
    return one_of(lambda: options)


def one_of(names: Callable[[], tuple[str, ...]]) -> Check:
    """One of the strings `names()` gives when a file is read (e.g. a registry that grows after import)."""

    def check(path: str, v) -> str:
        options = names()
        if not isinstance(v, str) or v not in options:
            raise _fail(path, "one of " + ", ".join(repr(o) for o in options), v)
        return v

    return check


def string(path: str, v) -> str:
    """Any string."""
    if not isinstance(v, str):
        raise _fail(path, "a string", v)
    return v


def vector(length: int | None = None, *, low: float | None = None, high: float | None = None) -> Check:
    """A non-empty list of finite numbers (of `length` if given, each in [`low`, `high`]), as a float array."""
    want = f"a list of {length if length else 'one or more'} numbers"
    entry = number(low=low, high=high)

    def check(path: str, v) -> np.ndarray:
        if not isinstance(v, list) or not v or (length is not None and len(v) != length):
            raise _fail(path, want, v)
        for i, x in enumerate(v):
            entry(f"{path}[{i}]", x)
        return np.array(v, dtype=float)

    return check


def matrix(path: str, v) -> np.ndarray:
    """A list of equally long lists of finite numbers, as a 2-D float array."""
    rows = isinstance(v, list) and v and all(isinstance(r, list) and r for r in v)
    if not rows or len({len(r) for r in v}) != 1:
        raise _fail(path, "a matrix (a list of equally long lists of numbers)", v)
    for i, row in enumerate(v):
        vector()(f"{path}[{i}]", row)
    return np.array(v, dtype=float)


def optional(check: Check) -> Check:
    """None (a JSON null) or a value `check` accepts."""
    return lambda path, v: None if v is None else check(path, v)


def either(*checks: Check, want: str) -> Check:
    """The first of `checks` that accepts the value (e.g. a number or a matrix)."""

    def check(path: str, v):
        inner = None  # a check that failed inside the value (a key of a table): its error names the deeper path
        for c in checks:
            try:
                return c(path, v)
            except InvalidInput as exc:
                if str(exc).startswith((f"{path}.", f"{path}[")):
                    inner = inner or exc
        if inner is not None:
            raise inner
        raise _fail(path, want, v)

    return check


def numbers_table(path: str, v) -> dict[str, float]:
    """A table of named numbers (names free, e.g. a device's design parameters)."""
    if not isinstance(v, dict):
        raise _fail(path, "a table of numbers", v)
    return {k: cast(float, number()(f"{path}.{k}", x)) for k, x in v.items()}


def table(spec: Spec) -> Check:
    """A nested table following `spec`."""
    return lambda path, v: parse(path, v, spec)


def tables(item: Check) -> Check:
    """An array of tables, each checked by `item` (`table(spec)` or `tagged(...)`); one table counts as one item."""

    def check(path: str, v) -> list[object]:
        if isinstance(v, dict):
            v = [v]
        if not isinstance(v, list):
            raise _fail(path, "an array of tables", v)
        return [item(f"{path}[{i}]", t) for i, t in enumerate(v)]

    return check


def tagged(tag: str, specs: Mapping[str, Spec]) -> Check:
    """A table whose `tag` key (e.g. "type") selects its spec among `specs`."""

    def check(path: str, v) -> dict:
        if not isinstance(v, dict):
            raise _fail(path, "a table", v)
        if tag not in v:
            raise InvalidInput(f"{path}.{tag}: missing (one of {', '.join(repr(k) for k in specs)})")
        kind = cast(str, choice(*specs)(f"{path}.{tag}", v[tag]))
        rest = {k: x for k, x in v.items() if k != tag}
        return {tag: kind, **parse(path, rest, specs[kind])}

    return check


def parse(path: str, d, spec: Spec) -> dict:
    """Check the table `d` (at key path `path`, "" for the root) against `spec`; defaults filled in.

    Raises:
        InvalidInput: not a table, an unknown key, a missing required key, a value of the wrong type.
    """
    where = path or "configuration"
    if not isinstance(d, dict):
        raise _fail(where, "a table", d)
    unknown = sorted(set(d) - set(spec))
    if unknown:
        key = f"{path}.{unknown[0]}" if path else unknown[0]
        raise InvalidInput(f"{key}: unknown key in {where} (allowed: {', '.join(sorted(spec))})")
    out = {}
    for key, (check, default) in spec.items():
        full = f"{path}.{key}" if path else key
        if key in d:
            out[key] = check(full, d[key])
        elif default is REQUIRED:
            raise InvalidInput(f"{full}: missing (required in {where})")
        elif isinstance(default, dict):  # an absent nested table: its own defaults
            out[key] = check(full, default)
        else:
            out[key] = default
    return out


def prefixed(path: str, fn: Callable, *args, **kwargs):
    """Call fn(*args, **kwargs); an `RhiError` it raises is re-raised, same class, with `path` before its message."""
    return keyed(path, (), fn, *args, **kwargs)


def keyed(path: str, keys: Collection[str], fn: Callable, *args, **kwargs):
    """`prefixed`, as ``path.key: ...`` where the error's message starts with one of `keys` (``key: ...``)."""
    try:
        return fn(*args, **kwargs)
    except RhiError as exc:
        msg = str(exc)
        raise type(exc)(f"{path}.{msg}" if msg.partition(":")[0] in keys else f"{path}: {msg}") from None
