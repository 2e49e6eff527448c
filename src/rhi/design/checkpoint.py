"""Resumable evaluation: a disk cache of design evaluations keyed by the exact design vector.

Sweeps and the seeded optimiser are deterministic, so re-running an interrupted job with
the same cache replays every finished evaluation from disk and computes only the rest.
The cache is rewritten atomically (temporary file + rename) after every batch.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rhi.errors import InvalidInput


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
            try:
                blob = json.loads(self.path.read_text())
            except (OSError, json.JSONDecodeError) as exc:
                raise InvalidInput(f"checkpoint: cannot read {self.path} ({exc})") from None
            if blob.get("tag") != tag:
                raise InvalidInput(f"checkpoint: {self.path} belongs to another problem "
                                   f"({blob.get('tag')!r} != {tag!r}); remove it or choose another path")
            self.data = blob.get("results", {})
        self.hits = 0

    def __len__(self) -> int:
        return len(self.data)

    def save(self) -> None:
        if self.path is None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_suffix(self.path.suffix + ".tmp")
        tmp.write_text(json.dumps({"tag": self.tag, "results": self.data}))
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
