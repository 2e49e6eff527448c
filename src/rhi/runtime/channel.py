"""A teleoperation channel with one-way delay, jitter and packet loss, in-process or over UDP.

Both ends exchange small vectors (a position, a force, cumulative energies). Each packet's
delay is `delay` plus a uniform draw in [0, `jitter`], and it is lost with probability `loss`;
the draws come from a seeded generator, so a schedule is reproducible. A receiver keeps the
newest packet by sequence number (a late packet never overwrites a newer one).

- `DelayLine` + `LocalEnd`: ticks of a lock-step simulation (delays rounded up to whole ticks).
- `schedule` + `ScheduledEnd`: the same lock-step channel with every packet's arrival drawn up front (which
  packet each end sees at each tick), for the compiled bilateral loop.
- `UDPEnd`: two processes on UDP; the delay is applied by the sender on the wall clock.
"""

from __future__ import annotations

import dataclasses
import heapq
import math
import socket
import struct
import time

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput

_MAGIC, _VERSION = b"RHIT", 1
_HEAD = struct.Struct("<4sHHId")  # magic, version, count, seq, t_send [s]; + count × f64


@dataclasses.dataclass(frozen=True)
class ChannelConfig:
    """Network conditions of one direction of the channel.

    Attributes:
        delay: constant one-way delay [s] (>= 0).
        jitter: extra delay drawn uniformly in [0, jitter] per packet [s] (>= 0).
        loss: probability that a packet is lost, in [0, 1).
        seed: seed of the delay/loss draws.
    """

    delay: float = 0.0
    jitter: float = 0.0
    loss: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for f in ("delay", "jitter"):
            scalar(f, getattr(self, f), nonnegative=True)
        if isinstance(self.loss, bool) or not isinstance(self.loss, (int, float)) or not 0 <= self.loss < 1:
            raise InvalidInput(f"loss: must be a probability in [0, 1), got {self.loss!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise InvalidInput(f"seed: expected an integer, got {self.seed!r}")

    @classmethod
    def from_dict(cls, d: dict) -> ChannelConfig:
        """From a mapping (e.g. a TOML table); unknown keys are refused by name."""
        names = {f.name for f in dataclasses.fields(cls)}
        bad = sorted(set(d) - names) if isinstance(d, dict) else None
        if bad is None or bad:
            raise InvalidInput(f"channel: unknown option(s) {bad}; known: {sorted(names)}")
        return cls(**d)


class DelayLine:
    """One direction of a lock-step channel: packets sent at tick k arrive at tick k + ⌈delay/dt⌉."""

    def __init__(self, config: ChannelConfig, dt: float) -> None:
        self.config, self.dt = config, float(dt)
        self._rng = np.random.default_rng(config.seed)
        self._queue: list[tuple[int, int, np.ndarray]] = []
        self.sent = self.lost = 0

    def send(self, tick: int, seq: int, values: np.ndarray) -> None:
        """Queue `values` sent at `tick`: delivered after the delay and jitter, or lost."""
        c = self.config
        self.sent += 1
        extra = self._rng.uniform(0.0, c.jitter) if c.jitter > 0 else 0.0
        if c.loss > 0 and self._rng.random() < c.loss:
            self.lost += 1
            return
        due = tick + math.ceil((c.delay + extra) / self.dt - 1e-9)
        heapq.heappush(self._queue, (due, seq, np.array(values, dtype=float)))

    def arrived(self, tick: int) -> list[tuple[int, np.ndarray]]:
        """The packets due by `tick`: [(seq, values)], in delivery order."""
        out = []
        while self._queue and self._queue[0][0] <= tick:
            _, seq, v = heapq.heappop(self._queue)
            out.append((seq, v))
        return out


class LocalEnd:
    """One end of a lock-step channel: sends on `out`, receives from `inp`; call `tick()` once per tick first."""

    def __init__(self, out: DelayLine, inp: DelayLine) -> None:
        self.out, self.inp = out, inp
        self._k = -1
        self._seq = 0
        self._best: tuple[int, np.ndarray] | None = None

    def tick(self) -> None:
        """Advance one tick and keep the newest packet that arrived."""
        self._k += 1
        for seq, v in self.inp.arrived(self._k):
            if self._best is None or seq > self._best[0]:
                self._best = (seq, v)

    def send(self, values: np.ndarray) -> None:
        """Send `values` to the other end (through the channel's delay, jitter and loss)."""
        self._seq += 1
        self.out.send(self._k, self._seq, values)

    def latest(self) -> np.ndarray | None:
        """The newest packet received so far (None before the first)."""
        return None if self._best is None else self._best[1]


def local_pair(forward: ChannelConfig, backward: ChannelConfig, dt: float) -> tuple[LocalEnd, LocalEnd]:
    """(master end, slave end) of a lock-step channel."""
    f, b = DelayLine(forward, dt), DelayLine(backward, dt)
    return LocalEnd(f, b), LocalEnd(b, f)


def schedule(config: ChannelConfig, dt: float, ticks: int, *, lag: int = 0) -> np.ndarray:
    """Which packet the receiver of a `DelayLine` sees at each tick, the sender sending one packet per tick.

    The draws of `DelayLine.send` (jitter, then loss, from the same seeded generator) for packets 0 .. ticks − 1,
    packet s sent at tick s; the receiver keeps the newest packet arrived (`LocalEnd`).

    Args:
        config: the direction's conditions.
        dt: the tick [s].
        ticks: N, the ticks of the run.
        lag: 1 where the receiver ticks before the sender within a tick (a packet due at its own tick is seen
            one tick later), else 0.

    Returns:
        (N,) int64: the index of the newest packet the receiver holds at tick k, −1 before the first.
    """
    c = config
    per = int(c.jitter > 0) + int(c.loss > 0)
    draws = np.random.default_rng(c.seed).random(per * ticks).reshape(ticks, per)
    extra = c.jitter * draws[:, 0] if c.jitter > 0 else np.zeros(ticks)
    sent = np.arange(ticks)
    due = np.maximum(sent + np.ceil((c.delay + extra) / float(dt) - 1e-9).astype(np.int64), sent + lag)
    ok = due < ticks if c.loss == 0 else (due < ticks) & (draws[:, -1] >= c.loss)
    seen = np.full(ticks, -1, dtype=np.int64)
    np.maximum.at(seen, due[ok], sent[ok])
    return np.maximum.accumulate(seen)


class ScheduledEnd:
    """One end of a lock-step channel on a `schedule`: the packets of both ends kept in two (N, width) arrays.

    Args:
        out: (N, width) the packets this end sends (row k: the packet of tick k), written.
        inp: (N, width) the packets the other end sends.
        seen: (N,) int64 this end's `schedule` of `inp`.
    """

    def __init__(self, out: np.ndarray, inp: np.ndarray, seen: np.ndarray) -> None:
        self.out, self.inp, self.seen = out, inp, seen
        self.k = -1  # the current tick

    def tick(self) -> None:
        """Advance one tick."""
        self.k += 1

    def send(self, values: np.ndarray) -> None:
        """Send `values` (width,) to the other end."""
        self.out[self.k] = values

    def latest(self) -> np.ndarray | None:
        """The newest packet received so far (None before the first)."""
        i = self.seen[self.k]
        return None if i < 0 else self.inp[i]


class UDPEnd:
    """One end of the channel between two processes: binds `port` on `host`, sends to `peer` (host, port).

    The sender holds each packet for its drawn delay (on the monotonic clock) and sends it when due;
    call `tick()` every control tick (it sends what is due and receives what arrived).
    """

    def __init__(self, config: ChannelConfig, *, port: int = 0, host: str = "127.0.0.1", peer=None) -> None:
        self.config = config
        self._rng = np.random.default_rng(config.seed)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, int(port)))
        except (OSError, ValueError, OverflowError) as exc:
            raise InvalidInput(f"port: cannot bind {host}:{port}: {exc}") from None
        self.sock.setblocking(False)
        self.port = self.sock.getsockname()[1]
        self.peer = peer
        self._queue: list[tuple[float, int, bytes]] = []
        self._seq = 0
        self._best: tuple[int, np.ndarray] | None = None
        self.stats = {"sent": 0, "lost": 0, "received": 0, "late": 0}

    def tick(self) -> None:
        """Send the datagrams that are due and keep the newest one received."""
        now = time.monotonic()
        while self._queue and self._queue[0][0] <= now and self.peer is not None:
            _, _, pkt = heapq.heappop(self._queue)
            try:
                self.sock.sendto(pkt, self.peer)
            except OSError:
                pass  # the peer is gone; its silence is the receiver's to detect
        while True:
            try:
                pkt, addr = self.sock.recvfrom(65536)
            except (BlockingIOError, OSError):
                break
            if len(pkt) < _HEAD.size or pkt[:4] != _MAGIC:
                continue
            magic, ver, count, seq, _ = _HEAD.unpack_from(pkt)
            if ver != _VERSION or len(pkt) != _HEAD.size + 8 * count:
                continue
            if self.peer is None:
                self.peer = addr
            self.stats["received"] += 1
            if self._best is None or seq > self._best[0]:
                self._best = (seq, np.frombuffer(pkt, "<f8", count, _HEAD.size).astype(float))
            else:
                self.stats["late"] += 1

    def send(self, values: np.ndarray) -> None:
        """Send `values` to the peer after the configured delay and jitter (or drop it, at the loss rate)."""
        c = self.config
        self._seq += 1
        self.stats["sent"] += 1
        if c.loss > 0 and self._rng.random() < c.loss:
            self.stats["lost"] += 1
            return
        v = np.ascontiguousarray(values, dtype="<f8")
        pkt = _HEAD.pack(_MAGIC, _VERSION, len(v), self._seq, time.monotonic()) + v.tobytes()
        due = time.monotonic() + c.delay + (self._rng.uniform(0.0, c.jitter) if c.jitter > 0 else 0.0)
        heapq.heappush(self._queue, (due, self._seq, pkt))

    def latest(self) -> np.ndarray | None:
        """The newest packet received so far (None before the first)."""
        return None if self._best is None else self._best[1]

    def close(self) -> None:
        """Close the socket."""
        self.sock.close()
