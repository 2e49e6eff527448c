"""Executors with one interface, ``map(fn, items) -> list``, for design evaluations.

* `SerialExecutor`: in-process loop (the baseline and the debugging path).
* `PoolExecutor`: a local process pool (default; ``workers`` processes, items sent in chunks).
* `RayExecutor`: the same map on a Ray cluster (``address=None`` starts a local instance,
  ``"auto"`` or ``"ray://host:10001"`` joins a running one). Needs the optional ``ray``.

All return results in the order of ``items``, so a seeded sweep or optimisation gives the
same numbers whichever executor runs it. Use them as context managers to release workers.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Any

from rhi.errors import InvalidInput


class SerialExecutor:
    """Evaluate in this process."""

    name = "serial"
    workers = 1

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
        return [fn(x) for x in items]

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class PoolExecutor(SerialExecutor):
    """Local process pool (fork-server start method; ``workers`` defaults to the CPU count)."""

    name = "local"

    def __init__(self, workers: int | None = None) -> None:
        self.workers = workers or os.cpu_count() or 1
        if self.workers < 1:
            raise InvalidInput(f"workers: must be >= 1, got {workers}")
        self._pool: ProcessPoolExecutor | None = None

    def map(self, fn, items):
        items = list(items)
        if self.workers == 1 or len(items) <= 1:
            return [fn(x) for x in items]
        if self._pool is None:
            self._pool = ProcessPoolExecutor(self.workers, mp_context=get_context("forkserver"))
        chunk = max(1, -(-len(items) // (4 * self.workers)))
        return list(self._pool.map(fn, items, chunksize=chunk))

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None


def _ray_apply(fn, chunk):
    return [fn(x) for x in chunk]


class RayExecutor(SerialExecutor):
    """Ray tasks, one per chunk of items. ``address=None`` starts (or reuses) a local Ray instance."""

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None) -> None:
        try:
            import ray
        except ImportError:
            raise InvalidInput("executor: 'ray' needs the optional dependency ray (pip install ray)") from None
        self._ray = ray
        if not ray.is_initialized():
            kw: dict[str, Any] = {"address": address, "include_dashboard": False, "log_to_driver": False}
            if address is None:
                kw["num_cpus"] = workers or os.cpu_count() or 1
            ray.init(**kw)
            self._owner = True
        else:
            self._owner = False
        self.workers = int(ray.cluster_resources().get("CPU", 1))
        self._remote = ray.remote(_ray_apply)

    def map(self, fn, items):
        items = list(items)
        if not items:
            return []
        size = max(1, -(-len(items) // (4 * self.workers)))
        fn_ref = self._ray.put(fn)
        refs = [self._remote.remote(fn_ref, items[i:i + size]) for i in range(0, len(items), size)]
        return [y for part in self._ray.get(refs) for y in part]

    def close(self) -> None:
        if self._owner and self._ray.is_initialized():
            self._ray.shutdown()


def make_executor(name: str = "local", *, address: str | None = None, workers: int | None = None) -> SerialExecutor:
    """Executor by name: "serial", "local" (process pool) or "ray" (with `address`)."""
    if name == "serial":
        return SerialExecutor()
    if name == "local":
        return PoolExecutor(workers)
    if name == "ray":
        return RayExecutor(address, workers)
    raise InvalidInput(f"executor: expected 'serial', 'local' or 'ray', got {name!r}")


#: Process-wide defaults used when an experiment gets no executor (set by `configure`, e.g. from the CLI).
DEFAULTS: dict[str, Any] = {"executor": "local", "address": None, "workers": None, "checkpoint_dir": None}


def configure(*, executor: str | None = None, address: str | None = None, workers: int | None = None,
              checkpoint_dir: str | None = None) -> None:
    """Set the default executor ("serial", "local", "ray"), Ray address, workers and checkpoint folder."""
    if executor is not None:
        if executor not in ("serial", "local", "ray"):
            raise InvalidInput(f"executor: expected 'serial', 'local' or 'ray', got {executor!r}")
        DEFAULTS["executor"] = executor
    if address is not None:
        DEFAULTS["address"] = address
    if workers is not None:
        DEFAULTS["workers"] = workers
    if checkpoint_dir is not None:
        DEFAULTS["checkpoint_dir"] = checkpoint_dir


def default_executor() -> SerialExecutor:
    """A new executor from `DEFAULTS` (close it when done)."""
    return make_executor(DEFAULTS["executor"], address=DEFAULTS["address"], workers=DEFAULTS["workers"])
