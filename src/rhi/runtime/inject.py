"""Fault injection: a link wrapper that corrupts readings on schedule, to test a safety configuration.

```python
link = Inject(SimLink(plant, hand=hand), freeze=(0.5, 0.6))   # encoders and F/T frozen 100 ms
res = run(link, controller, realtime=False)                    # → a "stale" fault at t = 0.503 s
link = Inject(SimLink(plant, hand=hand), frozen=(0.5, 0.8))   # values frozen, sequence numbers advancing
res = run(link, controller, realtime=False)                    # → a "frozen" fault (SafetyConfig.frozen_ticks)
```
"""

from __future__ import annotations

import collections
import dataclasses
import math

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput, LinkError
from rhi.runtime.link import DeviceLink, Reading


def _window(name: str, w) -> tuple[float, float] | None:
    if w is None:
        return None
    try:
        a, b = (float(v) for v in w)
    except (TypeError, ValueError):
        raise InvalidInput(f"{name}: expected (start, end) [s], got {w!r}") from None
    if not (math.isfinite(a) and a >= 0 and b > a):
        raise InvalidInput(f"{name}: expected 0 <= start < end [s], got {w!r}")
    return a, b


class Inject:
    """Wrap a link and corrupt its readings inside device-time windows (start, end) [s].

    Args:
        link: the link to wrap.
        freeze: the reading (sequence number and values) stops changing, as a hung sensor driver.
        frozen: the values (q, q̇, sensors) stop changing while the sequence number and time advance, as a
            device that keeps sending its last sample.
        nan: the F/T sensor reads NaN.
        reorder_at: at this time, return the reading from two samples earlier once (an out-of-order packet).
        silence: read() raises `LinkError` (the device went away).
        delay: a constant link delay [s]: each reading is the one taken `delay` earlier, its `age` (round trip)
            that delay plus one period, as a UDP link measures it.
    """

    def __init__(self, link: DeviceLink, *, freeze=None, frozen=None, nan=None, reorder_at: float | None = None,
                 silence=None, delay: float | None = None) -> None:
        self.link = link
        self.n = link.n
        self.rate = getattr(link, "rate", None)
        self.session = getattr(link, "session", None)
        self.freeze, self.nan, self.silence = _window("freeze", freeze), _window("nan", nan), _window("silence", silence)
        self.frozen = _window("frozen", frozen)
        self._values: Reading | None = None
        self.reorder_at = reorder_at
        self.delay = None if delay is None else scalar("delay", delay, nonnegative=True)
        self._past: collections.deque[Reading] = collections.deque()
        self._held: Reading | None = None
        self._hist: list[Reading] = []
        self._reordered = False

    @staticmethod
    def _in(w, t: float) -> bool:
        return w is not None and w[0] <= t < w[1]

    def open(self) -> None:
        """Open the wrapped link."""
        self.link.open()

    def read(self) -> Reading:
        """The wrapped link's reading, corrupted as scheduled (silence, freeze, NaN, reorder...)."""
        r = self.link.read()
        if self.delay is not None:
            self._past.append(r)
            while len(self._past) > 1 and self._past[1].t <= r.t - self.delay:
                self._past.popleft()
            then = self._past[0]
            r = dataclasses.replace(then, age=r.t - then.t + 1.0 / (self.rate or 1000.0))
        if self._in(self.silence, r.t):
            raise LinkError(f"no reading (injected silence at t={r.t:.4f} s)")
        old = self._hist[0] if len(self._hist) == 2 else None
        self._hist = (self._hist + [r])[-2:]
        if self._in(self.freeze, r.t):
            self._held = self._held or r
            return self._held
        self._held = None
        if self._in(self.frozen, r.t):
            self._values = self._values or r
            return dataclasses.replace(r, q=self._values.q, dq=self._values.dq, sensors=self._values.sensors)
        self._values = None
        if self.reorder_at is not None and r.t >= self.reorder_at and not self._reordered and old is not None:
            self._reordered = True
            return old
        if self._in(self.nan, r.t):
            s = dict(r.sensors)
            s["ft"] = np.full(6, np.nan)
            return dataclasses.replace(r, sensors=s)
        return r

    def write(self, tau, *, enable: bool) -> None:
        """Pass the command through to the wrapped link."""
        self.link.write(tau, enable=enable)

    def close(self) -> None:
        """Close the wrapped link."""
        self.link.close()
