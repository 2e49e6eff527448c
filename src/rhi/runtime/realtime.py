"""The real-time settings of a loop's thread and how it waits: CPU affinity, SCHED_FIFO, the GC, idle states, spinning.

`realtime_thread` applies them around a loop (`rhi.runtime.run`, `rhi.runtime.server.DeviceServer`);
`wait_until` and `wait_readable` wait for a deadline or a datagram, asleep or on a busy core; `spin_rest`
says which waits a spinning SCHED_FIFO loop sleeps to stay clear of the kernel's real-time throttling.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
import math
import os
import select
import struct
import time
import warnings
from collections.abc import Iterator

from rhi.errors import InvalidInput

#: Linux's PM QoS file: while a process holds it open with a value written, no core enters an idle state
#: whose wake-up takes longer than that value [µs] (Documentation/power/pm_qos_interface.rst).
CPU_LATENCY_FILE = "/dev/cpu_dma_latency"


def check_realtime(cpu: int | None, priority: int | None, cpu_latency: float | None = None) -> None:
    """Validate the real-time options of `run` and `DeviceServer`.

    Raises:
        InvalidInput: `cpu` not a CPU index >= 0, `priority` not a SCHED_FIFO priority in 1..99, or
            `cpu_latency` not a number of seconds in [0, 1].
    """
    if cpu_latency is not None and (isinstance(cpu_latency, bool) or not isinstance(cpu_latency, (int, float))
                                    or not 0.0 <= cpu_latency <= 1.0):
        raise InvalidInput(f"cpu_latency: expected seconds in [0, 1] or None, got {cpu_latency!r}")
    if cpu is not None and (isinstance(cpu, bool) or not isinstance(cpu, int) or cpu < 0):
        raise InvalidInput(f"cpu: expected a CPU index >= 0 or None, got {cpu!r}")
    if priority is not None and (isinstance(priority, bool) or not isinstance(priority, int)
                                 or not 1 <= priority <= 99):
        raise InvalidInput(f"priority: expected a SCHED_FIFO priority in 1..99 or None, got {priority!r}")


def _hold_cpu_latency(latency: float | None, notes: list[str]) -> int | None:
    """A PM QoS request that no core's wake-up take longer than `latency` [s], as an open descriptor (None: none)."""
    if latency is None:
        return None
    try:
        fd = os.open(CPU_LATENCY_FILE, os.O_WRONLY)
    except OSError as exc:
        notes.append(f"CPU latency request of {latency * 1e6:g} µs not applied ({exc}); it needs write access to "
                     f"{CPU_LATENCY_FILE} (root); cores may sleep deeply between ticks and wake with cold caches")
        return None
    try:
        os.write(fd, struct.pack("i", round(latency * 1e6)))
    except OSError as exc:
        os.close(fd)
        notes.append(f"CPU latency request of {latency * 1e6:g} µs not applied ({exc})")
        return None
    return fd


@contextlib.contextmanager
def realtime_thread(cpu: int | None, priority: int | None, cpu_latency: float | None = None) -> Iterator[list[str]]:
    """GC frozen and off; optional CPU affinity, SCHED_FIFO priority and CPU latency request; 1 µs timer slack.

    `cpu_latency` [s]: held for the loop, a PM QoS request (`CPU_LATENCY_FILE`) that keeps every core out of
    idle states that take longer to leave (0: none beyond polling), so a loop that sleeps between ticks does
    not wake on a core whose caches a deep idle state flushed. Yields the warnings.
    """
    notes: list[str] = []
    gc.collect()
    gc.freeze()
    was = gc.isenabled()
    gc.disable()
    old_aff = old_sched = None
    if cpu is not None:
        try:
            old_aff = os.sched_getaffinity(0)
            os.sched_setaffinity(0, {int(cpu)})
        except (OSError, AttributeError, ValueError) as exc:
            notes.append(f"CPU affinity {cpu} not applied ({exc}); the loop may migrate between cores")
    if priority is not None:
        try:
            old_sched = (os.sched_getscheduler(0), os.sched_getparam(0))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(int(priority)))
        except (OSError, AttributeError) as exc:
            old_sched = None
            notes.append(f"real-time priority {priority} not applied ({exc}); grant CAP_SYS_NICE or an rtprio "
                         "limit (/etc/security/limits.conf) to run the loop under SCHED_FIFO")
    qos = _hold_cpu_latency(cpu_latency, notes)
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).prctl(29, 1000)  # PR_SET_TIMERSLACK: 1 µs, so sleeps end on time
    for msg in notes:
        warnings.warn(msg, RuntimeWarning, stacklevel=4)
    try:
        yield notes
    finally:
        if qos is not None:
            os.close(qos)  # the request ends with its descriptor
        if old_sched is not None:
            with contextlib.suppress(OSError):
                os.sched_setscheduler(0, old_sched[0], old_sched[1])
        if old_aff is not None:
            with contextlib.suppress(OSError):
                os.sched_setaffinity(0, old_aff)
        gc.unfreeze()
        if was:
            gc.enable()


