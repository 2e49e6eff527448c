"""Resumable evaluation: a disk cache of design evaluations keyed by the exact design vector.

Sweeps and the seeded optimiser are deterministic, so re-running an interrupted job with
the same cache replays every finished evaluation from disk and computes only the rest.
The cache is rewritten atomically after every batch (a temporary file of its own, then a
rename), merged with what another writer of the same file saved meanwhile, so two processes
sharing one checkpoint both finish and leave a valid file. The file carries a schema name and
version and a SHA-256 checksum of its content, and its values are checked, not only its
checksum: every entry must be a design vector of one length with a result of the same
fields, and a few loaded entries chosen at random are recomputed (with the first batch) and
must match; a tampered, truncated, foreign or stale file is refused, never silently replayed.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import random
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rhi.errors import InvalidInput

SCHEMA = "rhi.design.checkpoint"
VERSION = 1
#: Loaded entries recomputed (at random) when a cache is first used, and the tolerance of the comparison.
SPOT_CHECKS = 3
RTOL = 1e-6


def _digest(tag: str, results: dict) -> str:
    """SHA-256 of the canonical JSON of (tag, results)."""
    text = json.dumps({"tag": tag, "results": results}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _key(x: Sequence[float] | np.ndarray) -> str:
    return ",".join(float(v).hex() for v in np.atleast_1d(np.asarray(x, dtype=float)))


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _check_entries(path: Path, results: dict) -> None:
    """Every key a design vector of one length, every result a dict of numbers (or lists of numbers), same fields."""
    fields, length = None, None
    for key, res in results.items():
        try:
            x = [float.fromhex(v) for v in key.split(",")]
        except (ValueError, OverflowError):
            raise InvalidInput(f"checkpoint: {path}: entry {key[:40]!r} is not a design vector") from None
        if length is None:
            length = len(x)
        if len(x) != length or not all(map(math.isfinite, x)):
            raise InvalidInput(f"checkpoint: {path}: entry {key[:40]!r} is not a finite design vector of {length} values")
        if not isinstance(res, dict) or not all(
                _number(v) or (isinstance(v, list) and all(map(_number, v))) for v in res.values()):
            raise InvalidInput(f"checkpoint: {path}: the result at x={x} is not a record of numbers")
        if fields is None:
            fields = set(res)
        if set(res) != fields:
            raise InvalidInput(f"checkpoint: {path}: the result at x={x} has fields {sorted(res)}, "
                               f"the others {sorted(fields)}")


def _same(a: Any, b: Any) -> bool:
    """Whether two results agree (same fields; numbers equal to `RTOL`, NaN equal to NaN)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return set(a) == set(b) and all(_same(a[k], b[k]) for k in a)
    try:
        return bool(np.allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float), rtol=RTOL, atol=1e-12,
                                equal_nan=True))
    except (TypeError, ValueError):
        return a == b


class EvalCache:
    """{design vector: result dict}, optionally persisted as JSON at `path`.

    Args:
        path: JSON file (created if missing); None keeps the cache in memory only.
        tag: identifies the problem; a file written for another tag is rejected.
        spot_checks: loaded entries recomputed with the first batch of `map` (at random), which must match.

    Raises:
        InvalidInput: the file is unreadable, foreign, of another problem, fails its checksum, or holds
            malformed entries (at construction), or a recomputed entry differs from the file (in `map`).
    """

    def __init__(self, path: str | Path | None = None, tag: str = "", *, spot_checks: int = SPOT_CHECKS) -> None:
        self.path = None if path is None else Path(path)
        self.tag = tag
        self.data: dict[str, Any] = {}
        if self.path is not None and self.path.is_file():
            self.data = self._load(self.path, tag)
        self.loaded = set(self.data)  # entries read from the file, not computed here
        self._unchecked = random.SystemRandom().sample(sorted(self.data), min(spot_checks, len(self.data)))
        self.hits = 0

    @staticmethod
    def _load(path: Path, tag: str) -> dict[str, Any]:
        """The results of a checkpoint file, after checking its schema, version, checksum and tag."""
        try:
            blob = json.loads(path.read_text())
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise InvalidInput(f"checkpoint: cannot read {path} (truncated or not JSON: {exc})") from None
        if not isinstance(blob, dict) or blob.get("schema") != SCHEMA:
            raise InvalidInput(f"checkpoint: {path} is not an rhi design checkpoint (no schema {SCHEMA!r})")
        if blob.get("version") != VERSION:
            raise InvalidInput(f"checkpoint: {path} has schema version {blob.get('version')!r}; this rhi reads {VERSION}")
        results = blob.get("results")
        if not isinstance(results, dict) or not isinstance(blob.get("tag"), str):
            raise InvalidInput(f"checkpoint: {path} is malformed (missing tag or results)")
        if blob.get("sha256") != _digest(blob["tag"], results):
            raise InvalidInput(f"checkpoint: {path} fails its checksum (modified or corrupted); remove it to start over")
        if blob["tag"] != tag:
            raise InvalidInput(f"checkpoint: {path} belongs to another problem "
                               f"({blob['tag']!r} != {tag!r}); remove it or choose another path")
        _check_entries(path, results)
        return results

    def confirm(self, x: Sequence[float] | np.ndarray, result: Any) -> None:
        """Check a freshly computed `result` at x against the entry the file held there (if any).

        Raises:
            InvalidInput: the file's entry differs (edited, or written by another version of rhi).
        """
        key = _key(x)
        if key in self.loaded and not _same(self.data[key], result):
            raise InvalidInput(f"checkpoint: {self.path}: the entry at x={np.atleast_1d(x).tolist()} holds "
                               f"{self.data[key]} but recomputes to {result} (edited, or written by another version "
                               "of rhi); remove the file to start over")

    def __len__(self) -> int:
        return len(self.data)

    def save(self) -> None:
        """Write the evaluations to the checkpoint file (atomically: a temporary file, then a rename)."""
        if self.path is None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.is_file():  # another writer's entries (e.g. a parallel experiment sharing the file)
            try:
                theirs = self._load(self.path, self.tag)
            except InvalidInput:
                theirs = {}
            for k, v in theirs.items():
                self.data.setdefault(k, v)
        blob = {"schema": SCHEMA, "version": VERSION, "tag": self.tag, "results": self.data,
                "sha256": _digest(self.tag, self.data)}
        fd, tmp = tempfile.mkstemp(prefix=self.path.name + ".", suffix=".tmp", dir=self.path.parent)
        try:
            with os.fdopen(fd, "w") as f:
                f.write(json.dumps(blob))
            os.replace(tmp, self.path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def map(self, fn: Callable[[np.ndarray], Any], xs: Sequence[Sequence[float]], mapper) -> list[Any]:
        """Results of fn at each x, computing (through ``mapper(fn, items)``) only the ones not cached."""
        keys = [_key(x) for x in xs]
        todo = [i for i, k in enumerate(keys) if k not in self.data]
        self.hits += len(xs) - len(todo)
        checks, self._unchecked = self._unchecked, []  # recomputed with this batch, once
        if todo or checks:
            items = [np.asarray(xs[i], dtype=float) for i in todo] + [
                np.array([float.fromhex(v) for v in k.split(",")]) for k in checks]
            out = list(mapper(fn, items))
            for i, r in zip(todo, out):
                self.data[keys[i]] = r
            for x, r in zip(items[len(todo):], out[len(todo):]):
                self.confirm(x, r)
            if todo:
                self.save()
        return [self.data[k] for k in keys]
