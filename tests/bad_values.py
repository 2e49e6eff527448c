"""Generated invalid values for the property-based bad-input tests (issue 24), shared by the test modules."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, settings, strategies as st

from rhi.errors import RhiError


def cli_exit(argv: list[str]) -> int:
    """`rhi.cli.main(argv)`'s exit status, whether it returns or raises SystemExit."""
    from rhi.cli import main

    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def examples(n: int):
    """Hypothesis settings: `n` examples, derandomized (a reproducible suite), no deadline."""
    return settings(max_examples=n, derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.function_scoped_fixture])


# ------------------------------------------------------------------ generated invalid values
NOT_A_NUMBER = st.one_of(st.text(max_size=5), st.none(), st.just(1j), st.lists(st.floats(), max_size=2),
                         st.just({"a": 1}))
NON_FINITE = st.sampled_from([math.nan, math.inf, -math.inf])


def bad_scalar(*, low_ok: float | None = None, high_ok: float | None = None):
    """Values that are not a finite number inside [low_ok, high_ok]."""
    parts = [NOT_A_NUMBER, NON_FINITE]
    if low_ok is not None:
        parts.append(st.floats(max_value=low_ok, exclude_max=True, allow_nan=False, allow_infinity=False,
                               min_value=-1e300))
    if high_ok is not None:
        parts.append(st.floats(min_value=high_ok, exclude_min=True, allow_nan=False, max_value=1e300))
    return st.one_of(*parts)


def bad_vector(n: int, *, none_is_valid: bool = False):
    """(n,) vectors with a NaN/inf entry, a wrong length, or not numbers (None too unless it is valid)."""
    finite = st.floats(-10, 10)
    with_bad = st.tuples(st.lists(finite, min_size=n, max_size=n), st.integers(0, n - 1), NON_FINITE).map(
        lambda t: np.array(t[0][:t[1]] + [t[2]] + t[0][t[1] + 1:]))
    wrong = st.integers(0, 2 * n + 1).filter(lambda k: k != n).map(lambda k: np.ones(k))
    return st.one_of(with_bad, wrong, st.text(max_size=3), st.just(np.ones((2, n + 1))),
                     *([] if none_is_valid else [st.none()]))


def bad_matrix(rows: int, cols: int, *, none_is_valid: bool = False):
    """(rows, cols) matrices with a NaN/inf entry, or a vector, or not numbers (None too unless it is valid)."""
    nan_at = st.tuples(st.integers(0, rows * cols - 1), NON_FINITE).map(
        lambda t: np.where(np.arange(rows * cols) == t[0], t[1], 1.0).reshape(rows, cols))
    parts = [nan_at, st.just(np.ones(cols)), st.text(max_size=3)] + ([] if none_is_valid else [st.none()])
    return st.one_of(*parts)


def bad_object():
    """Objects of the wrong kind for an argument that takes an object with methods."""
    return st.one_of(st.text(max_size=4), st.integers(), st.floats(), st.just([1, 2]), st.just({"x": 1}))


def expect_error(fn, name: str, /, **kwargs) -> None:
    """fn(**kwargs) must raise an rhi.errors error naming `name`."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        try:
            out = fn(**kwargs)
        except RhiError as exc:
            assert name in str(exc), f"error does not name {name!r}: {exc}"
            return
        except Exception as exc:  # noqa: BLE001 - the point of the suite
            pytest.fail(f"{name}={kwargs.get(name)!r:.80}: foreign {type(exc).__name__}: {exc}")
    pytest.fail(f"{name}={kwargs.get(name)!r:.80}: accepted, returned {out!r:.120}")