def rt_throttled() -> bool:
    """Whether Linux throttles real-time tasks (kernel.sched_rt_runtime_us ≠ -1)."""
    try:
        with open("/proc/sys/kernel/sched_rt_runtime_us") as f:
            return int(f.read()) >= 0
    except (OSError, ValueError):
        return False


class SpinRest:
    """The sleep a spinning SCHED_FIFO loop owes the kernel, taken as whole waits rather than a slice of each.

    Linux stops a real-time thread busy for more than 95 % of a second for the rest of it (`rt_throttled`), so
    a spinning loop must sleep some of its waits. A sleep hands the core to other work, which evicts the caches
    and predictors the next tick runs from: asleep 100 µs cost the next step as much as asleep 900 µs
    (`benchmarks/bench_runtime_parts.py`), so a short sleep before every wait leaves every tick cold. Here the
    waits slept are whole ones, as few as keep at least `share` of each half second asleep: one tick in a dozen
    or so wakes cold instead of each.

    Args:
        share: the least share of the time asleep (0: never asleep).
    """

    WINDOW = 0.5  # [s]

    def __init__(self, share: float = 0.0) -> None:
        self.share = share
        self._t0 = -math.inf
        self._slept = 0.0

    def due(self, now: float) -> bool:
        """Whether the wait that begins at the monotonic time `now` [s] is slept (then tell `slept` how long)."""
        if self.share <= 0.0:
            return False
        if now - self._t0 > self.WINDOW:
            self._t0, self._slept = now, 0.0
        return self._slept < self.share * (now - self._t0)

    def slept(self, seconds: float) -> None:
        """A wait was slept for `seconds` [s]."""
        self._slept += seconds


def spin_rest(spin: bool) -> SpinRest:
    """The sleeps of a spinning loop in this thread (`SpinRest`).

    8 % of the time under a SCHED_FIFO priority that the kernel throttles (`kernel.sched_rt_runtime_us`: a
    real-time thread busy for more than 95 % of a second is stopped for the other 50 ms), else none.
    """
    try:
        fifo = os.sched_getscheduler(0) == os.SCHED_FIFO
    except (AttributeError, OSError):
        fifo = False
    return SpinRest(0.08 if spin and fifo and rt_throttled() else 0.0)


def wait_until(deadline: float, spin: bool = False, rest: SpinRest | None = None) -> None:
    """Return at the monotonic time `deadline` [s]: asleep, the last 50 µs spinning; `spin`: spinning throughout.

    `rest`: with `spin`, the waits it says are due are slept instead (`spin_rest`). Spinning keeps the core
    out of its idle state and to this thread, so the tick that follows finds its caches warm (and, on a
    virtual machine, does not wait for the hypervisor to wake it); it costs that core at 100 % (docs/runtime.md
    has the measured effect).
    """
    now = time.monotonic()
    if spin and rest is not None and rest.due(now):
        wait_until(deadline)
        rest.slept(time.monotonic() - now)
        return
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return
        if left > 5e-5 and not spin:
            time.sleep(left - 5e-5)


def wait_readable(sock, timeout: float, spin: bool = False) -> bool:
    """Whether `sock` has a datagram waiting, waiting up to `timeout` [s] for one (`spin`: on a busy core)."""
    if not spin:
        return bool(select.select([sock], [], [], timeout)[0])
    end = time.monotonic() + timeout
    while not select.select([sock], [], [], 0.0)[0]:
        if time.monotonic() >= end:
            return False
    return True
