"""The browser view in its own process, so that the control loop never shares Python's GIL with it.

A `View` thread in the loop's process holds the GIL while it draws (milliseconds per frame), and
a 1 kHz loop waking from its sleep then waits for it (up to the interpreter's 5 ms switch
interval): measured by `benchmarks/bench_view.py`, that multiplies the tick's p99. `RemoteView`
runs the view in a child process instead. The loop publishes into a `SharedTelemetry` (the
`rhi.runtime.Telemetry` interface, a seqlock over shared memory: one row copy per published
tick, no lock, no system call) and the mouse's hand target comes back through a
`SharedDraggableHand` (a `DraggableHand` whose target lives in shared memory).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import time
import types
import warnings
from multiprocessing import shared_memory
from multiprocessing.process import BaseProcess
from multiprocessing.synchronize import Event

import numpy as np

from rhi._lifetime import die_with_parent
from rhi.errors import InvalidInput, RhiError
from rhi.sim.hand import DraggableHand
from rhi.sim.log import layout
from rhi.viz.commands import ViewCommands

_FAULT_BYTES = 512


class SharedTelemetry:
    """`rhi.runtime.Telemetry` over shared memory: the loop's process writes, another process reads.

    Args:
        n, m, m_slave: the log layout's sizes (motors, task rows, slave rows), as `rhi.sim.log.layout`.
        every: publish one tick in `every`.
        name: attach to an existing block (the reader's side); None: create one (the writer's side).
    """

    def __init__(self, n: int, m: int, m_slave: int = 0, *, every: int = 10, name: str | None = None) -> None:
        if isinstance(every, bool) or not isinstance(every, int) or every < 1:
            raise InvalidInput(f"every: must be an integer >= 1, got {every!r}")
        self.columns = layout(n, m, m_slave)
        self.sizes = (n, m, m_slave)
        self.cols: dict = {}
        i = 0
        for c, w in self.columns:
            self.cols[c] = i if w == 1 else slice(i, i + w)
            i += w
        self.width = i
        size = 8 * (2 + self.width) + _FAULT_BYTES
        self._owner = name is None
        self.shm = shared_memory.SharedMemory(name=name, create=self._owner, size=size)
        buf = self.shm.buf
        self._seq = np.ndarray((1,), dtype=np.int64, buffer=buf, offset=0)
        self._flen = np.ndarray((1,), dtype=np.int64, buffer=buf, offset=8)
        self._row = np.ndarray((self.width,), dtype=np.float64, buffer=buf, offset=16)
        self._fault = np.ndarray((_FAULT_BYTES,), dtype=np.uint8, buffer=buf, offset=16 + 8 * self.width)
        if self._owner:
            self._seq[0] = 0
        self.every = every
        self.count = 0
        self._k = 0

    @property
    def name(self) -> str:
        """Name of the shared-memory block (give it to the reader's process)."""
        return self.shm.name

    def publish(self, row: np.ndarray, cols: dict, fault: str | None = None) -> None:
        """Offer the current log row (called by the loop every tick; `cols` must be the layout's)."""
        self._k += 1
        if self._k < self.every and fault is None:
            return
        self._k = 0
        self._seq[0] += 1  # odd: writing
        self._row[:] = row
        f = (fault or "").encode()[:_FAULT_BYTES]
        self._fault[: len(f)] = np.frombuffer(f, dtype=np.uint8)
        self._flen[0] = len(f) if fault is not None else -1
        self._seq[0] += 1  # even: done
        self.count += 1

    def latest(self) -> types.SimpleNamespace | None:
        """The newest snapshot (the `Telemetry.latest` attributes), or None before the first one.

        A read that meets the writer in the middle of a row is retried (a descheduled writer: for up to about a
        second), so that None means "nothing published yet".
        """
        for k in range(10_000):
            s1 = int(self._seq[0])
            if s1 == 0:
                return None
            row, flen = self._row.copy(), int(self._flen[0])
            fault = bytes(self._fault[:flen]).decode(errors="replace") if flen >= 0 else None
            if s1 % 2 == 0 and int(self._seq[0]) == s1:
                break
            if k >= 10:  # the writer was descheduled in the middle of a row (a loaded machine): let it finish
                time.sleep(1e-4)
        else:
            return None
        snap = {c: (float(row[i]) if isinstance(i, int) else row[i]) for c, i in self.cols.items()}
        snap["fault"] = fault
        snap["safety"] = "fault" if (fault is not None or snap.get("safety", 0.0) == 1.0) else "ok"
        return types.SimpleNamespace(**snap)

    def close(self) -> None:
        """Detach (and free the block on the creating side); idempotent."""
        if self._row is None:
            return
        # the views on the block must be released before it is closed; None also marks the reader closed
        self._seq = self._flen = self._row = self._fault = None  # type: ignore[assignment]
        self.shm.close()
        if self._owner:
            self.shm.unlink()


class SharedDraggableHand(DraggableHand):
    """A `DraggableHand` whose target lives in shared memory: moved in the view's process, felt in the loop's.

    Args:
        m: task dimension.
        name: attach to an existing block; None: create one.
        **kw: stiffness, damping, max_force as `DraggableHand`.
    """

    def __init__(self, m: int, *, name: str | None = None, **kw) -> None:
        super().__init__(**kw)
        self.m = int(m)
        self._owner = name is None
        self.shm = shared_memory.SharedMemory(name=name, create=self._owner, size=8 * (1 + self.m))
        self._buf = np.ndarray((1 + self.m,), dtype=np.float64, buffer=self.shm.buf)
        if self._owner:
            self._buf[:] = np.nan

    @property
    def name(self) -> str:
        """Name of the shared-memory block (give it to the other process)."""
        return self.shm.name

    @property
    def target(self) -> np.ndarray | None:
        """The hand's target position (m,) [m] set by the mouse, or None."""
        b = self._buf
        return None if b[0] != b[0] else b[1:].copy()  # NaN flag: no target

    @target.setter
    def target(self, x) -> None:
        if x is None:
            self._buf[0] = np.nan
            return
        x = np.asarray(x, dtype=float)
        if x.shape != (self.m,) or not np.all(np.isfinite(x)):
            raise InvalidInput(f"target: expected {self.m} finite coordinates, got {np.asarray(x).tolist()}")
        self._buf[0] = np.nan  # invalid while the coordinates change
        self._buf[1:] = x
        self._buf[0] = 1.0

    def __getstate__(self):  # pickled to the view's process as a reference to the block
        return {"m": self.m, "name": self.name, "kw": dict(stiffness=self.stiffness, damping=self.damping,
                                                          max_force=self.max_force)}

    def __setstate__(self, state) -> None:
        type(self).__init__(self, state["m"], name=state["name"], **state["kw"])

    def close(self) -> None:
        """Detach (and free the block on the creating side); idempotent."""
        if self._buf is None:
            return
        self._buf = None  # type: ignore[assignment]  # release the view before closing the block; None marks closed
        self.shm.close()
        if self._owner:
            self.shm.unlink()


def _serve(device, tel_name: str, sizes, hand, kw: dict, cpus, ready, stop) -> None:
    from rhi.viz.view import View

    die_with_parent()  # a killed `rhi run --view` or `rhi view` takes its view with it

    if cpus:
        try:
            os.sched_setaffinity(0, cpus)
        except (OSError, AttributeError, ValueError) as exc:
            warnings.warn(f"view: CPU affinity {sorted(cpus)} not applied ({exc})", RuntimeWarning, stacklevel=1)

    tel = SharedTelemetry(*sizes, name=tel_name)
    view = View(device, tel, hand=hand, **kw).start()
    ready.put(view.port)
    stop.wait()
    view.close()
    tel.close()
    kw["commands"].close()
    if hand is not None:
        hand.close()


def spawn_view(target, args: tuple, *, name: str, timeout: float = 180.0) -> tuple[BaseProcess, Event, int]:
    """Start a view's child process, `target(*args, ready, stop)`, and wait until it serves.

    The child (spawned, a daemon that calls `die_with_parent`) puts its port on `ready` once it serves and
    closes when `stop` is set. Used by `ViewProcess` (`RemoteView`, `rhi.viz.compare.RemoteCompare`).

    Args:
        target: the child's function.
        args: its arguments before `ready` and `stop`.
        name: the child's process name.
        timeout: how long the child may take to serve [s] (it imports viser and builds the scene).

    Returns:
        (the process, its stop event, the port it serves on).

    Raises:
        RhiError: the child ended before serving, or did not serve within `timeout` (it is ended first).
    """
    ctx = mp.get_context("spawn")
    ready, stop = ctx.Queue(), ctx.Event()
    process = ctx.Process(target=target, args=(*args, ready, stop), daemon=True, name=name)
    process.start()
    try:
        return process, stop, _port_when_ready(ready, process, timeout)
    except BaseException:
        end_view(process, stop)
        raise


#: [s] how long a view's child process may take to close before it is ended (it holds nothing to save)
CLOSE_WAIT = 5.0


def end_view(process: BaseProcess, stop: Event) -> None:
    """Ask a view's child process to close (`stop`), and end it where it does not within `CLOSE_WAIT`."""
    stop.set()
    process.join(CLOSE_WAIT)
    if process.is_alive():
        process.terminate()
        process.join(5)


def _port_when_ready(ready, process, timeout: float) -> int:
    """The port the view's `process` puts on `ready`; an RhiError at once if the process ends first."""
    import queue
    import time

    end = time.monotonic() + timeout
    while True:
        try:
            return int(ready.get(timeout=0.25))
        except queue.Empty:
            if not process.is_alive():
                raise RhiError(f"view: its process ended before serving (exit code {process.exitcode}); "
                               "the reason is printed above") from None
            if time.monotonic() > end:
                raise RhiError(f"view: its process did not serve within {timeout:g} s") from None


class ViewProcess:
    """A page served from a child process (`spawn_view`): its address and its closing.

    Subclasses set `hand` (a `SharedDraggableHand` or None), call `_spawn` last in ``__init__`` and name the shared
    memory they hold in `_shared`; `close` frees it all (the hand's too).

    Attributes:
        port: the port the page listens on.
    """

    hand: SharedDraggableHand | None

    def _spawn(self, target, args: tuple, name: str) -> None:
        """Start the page's process, `target(*args, ready, stop)` (`spawn_view`); on failure, `close` and raise."""
        try:
            self.process, self._stop, self.port = spawn_view(target, args, name=name)
        except Exception:
            self.close()
            raise

    def _shared(self) -> list:
        """The shared-memory objects to close with the page (telemetries, commands)."""
        raise NotImplementedError

    @property
    def url(self) -> str:
        """The page's address in a browser."""
        return f"http://127.0.0.1:{self.port}"

    def request_close(self) -> None:
        """Ask the page's process to close, without waiting (`close` waits and frees the shared memory)."""
        if hasattr(self, "_stop"):
            self._stop.set()

    def close(self) -> None:
        """Stop the page's process and free the shared memory (the hand's too)."""
        if hasattr(self, "process"):
            end_view(self.process, self._stop)
        for shared in self._shared():
            shared.close()
        if self.hand is not None:
            self.hand.close()


class RemoteView(ViewProcess):
    """A `View` in a child process, fed by a `SharedTelemetry` (give `telemetry` to `run`/`simulate`).

    Args:
        device: the device drawn.
        hand: a `SharedDraggableHand` for the mouse (created by the caller, who gives it to the simulated
            link; `close` frees it), or None.
        m_slave: slave rows of a teleoperation log (0 otherwise).
        every: publish one tick in `every` (10 at 1 kHz: 100 snapshots per second).
        cpus: CPUs the view's process may run on (e.g. all but the control loop's), or None (any).
        **kw: the `View` options (virtual, fme, q0, host, port, fps, lp_every).

    Attributes:
        telemetry: the `SharedTelemetry` the loop publishes into.
        commands: the view's pause / reset requests and the run's status line (`rhi.viz.session.supervise`).
        port: the port the view listens on.
    """

    def __init__(self, device, *, hand: SharedDraggableHand | None = None, m_slave: int = 0, every: int = 10,
                 cpus: set[int] | None = None, **kw) -> None:
        if hand is not None and not isinstance(hand, SharedDraggableHand):
            raise InvalidInput("hand: a view in another process needs a SharedDraggableHand")
        self.hand = hand
        self.telemetry = SharedTelemetry(device.n, device.m, m_slave, every=every)
        self.commands = kw["commands"] = ViewCommands()
        self._spawn(_serve, (device, self.telemetry.name, self.telemetry.sizes, hand, kw, cpus), "rhi-view")

    def _shared(self) -> list:
        return [self.telemetry, self.commands]
