"""`UDPLink`: the control host's side of the rhi device protocol (docs/protocol.md) over UDP."""

from __future__ import annotations

import socket
import time
import urllib.parse

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput, LinkError
from rhi.runtime import protocol as P
from rhi.runtime.link import Reading
from rhi.runtime.loop import wait_readable


def parse_url(url: str) -> tuple[str, int]:
    """``udp://HOST:PORT`` → (host, port).

    Raises:
        InvalidInput: anything else, naming `link`.
    """
    try:
        u = urllib.parse.urlsplit(str(url))
        host, port = u.hostname, u.port
    except ValueError as exc:
        raise InvalidInput(f"link: cannot parse {url!r} as udp://HOST:PORT ({exc})") from None
    if u.scheme != "udp" or not host or port is None or port == 0 or u.path not in ("", "/"):
        raise InvalidInput(f"link: expected udp://HOST:PORT (e.g. udp://127.0.0.1:5005), got {url!r}")
    return host, port


class UDPLink:
    """A device process reached over UDP (e.g. `rhi device-server`, or a lab's own driver).

    Args:
        host, port: the device's address.
        rate: the control rate [Hz]; must equal the device's.
        timeout: longest wait for a new reading in `read` [s]; after it the previous reading is returned
            again (the safety layer counts it as stale).
        connect_timeout: longest wait for the device's INFO answer in `open` [s].
        spin: wait for readings on a busy core, never asleep (`rhi.runtime.loop.wait_until`).

    Attributes:
        n: motors; sensors: [(name, width)] the device reports; info: the device's description.
        stats: datagram counts: sent, received, lost (gaps in the reading sequence), reordered, invalid, skipped
            (readings superseded before the host read them: device periods the host missed).

    Timing: with ``run(..., realtime=False)`` the host is paced by the device — each tick waits (up to
    `timeout`) for the device's next reading, so host and device clocks cannot drift apart; this is the
    mode for a free-running device. With ``realtime=True`` the host keeps its own deadlines and takes
    whatever reading arrived within `timeout`.

    A reading that arrives after a newer one (network reordering) raises `LinkError`: the loop
    stops with zero torque rather than act on a network that reorders a 1 kHz stream.
    """

    def __init__(self, host: str, port: int, *, rate: float = 1000.0, timeout: float = 0.05,
                 connect_timeout: float = 2.0, spin: bool = False) -> None:
        if not isinstance(port, int) or isinstance(port, bool) or not 0 < port < 65536:
            raise InvalidInput(f"port: expected an integer in 1..65535, got {port!r}")
        self.addr = (str(host), port)
        self.rate = scalar("rate", rate, positive=True)
        self.timeout = scalar("timeout", timeout, positive=True)
        self.connect_timeout = scalar("connect_timeout", connect_timeout, positive=True)
        self.spin = bool(spin)
        self.n = 0
        self.sensors: list[tuple[str, int]] = []
        self.info: dict = {}
        self.stats = {"sent": 0, "received": 0, "lost": 0, "reordered": 0, "invalid": 0, "skipped": 0}
        self._sock: socket.socket | None = None
        self._last: Reading | None = None
        self._last_seq: int | None = None
        self._seq = 0

    @classmethod
    def from_url(cls, url: str, **kw) -> UDPLink:
        """A link to ``udp://HOST:PORT``; keywords as for the constructor."""
        host, port = parse_url(url)
        return cls(host, port, **kw)

    def open(self) -> None:
        """Say HELLO and read the device's INFO.

        Raises:
            LinkError: no answer, a refusal, another protocol version, another rate.
        """
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        try:
            s.connect(self.addr)
        except OSError as exc:
            raise LinkError(f"link: cannot reach {self.addr[0]}:{self.addr[1]}: {exc}") from None
        self._sock = s
        end = time.monotonic() + self.connect_timeout
        while True:
            self._send(P.hello())
            pkt = self._recv(min(0.2, max(end - time.monotonic(), 0.0)))
            while pkt is not None and P.kind(pkt) == P.READING:  # readings of a previous session
                pkt = self._recv(0.0)
            if pkt is not None:
                break
            if time.monotonic() > end:
                self.close()
                raise LinkError(f"link: no answer from {self.addr[0]}:{self.addr[1]} within "
                                f"{self.connect_timeout:g} s (is the device server running?)")
        if P.kind(pkt) == P.ERROR:
            self.close()
            raise LinkError(f"link: device refused: {pkt[8:].decode(errors='replace')}")
        self.info = P.parse_info(pkt)
        if abs(self.info["rate"] - self.rate) > 1e-9 * self.rate:
            self.close()
            raise LinkError(f"link: the device runs at {self.info['rate']:g} Hz, the loop at {self.rate:g} Hz")
        self.n, self.sensors = int(self.info["n"]), [(str(a), int(b)) for a, b in self.info["sensors"]]
        self._k = int(self.info["k"])

    def _send(self, pkt: bytes) -> None:
        if self._sock is None:
            raise LinkError("link: not open")
        try:
            self._sock.send(pkt)
        except OSError as exc:
            raise LinkError(f"link: send to {self.addr[0]}:{self.addr[1]} failed: {exc}") from None
        self.stats["sent"] += 1

    def _recv(self, timeout: float) -> bytes | None:
        s = self._sock
        if s is None:
            raise LinkError("link: not open")
        try:
            if timeout > 0 and not wait_readable(s, timeout, self.spin):
                return None
            return s.recv(65536, socket.MSG_DONTWAIT)
        except BlockingIOError:
            return None
        except OSError as exc:  # e.g. ECONNREFUSED: the device process is gone
            raise LinkError(f"link: {self.addr[0]}:{self.addr[1]} unreachable: {exc}") from None

    def read(self) -> Reading:
        """The newest reading that arrived; waits up to `timeout` for one newer than the last returned.

        Raises:
            LinkError: the device is unreachable, or sent no reading at all within `timeout` after `open`.
        """
        if self._sock is None:
            raise LinkError("link: read() before open()")
        newest, wait = None, self.timeout
        end = time.monotonic() + wait
        while True:
            pkt = self._recv(0.0 if newest is not None else max(end - time.monotonic(), 0.0))
            if pkt is None:
                if newest is not None or time.monotonic() >= end:
                    break
                continue
            r = self._parse(pkt)
            if r is not None:
                if newest is not None:
                    self.stats["skipped"] += 1  # the host fell a device period behind
                newest = r
        if newest is None:
            if self._last is None:
                raise LinkError(f"link: no reading from {self.addr[0]}:{self.addr[1]} within {self.timeout:g} s")
            return self._last
        self._last = newest
        return newest

    def _parse(self, pkt: bytes) -> Reading | None:
        if P.kind(pkt) != P.READING:
            if P.kind(pkt) == P.ERROR:
                raise LinkError(f"link: device error: {pkt[8:].decode(errors='replace')}")
            return None  # e.g. a repeated INFO
        v = P.parse_reading(pkt, self.n, self._k)
        if v is None:
            self.stats["invalid"] += 1
            return None
        seq, cmd_seq, status, t, q, dq, s = v
        self.stats["received"] += 1
        if self._last_seq is not None:
            if seq > self._last_seq + 1:
                self.stats["lost"] += seq - self._last_seq - 1
            elif seq <= self._last_seq:
                self.stats["reordered"] += 1
                raise LinkError(f"link: out-of-order datagram: reading {seq} arrived after reading {self._last_seq}")
        self._last_seq = seq
        sensors, i = {}, 0
        for name, w in self.sensors:
            sensors[name] = s[i:i + w]
            i += w
        return Reading(t, seq, q, dq, sensors, status, -1 if cmd_seq == P.NO_SEQ else cmd_seq)

    def write(self, tau, *, enable: bool, flags: int = 0) -> None:
        """Send a COMMAND answering the last reading; `flags` adds ESTOP/RESET bits."""
        if self._sock is None:
            raise LinkError("link: write() before open()")
        tau = np.asarray(tau, dtype=float)
        if tau.shape != (self.n,):
            raise InvalidInput(f"tau: expected shape ({self.n},), got {tau.shape}")
        ack = self._last.seq if self._last is not None else P.NO_SEQ
        self._seq += 1
        self._send(P.command(self._seq, ack, flags | (P.ENABLE if enable else 0), time.monotonic(), tau))

    def close(self) -> None:
        """Zero torque, motors disabled, BYE; then close the socket (idempotent)."""
        s, self._sock = self._sock, None
        if s is None:
            return
        if self.n:
            for _ in range(3):
                try:
                    s.send(P.command(self._seq + 1, P.NO_SEQ, P.BYE, time.monotonic(), np.zeros(self.n)))
                except OSError:
                    break
        s.close()
