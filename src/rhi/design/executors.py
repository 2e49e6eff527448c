"""Executors with one interface, ``map(fn, items) -> list``, for design evaluations.

* `SerialExecutor`: in-process loop (the baseline and the debugging path).
* `PoolExecutor`: a local process pool (default; ``workers`` processes, items sent in chunks).
* `RayExecutor`: the same map on a Ray cluster (``address=None`` starts a local instance,
  ``"auto"`` or ``"ray://host:10001"`` joins a running one). Needs the optional ``ray``.

All return results in the order of ``items``, so a seeded sweep or optimisation gives the
same numbers whichever executor runs it. Use them as context managers to release workers.
``imap`` yields the same results one by one as they finish (in order), for progress bars.

`parallel_map` is what experiments call: the given executor (or a name, or a worker count,
or the process-wide default of `configure`), a progress callback counted in work units,
and the default executor closed afterwards. Workspace maps (Figs 3.7–3.8, 7.5) send one
grid row per item, so each task carries enough work to hide the pool's overhead and the
IK warm start along a row is the same whichever process computes it.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Any

from rhi._lifetime import die_with_parent
from rhi.errors import InvalidInput, LinkError

RAY_CONNECT_TIMEOUT = 5.0
"""[s] How long `check_ray_address` waits for a Ray cluster's port to accept a connection."""


