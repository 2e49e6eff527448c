"""Child processes that die with their parent: no worker or view outlives the command that started it.

`die_with_parent` is called first thing in every child rhi starts (pool workers, the browser view's
process). On Linux the kernel sends the child SIGKILL when its parent goes (``prctl(PR_SET_PDEATHSIG)``,
also when the parent itself was killed with SIGKILL); everywhere, a daemon thread polls for the
process that started it and ends the child once it is gone.

`STOP_SIGNALS` keeps a stop signal from being lost: the `rhi` command turns SIGTERM and SIGHUP outside a run's
loop into a KeyboardInterrupt, which Python ignores where it lands in a finaliser or a weakref callback (Numba
runs such callbacks while it compiles); the command records the signal there, and a run that starts after it
e-stops at once (`rhi.runtime.run`).
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

PR_SET_PDEATHSIG = 1
#: The stop signals (names, e.g. "SIGTERM") the running `rhi` command received outside a run's loop.
STOP_SIGNALS: list[str] = []
#: How often the portable watcher looks for the parent [s].
POLL = 0.5


def _watch(pid: int) -> None:
    while True:
        time.sleep(POLL)
        if not _alive(pid):
            os._exit(1)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # the pid now belongs to another user's process: ours is gone
        return False
    return True


def die_with_parent(pid: int | None = None) -> None:
    """Make this process exit when the process `pid` (default: its parent) exits, however it ends.

    Args:
        pid: the process whose death ends this one (e.g. the main process of a pool whose workers are
            forked by a fork server); None: the parent.
    """
    parent = os.getppid()
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent or os.getppid() == 1 or not _alive(parent if pid is None else pid):
        os._exit(1)  # the parent went before the kernel was told to watch it
    threading.Thread(target=_watch, args=(parent if pid is None else pid,), daemon=True,
                     name="rhi-parent-watch").start()
