"""One argument check for every experiment: `checked` derives each parameter's rule from its default.

An experiment's keyword parameters have defaults of the thesis's values; a value given in their place must be of
the same kind and plausible:

- a bool default takes a bool;
- an int default takes an integer (not a bool): >= 1 when the default is >= 1, else >= 0 (seeds), and at most
  `MAX_FACTOR` times a positive default (sizes, counts, resolutions);
- a float default takes a finite real number: > 0 when the default is > 0 (durations, gains, stiffnesses), >= 0
  when it is 0 or the parameter is named in ``checked(skip_at_zero=...)`` (0 documented as "skip this part"),
  and at most `MAX_FACTOR` times a positive default;
- a str default takes a str (each experiment checks its own choices);
- a tuple default takes a sequence whose entries are of the kind of the default's first entry (finite numbers,
  strings or sequences);
- None, where the parameter's annotation allows it (``float | None``);
- ``progress`` takes None or a callable; None defaults and the other objects are the experiment's own to check.

A bad value raises `rhi.errors.InvalidInput` naming the argument before any work starts.
"""

from __future__ import annotations

import functools
import inspect
import math
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np

from rhi.errors import InvalidInput

MAX_FACTOR = 100.0
"""A positive number or count may be at most this many times its default (1e300 s of simulation is a hang)."""

F = TypeVar("F", bound=Callable[..., Any])


def _is_int(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def _is_real(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _number(name: str, v, default: float, integer: bool, zero: bool) -> None:
    kind = "an integer" if integer else "a finite real number"
    if not (_is_int(v) if integer else _is_real(v)) or not math.isfinite(float(v)):
        raise InvalidInput(f"{name}: expected {kind}, got {v!r:.60}")
    if default > 0 and zero and v == 0:
        return
    if default > 0:
        low = 1 if integer else 0.0
        if not (v >= low if integer else v > low) or v > MAX_FACTOR * default:
            raise InvalidInput(f"{name}: expected {kind} in {'[1' if integer else '(0'}, {MAX_FACTOR * default:g}] "
                               f"(at most {MAX_FACTOR:g} × the default {default:g}), got {v!r:.60}")
    elif default == 0 and v < 0:
        raise InvalidInput(f"{name}: expected {kind} >= 0, got {v!r:.60}")


def _entry_rule(first) -> Callable[[str, Any], None] | None:
    if isinstance(first, str):
        def text(n: str, v) -> None:
            if not isinstance(v, str):
                raise InvalidInput(f"{n}: expected a name (str), got {v!r:.60}")
        return text
    if _is_real(first):
        def real(n: str, v) -> None:
            if not _is_real(v) or not math.isfinite(float(v)):
                raise InvalidInput(f"{n}: expected a finite real number, got {v!r:.60}")
        return real
    if isinstance(first, tuple):
        def seq(n: str, v) -> None:
            if isinstance(v, (str, bytes)) or not isinstance(v, (Sequence, np.ndarray)):
                raise InvalidInput(f"{n}: expected a sequence, got {v!r:.60}")
        return seq
    return None


def _rule(name: str, default, optional: bool, zero: bool) -> Callable[[Any], None] | None:
    """The check of parameter `name` from its default, None passing when `optional`, 0 when `zero` (None: no check)."""
    rule = _value_rule(name, default, zero)
    if rule is None or not optional:
        return rule
    return lambda v: None if v is None else rule(v)


def _value_rule(name: str, default, zero: bool) -> Callable[[Any], None] | None:
    if name == "progress":
        def progress(v) -> None:
            if v is not None and not callable(v):
                raise InvalidInput(f"progress: expected None or a callable, got {v!r:.60}")
        return progress
    if isinstance(default, bool):
        def boolean(v) -> None:
            if not isinstance(v, (bool, np.bool_)):
                raise InvalidInput(f"{name}: expected True or False, got {v!r:.60}")
        return boolean
    if _is_int(default) or isinstance(default, float):
        return lambda v: _number(name, v, float(default), _is_int(default), zero)
    if isinstance(default, str):
        def text(v) -> None:
            if not isinstance(v, str):
                raise InvalidInput(f"{name}: expected a str, got {v!r:.60}")
        return text
    if isinstance(default, tuple) and default:
        entry = _entry_rule(default[0])

        def sequence(v) -> None:
            if isinstance(v, (str, bytes, dict, set)) or not isinstance(v, (Sequence, np.ndarray)):
                raise InvalidInput(f"{name}: expected a sequence like {default!r:.60}, got {v!r:.60}")
            if entry is not None:
                for i, x in enumerate(v):
                    entry(f"{name}[{i}]", x)
        return sequence
    return None


def checked(fn: F | None = None, *, skip_at_zero: tuple[str, ...] = ()) -> Any:
    """`fn` with its arguments checked first by the rules of this module's docstring.

    Used as ``@checked`` or ``@checked(skip_at_zero=("t_long",))`` (those parameters also take 0). The wrapper also
    has ``check(*args, **kwargs)``: the same checks without running `fn`.
    """
    if fn is None:
        return functools.partial(checked, skip_at_zero=skip_at_zero)
    sig = inspect.signature(fn)
    rules = {p.name: r for p in sig.parameters.values() if p.default is not p.empty
             and (r := _rule(p.name, p.default, "None" in str(p.annotation), p.name in skip_at_zero)) is not None}

    def check(*args, **kwargs) -> None:
        try:
            bound = sig.bind(*args, **kwargs)
        except TypeError as exc:  # an unknown or missing argument
            raise InvalidInput(f"{fn.__name__}: {exc}") from None
        for name, value in bound.arguments.items():
            if name in rules:
                rules[name](value)

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        check(*args, **kwargs)
        return fn(*args, **kwargs)

    wrapper.check = check  # type: ignore[attr-defined]
    wrapper.skip_at_zero = skip_at_zero  # type: ignore[attr-defined]
    return wrapper


__all__ = ["MAX_FACTOR", "checked"]
