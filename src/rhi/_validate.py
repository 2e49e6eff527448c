"""Argument checks shared by every layer: each raises an `rhi.errors` error naming the argument."""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path

import numpy as np

from rhi.errors import InfeasibleLimits, InvalidInput


def all_finite(arr: np.ndarray) -> bool:
    """Whether every entry of the float array `arr` is finite."""
    # The sum of squares (or, for large arrays, the sum: no BLAS call, whose threads stall on a shared machine)
    # is finite iff every entry is, unless huge entries overflow it: then check one by one.
    total = arr.sum() if arr.size > 1024 else np.vdot(arr, arr)
    return math.isfinite(total) or bool(np.isfinite(arr).all())


def float_array(name: str, value) -> np.ndarray:
    """`value` as a float array; refuses None, strings, complex numbers and non-numeric objects."""
    if value is None or isinstance(value, (str, bytes, dict, set)):
        raise InvalidInput(f"{name}: expected a number or an array of numbers, got {type(value).__name__}")
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiub":
        return value.astype(float, copy=False)
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError) as exc:  # ragged nesting
        raise InvalidInput(f"{name}: cannot be read as an array of numbers ({exc})") from None
    if raw.dtype.kind == "c":
        raise InvalidInput(f"{name}: complex values are not accepted (got dtype {raw.dtype})")
    if raw.dtype.kind not in "fiub":
        if raw.dtype.kind == "O" and all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                                         for v in raw.flat):
            return raw.astype(float)
        raise InvalidInput(f"{name}: expected numbers, got an array of dtype {raw.dtype}")
    return raw.astype(float, copy=False)


def as_array(name: str, value, *, ndim_min: int = 0, shape_tail: tuple[int | None, ...] = ()) -> np.ndarray:
    """Return `value` as a finite float array, checking its trailing shape.

    Args:
        name: argument name used in error messages.
        value: array-like input.
        ndim_min: minimum number of dimensions.
        shape_tail: required trailing dimensions (None = any size).
    """
    arr = float_array(name, value)
    ndim = max(ndim_min, len(shape_tail))
    if arr.ndim < ndim:
        raise InvalidInput(f"{name}: expected at least {ndim} dimension(s), got shape {arr.shape}")
    if shape_tail:
        tail = arr.shape[arr.ndim - len(shape_tail):]
        for got, want in zip(tail, shape_tail):
            if want is not None and got != want:
                want_s = "(..., " + ", ".join("*" if w is None else str(w) for w in shape_tail) + ")"
                raise InvalidInput(f"{name}: expected shape {want_s}, got {arr.shape}")
    if not all_finite(arr):
        raise InvalidInput(f"{name}: contains NaN or inf")
    return arr


def limits_pair(name_min: str, lo, name_max: str, hi, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Validate a (minimum, maximum) pair of limit vectors: not NaN, same shape, min <= max."""
    lo = float_array(name_min, lo)
    hi = float_array(name_max, hi)
    if np.isnan(lo).any() or np.isnan(hi).any():
        raise InvalidInput(f"{name_min}/{name_max}: contains NaN")
    if n is not None:
        lo = np.broadcast_to(lo, (n,)) if lo.ndim == 0 else lo
        hi = np.broadcast_to(hi, (n,)) if hi.ndim == 0 else hi
        if lo.shape[-1:] != (n,) or hi.shape[-1:] != (n,):
            raise InvalidInput(f"{name_min}/{name_max}: expected {n} entries, got shapes {lo.shape} and {hi.shape}")
    bad = lo > hi
    if bad.any():
        raise InfeasibleLimits(f"{name_min} > {name_max} at index {int(np.flatnonzero(bad)[0])}")
    return lo, hi


def per_joint(name: str, value, n: int, *, positive: bool = False) -> np.ndarray:
    """`value` as (n,) floats, one a joint (a scalar is every joint's): each finite and >= 0 (> 0 with `positive`).

    Raises:
        InvalidInput: not a number or an (n,) array of them, non-finite, or out of range (naming `name`).
    """
    v = as_array(name, value)
    v = np.full(n, float(v)) if v.ndim == 0 else v
    if v.shape != (n,):
        raise InvalidInput(f"{name}: expected a scalar or {n} values, got shape {v.shape}")
    if np.any(v <= 0) if positive else np.any(v < 0):
        raise InvalidInput(f"{name}: expected {n} values {'> 0' if positive else '>= 0'}, got {v.tolist()}")
    return v


def unit_vector(name: str, u, m: int | None = None) -> np.ndarray:
    """Return `u` normalised along its last axis; raise if any vector has zero length."""
    u = as_array(name, u, ndim_min=1, shape_tail=(m,) if m else ())
    norm = np.sqrt((u * u).sum(axis=-1, keepdims=True))
    if (norm < 1e-12).any():
        raise InvalidInput(f"{name}: zero-length direction vector")
    return u / norm


MAX_DURATION = 1e6
"""[s] The longest run, live view or device-server session rhi accepts (11.6 days; 1e300 s would never end)."""


def writable_file(name: str, path, *, suffix: str | None = None) -> Path:
    """`path` as an output file that can be written: not a folder, in a folder that exists or can be made.

    Checked before the work that produces the file starts, leaving nothing behind (a folder it made to check is
    taken back, so a run refused later leaves no empty folder); the writer makes the folder (`parent_made`).
    `suffix` (e.g. ".png") is required when given.

    Raises:
        InvalidInput: naming `name` (an argument or a flag such as "--log").
    """
    if path is None or not isinstance(path, (str, os.PathLike)) or not str(path):
        raise InvalidInput(f"{name}: expected a file path, got {path!r}")
    p = Path(path)
    if suffix is not None and p.suffix.lower() != suffix:
        raise InvalidInput(f"{name}: expected a {suffix} file name, got {str(path)!r}")
    if p.is_dir():
        raise InvalidInput(f"{name}: {p} is a folder, not a file")
    made = [d for d in p.absolute().parents if not d.exists()]  # innermost first
    try:
        p.parent.mkdir(parents=True, exist_ok=True)  # made for real (a checked answer), then taken back
        writable = os.access(p if p.exists() else p.parent, os.W_OK)
    except OSError as exc:
        raise InvalidInput(f"{name}: cannot create the folder {p.parent} ({exc.strerror or exc})") from None
    finally:
        for d in made:
            with contextlib.suppress(OSError):
                d.rmdir()
    if not writable:
        raise InvalidInput(f"{name}: cannot write {p} (permission denied)")
    return p


def parent_made(path: Path) -> Path:
    """`path` after making its folder (a path `writable_file` accepted)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def scalar(name: str, value, *, positive: bool = False, nonnegative: bool = False, allow_inf: bool = False) -> float:
    """Return `value` as a float, refusing None, strings, complex numbers, arrays and NaN.

    ±inf and booleans are refused (unless `allow_inf` for ±inf); `positive` requires > 0, `nonnegative` >= 0.
    """
    if value is None or isinstance(value, (str, bytes, bool, np.bool_, complex, np.complexfloating)) \
            or not isinstance(value, (int, float, np.integer, np.floating, np.ndarray)) or np.ndim(value) != 0:
        raise InvalidInput(f"{name}: expected a real number, got {value!r:.60}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInput(f"{name}: expected a real number, got {value!r:.60}") from None
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise InvalidInput(f"{name}: must be finite, got {v}")
    if positive and not v > 0:
        raise InvalidInput(f"{name}: must be > 0, got {v}")
    if nonnegative and not v >= 0:
        raise InvalidInput(f"{name}: must be >= 0, got {v}")
    return v
