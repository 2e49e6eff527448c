"""`ViewCommands`: the view's buttons and the run's status line, shared between the view's and the loop's process.

The browser's pause, resume and reset buttons act in the view's process; the run they act on is in the
loop's (`rhi.viz.session.supervise`). One small block of shared memory carries both ways: the pause
flag, a reset counter and a stop flag (view → loop) and a status line ("warming up …", "live", "paused", the fault's
kind, reason and time) with a change counter (loop → view). Every field is a single aligned int64 or a
bytes field published under a seqlock, so no lock is needed across processes.
"""

from __future__ import annotations

import time
from multiprocessing import shared_memory

import numpy as np

_TEXT = 480  # bytes of the status line


class ViewCommands:
    """Pause / reset requests from the view and the run's status line.

    Args:
        name: attach to an existing block (the other process's side); None: create one.

    Attributes:
        name: the shared-memory block's name (give it to the other process).
    """

    def __init__(self, name: str | None = None) -> None:
        self._owner = name is None
        self.shm = shared_memory.SharedMemory(name=name, create=self._owner, size=8 * 5 + _TEXT)
        # pause, resets, status seq, status len, stop
        self._i = np.ndarray((5,), dtype=np.int64, buffer=self.shm.buf)
        self._text = np.ndarray((_TEXT,), dtype=np.uint8, buffer=self.shm.buf, offset=40)
        if self._owner:
            self._i[:] = 0

    @property
    def name(self) -> str:
        """Name of the shared-memory block."""
        return self.shm.name

    # -------------------------------------------------- view → loop
    @property
    def paused(self) -> bool:
        """Whether the view asks the run to pause."""
        return bool(self._i[0])

    @paused.setter
    def paused(self, on: bool) -> None:
        self._i[0] = int(bool(on))

    @property
    def resets(self) -> int:
        """How many resets the view has asked for (compare with a count seen before)."""
        return int(self._i[1])

    def request_reset(self) -> None:
        """Ask the run to re-arm its safety layer and restart from its configuration's start (unpauses)."""
        self._i[0] = 0
        self._i[1] += 1

    @property
    def stopped(self) -> bool:
        """Whether the view asks the session to end (the run stops with zero torque and is not restarted)."""
        return bool(self._i[4])

    def request_stop(self) -> None:
        """Ask the session to end."""
        self._i[4] = 1

    # -------------------------------------------------- loop → view
    def set_status(self, text: str) -> None:
        """Publish the run's status line (truncated to 480 bytes of UTF-8)."""
        b = text.encode()[:_TEXT]
        self._i[2] += 1  # odd: writing
        self._text[: len(b)] = np.frombuffer(b, dtype=np.uint8)
        self._i[3] = len(b)
        self._i[2] += 1  # even: done

    def status(self) -> tuple[int, str]:
        """(change counter, status line): the counter grows with every `set_status`."""
        for k in range(10_000):
            s = int(self._i[2])
            text = bytes(self._text[: int(self._i[3])]).decode(errors="replace")
            if s % 2 == 0 and int(self._i[2]) == s:
                return s, text
            if k >= 10:  # the writer was descheduled in the middle of the line: let it finish
                time.sleep(1e-4)
        return s, text

    def __getstate__(self):  # pickled to the other process as a reference to the block
        return {"name": self.name}

    def __setstate__(self, state) -> None:
        type(self).__init__(self, state["name"])

    def close(self) -> None:
        """Detach (and free the block on the creating side); idempotent."""
        if self._text is None:
            return
        self._i = self._text = None  # type: ignore[assignment]  # release the views before the block
        self.shm.close()
        if self._owner:
            self.shm.unlink()
