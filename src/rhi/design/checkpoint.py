"""Resumable evaluation: a disk cache of design evaluations keyed by the exact design vector.

Sweeps and the seeded optimiser are deterministic, so re-running an interrupted job with
the same cache replays every finished evaluation from disk and computes only the rest.
The cache is rewritten atomically (temporary file + rename) after every batch. The file
carries a schema name and version and a SHA-256 checksum of its content: a tampered,
truncated or foreign file is refused, never silently replayed.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rhi.errors import InvalidInput

SCHEMA = "rhi.design.checkpoint"
VERSION = 1


def _digest(tag: str, results: dict) -> str:
    """SHA-256 of the canonical JSON of (tag, results)."""
    text = json.dumps({"tag": tag, "results": results}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _key(x: Sequence[float]) -> str:
    return ",".join(float(v).hex() for v in np.atleast_1d(np.asarray(x, dtype=float)))


class EvalCache:
    """{design vector: result dict}, optionally persisted as JSON at `path`.

    Args:
        path: JSON file (created if missing); None keeps the cache in memory only.
        tag: identifies the problem; a file written for another tag is rejected.
    """

    def __init__(self, path: str | Path | None = None, tag: str = "") -> None:
        self.path = None if path is None else Path(path)
        self.tag = tag
        self.data: dict[str, Any] = {}
        if self.path is not None and self.path.is_file():
            self.data = self._load(self.path, tag)
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
        return results

    def __len__(self) -> int:
        return len(self.data)

    def save(self) -> None:
        """Write the evaluations to the checkpoint file (atomically: a temporary file, then a rename)."""
        if self.path is None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_suffix(self.path.suffix + ".tmp")
        blob = {"schema": SCHEMA, "version": VERSION, "tag": self.tag, "results": self.data,
                "sha256": _digest(self.tag, self.data)}
        tmp.write_text(json.dumps(blob))
        os.replace(tmp, self.path)

    def map(self, fn: Callable[[np.ndarray], Any], xs: Sequence[Sequence[float]], mapper) -> list[Any]:
        """Results of fn at each x, computing (through ``mapper(fn, items)``) only the ones not cached."""
        keys = [_key(x) for x in xs]
        todo = [i for i, k in enumerate(keys) if k not in self.data]
        self.hits += len(xs) - len(todo)
        if todo:
            for i, r in zip(todo, mapper(fn, [np.asarray(xs[i], dtype=float) for i in todo])):
                self.data[keys[i]] = r
            self.save()
        return [self.data[k] for k in keys]