class SerialExecutor:
    """Evaluate in this process."""

    name = "serial"
    workers = 1

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
        """``[fn(x) for x in items]``, in this process."""
        return [fn(x) for x in items]

    def imap(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        """Results of fn over items, in order, yielded as they become available."""
        return (fn(x) for x in items)

    def close(self) -> None:
        """Nothing to release."""
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


#: Modules the fork server imports once, so that every pool worker forked from it starts warm
#: (NumPy, SciPy, Pinocchio and rhi's lower layers; a module that fails to import is skipped).
PRELOAD = ["rhi.design", "rhi.control"]


def _check_workers(workers) -> None:
    """`workers` must be None (the CPU count) or an integer >= 1."""
    if workers is not None and (not isinstance(workers, int) or isinstance(workers, bool) or workers < 1):
        raise InvalidInput(f"workers: expected an integer >= 1 (or None for the CPU count), got {workers!r}")


def _new_pool(workers: int) -> ProcessPoolExecutor:
    ctx = get_context("forkserver")
    ctx.set_forkserver_preload(PRELOAD)  # no effect once this process's fork server runs
    return ProcessPoolExecutor(workers, mp_context=ctx, initializer=die_with_parent, initargs=(os.getpid(),))


class PoolExecutor(SerialExecutor):
    """Local process pool (fork-server start method; ``workers`` defaults to the CPU count).

    Workers are forked from a fork server that has already imported `PRELOAD`, so starting
    a pool costs a fork per worker rather than a fresh interpreter's imports.
    """

    name = "local"

    def __init__(self, workers: int | None = None) -> None:
        _check_workers(workers)
        self.workers = workers or os.cpu_count() or 1
        self._pool: ProcessPoolExecutor | None = None

    def map(self, fn, items):
        """``[fn(x) for x in items]`` on the process pool, in chunks, in order."""
        items = list(items)
        if self.workers == 1 or len(items) <= 1:
            return [fn(x) for x in items]
        if self._pool is None:
            self._pool = _new_pool(self.workers)
        chunk = max(1, -(-len(items) // (4 * self.workers)))
        return list(self._pool.map(fn, items, chunksize=chunk))

    def imap(self, fn, items):
        """In-order results, one task per item (items should be coarse, e.g. a grid row each)."""
        items = list(items)
        if self.workers == 1 or len(items) <= 1:
            return (fn(x) for x in items)
        if self._pool is None:
            self._pool = _new_pool(self.workers)
        return self._pool.map(fn, items, chunksize=1)

    def close(self) -> None:
        """Shut the pool down, cancelling queued work."""
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)  # an interrupted map leaves no queued work behind
            self._pool = None


def check_ray_address(address: str | None) -> None:
    """Refuse, within `RAY_CONNECT_TIMEOUT`, a Ray address that is malformed or where nothing listens.

    Accepted: None (start a local instance), "auto" and "local", or ``host:port`` / ``ray://host:port`` whose
    TCP port accepts a connection (Ray's own client retries for minutes).

    Raises:
        InvalidInput: a malformed address. LinkError: nothing answers there.
    """
    import socket

    if address is None or address in ("auto", "local"):
        return
    if not isinstance(address, str):
        raise InvalidInput(f"address: expected a Ray address string, got {type(address).__name__}")
    hostport = address.removeprefix("ray://")
    host, sep, port = hostport.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536 or "/" in hostport:
        raise InvalidInput(f"address: expected 'auto', 'host:port' or 'ray://host:port' (port 1-65535), got {address!r}")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=RAY_CONNECT_TIMEOUT):
            pass
    except OSError as exc:
        raise LinkError(f"address: no Ray cluster answers at {address!r} ({exc.strerror or exc})") from None


def _ray_apply(fn, chunk):
    return [fn(x) for x in chunk]


class RayExecutor(SerialExecutor):
    """Ray tasks, one per chunk of items. ``address=None`` starts (or reuses) a local Ray instance."""

    name = "ray"

    def __init__(self, address: str | None = None, workers: int | None = None) -> None:
        _check_workers(workers)
        try:
            import ray
        except ImportError:
            raise InvalidInput("executor: 'ray' needs the optional dependency ray (pip install ray)") from None
        self._ray = ray
        if not ray.is_initialized():
            check_ray_address(address)
            kw: dict[str, Any] = {"address": address, "include_dashboard": False, "log_to_driver": False}
            if address is None:
                kw["num_cpus"] = workers or os.cpu_count() or 1
            try:
                ray.init(**kw)
            except (ConnectionError, ValueError, RuntimeError) as exc:  # "auto" with no cluster, a refused client
                raise LinkError(f"address: Ray cannot start or join {address or 'a local instance'!r}: "
                                f"{' '.join(str(exc).split())[:300]}") from None
            self._owner = True
        else:
            self._owner = False
        self.workers = int(ray.cluster_resources().get("CPU", 1))
        self._remote = ray.remote(_ray_apply)

    def map(self, fn, items):
        """``[fn(x) for x in items]`` as Ray tasks, in chunks, in order."""
        items = list(items)
        if not items:
            return []
        size = max(1, -(-len(items) // (4 * self.workers)))
        fn_ref = self._ray.put(fn)
        refs = [self._remote.remote(fn_ref, items[i:i + size]) for i in range(0, len(items), size)]
        return [y for part in self._ray.get(refs) for y in part]

    def imap(self, fn, items):
        """In-order results, one Ray task per item."""
        items = list(items)
        if not items:
            return iter(())
        fn_ref = self._ray.put(fn)
        refs = [self._remote.remote(fn_ref, [x]) for x in items]
        return (self._ray.get(r)[0] for r in refs)

    def close(self) -> None:
        """Shut down the Ray instance this executor started (not one it connected to)."""
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
    """Set the default executor ("serial", "local", "ray"), Ray address, workers and checkpoint folder.

    Raises:
        InvalidInput: an unknown executor, an address without executor "ray" or a malformed one, bad workers.
        LinkError: nothing answers at the Ray address (`check_ray_address`).
    """
    if executor is not None and executor not in ("serial", "local", "ray"):
        raise InvalidInput(f"executor: expected 'serial', 'local' or 'ray', got {executor!r}")
    kind = executor or DEFAULTS["executor"]
    if address is not None:
        if kind != "ray":
            raise InvalidInput(f"address: a Ray cluster address is for executor 'ray', not {kind!r}")
        check_ray_address(address)  # before any work, not at the first map
    if workers is not None:
        _check_workers(workers)
    new = {"executor": executor, "address": address, "workers": workers, "checkpoint_dir": checkpoint_dir}
    DEFAULTS.update({k: v for k, v in new.items() if v is not None})  # all checked first: nothing half set


def default_executor() -> SerialExecutor:
    """A new executor from `DEFAULTS` (close it when done)."""
    return make_executor(DEFAULTS["executor"], address=DEFAULTS["address"], workers=DEFAULTS["workers"])


_SHARED: list[SerialExecutor] = []


@contextlib.contextmanager
def shared() -> Iterator[SerialExecutor]:
    """Keep one default executor (`configure`) open for every `parallel_map` inside the block.

    A reproduction runs many maps; one pool for all of them starts its workers (and their
    imports and per-process caches) once instead of once per map. Results do not change.
    """
    ex = default_executor()
    _SHARED.append(ex)
    try:
        yield ex
    finally:
        _SHARED.pop()
        ex.close()


@contextlib.contextmanager
def using(executor: SerialExecutor | str | None = None, workers: int | None = None) -> Iterator[SerialExecutor]:
    """The executor to run on, closed on exit if this call created it.

    Args:
        executor: an executor object (used as is, left open), a name ("serial", "local",
            "ray"), or None: ``workers`` decides, else the `configure` default.
        workers: processes of a new local pool (1: serial); ignored when ``executor`` is an object.
    """
    if executor is not None and not isinstance(executor, str):
        if not callable(getattr(executor, "map", None)):
            raise InvalidInput(f"executor: expected an executor or a name, got {executor!r}")
        yield executor
        return
    if workers is not None and (not isinstance(workers, int) or workers < 1):
        raise InvalidInput(f"workers: must be a positive integer, got {workers!r}")
    if executor is not None:
        own = make_executor(executor, address=DEFAULTS["address"], workers=workers)
    elif workers is not None:
        own = SerialExecutor() if workers == 1 else PoolExecutor(workers)
    elif _SHARED:
        yield _SHARED[-1]  # the open default of `shared` (its owner closes it)
        return
    else:
        own = default_executor()
    try:
        yield own
    finally:
        own.close()


def parallel_map(
    fn: Callable[[Any], Any],
    items: Sequence[Any],
    *,
    executor: SerialExecutor | str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    units: Sequence[int] | None = None,
) -> list[Any]:
    """``[fn(x) for x in items]`` on an executor (see `using`), with progress.

    Args:
        fn: picklable function (module level, or a ``functools.partial`` of one).
        items: the work items, e.g. one grid row each.
        executor: where to run (an executor or its name; see `using`).
        workers: processes of a local pool (see `using`).
        progress: ``progress(done, total)`` after each finished item, counted in units.
        units: (len(items),) work units per item (e.g. grid points per row); default 1 each.

    Returns:
        Results in the order of items; identical on every executor when fn is deterministic.
    """
    items = list(items)
    units = [1] * len(items) if units is None else [int(u) for u in units]
    if len(units) != len(items):
        raise InvalidInput(f"units: expected {len(items)} values, got {len(units)}")
    total, done, out = sum(units), 0, []
    with using(executor, workers) as ex:
        it = ex.imap(fn, items) if hasattr(ex, "imap") else iter(ex.map(fn, items))
        for u, r in zip(units, it):
            out.append(r)
            done += u
            if progress:
                progress(done, total)
    return out
