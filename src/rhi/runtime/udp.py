"""`UDPLink`: the control host's side of the rhi device protocol v1.1 (docs/protocol.md) over UDP."""

from __future__ import annotations

import math
import secrets
import select
import socket
import time
import urllib.parse

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput, LinkError
from rhi.runtime import protocol as P
from rhi.runtime.link import Reading
from rhi.runtime.realtime import SpinRest, spin_rest, wait_readable


class SessionLost(LinkError):
    """The device ended this host's session: another host took it over (ERROR/SESSION_LOST)."""

    kind = "session_lost"


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
    """A device process reached over UDP (e.g. `rhi device-server`, kit/c's reference device, a lab's own driver).

    Args:
        host, port: the device's address.
        rate: the control rate [Hz]; must equal the device's.
        timeout: longest wait for a new reading in `read` [s]; after it the previous reading is returned
            again (the safety layer counts it as stale). In real time keep it under one period.
        connect_timeout: longest wait for the device's INFO answer in `open` [s].
        spin: wait for readings polling the socket on a busy core, not asleep (`rhi.runtime.realtime.spin_rest`).
        takeover: ask the device to end another host's active session and serve this one (HELLO's TAKEOVER).

    Attributes:
        n: motors; sensors: [(name, width)] the device reports; info: the device's description.
        session: this host's random session id (u64), drawn at `open`.
        stats: datagram counts: sent, received, lost (gaps in the reading sequence), reordered, invalid, skipped
            (readings superseded before the host read them: device periods the host missed), foreign (readings
            of another session).

    Timing: with ``run(..., realtime=False)`` the host is paced by the device — each tick waits (up to
    `timeout`) for the device's next reading; with ``realtime=True`` the host keeps its own deadlines and
    takes whatever reading arrived within `timeout`. Each reading carries its arrival time and its
    round-trip age (`Reading.age`: arrival minus the send time of the command it echoes), except from a
    device whose INFO says ``"lockstep": true`` (a simulation that waits for each command: its time is not
    the wall clock's).

    A reading that arrives after a newer one, or repeats one (network reordering or duplication), raises
    `LinkError`: the loop stops with zero torque rather than act on a network that reorders a 1 kHz stream.
    """

    _RING = 4096  # send times of the last commands, by seq (4 s at 1 kHz)

    def __init__(self, host: str, port: int, *, rate: float = 1000.0, timeout: float = 0.05,
                 connect_timeout: float = 2.0, spin: bool = False, takeover: bool = False) -> None:
        if not isinstance(port, int) or isinstance(port, bool) or not 0 < port < 65536:
            raise InvalidInput(f"port: expected an integer in 1..65535, got {port!r}")
        self.addr = (str(host), port)
        self.rate = scalar("rate", rate, positive=True)
        self.timeout = scalar("timeout", timeout, positive=True)
        self.connect_timeout = scalar("connect_timeout", connect_timeout, positive=True)
        self.spin = bool(spin)
        self._rest = SpinRest()  # which spinning waits are slept (`rhi.runtime.realtime.spin_rest`)
        self.takeover = bool(takeover)
        self.n = 0
        self.session = 0
        self.sensors: list[tuple[str, int]] = []
        self.info: dict = {}
        self.stats = {"sent": 0, "received": 0, "lost": 0, "reordered": 0, "invalid": 0, "skipped": 0, "foreign": 0}
        self._sock: socket.socket | None = None
        self._last: Reading | None = None
        self._last_seq: int | None = None
        self._seq = 0
        self._sent_seq = [-1] * self._RING
        self._sent_t = [0.0] * self._RING
        self._first_sent: float | None = None
        self._wall = True
        # the per-tick buffers, allocated once (`open`): datagrams are received into `_rx` and a reading's floats
        # copied out of it in one call; commands are packed into `_tx` in place
        self._rx = bytearray(65536)
        self._poll = select.poll()
        self._size = P.READING_SIZE  # a reading's size in bytes (`open`: with the device's floats)
        self._values = np.zeros(0)
        self._slices: list[tuple[str, slice]] = []
        self._tx = bytearray(P.COMMAND_SIZE)
        self._tx_tau = np.zeros(0)

    @property
    def packed(self) -> dict[str, slice]:
        """Each sensor's slice of the one float64 array a reading's q ([:n]), q̇ ([n:2 n]) and sensors are views of."""
        return dict(self._slices)

    @classmethod
    def from_url(cls, url: str, **kw) -> UDPLink:
        """A link to ``udp://HOST:PORT``; keywords as for the constructor."""
        host, port = parse_url(url)
        return cls(host, port, **kw)

    def open(self) -> None:
        """Draw a session id, say HELLO and read the device's INFO for this session.

        Raises:
            LinkError: no answer, a refusal (another session active, another protocol version), another rate
                (the device is then told BYE).
        """
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        try:
            s.connect(self.addr)
        except OSError as exc:
            raise LinkError(f"link: cannot reach {self.addr[0]}:{self.addr[1]}: {exc}") from None
        self._sock = s
        self._poll = select.poll()
        self._poll.register(s, select.POLLIN)
        self.session = secrets.randbits(64) or 1
        end = time.monotonic() + self.connect_timeout
        pkt = None
        while pkt is None:
            self._send(P.hello(self.session, P.TAKEOVER if self.takeover else 0))
            until = time.monotonic() + min(0.2, max(end - time.monotonic(), 0.0))
            while pkt is None and time.monotonic() < until:
                size = self._recv(max(until - time.monotonic(), 0.0))
                if size < 0:
                    break
                got = bytes(self._rx[:size])
                if P.kind(got) == P.ERROR or (P.kind(got) == P.INFO and (
                        P.version(got) != P.VERSION or len(got) < P.INFO_SIZE
                        or int.from_bytes(got[28:36], "little") == self.session)):
                    pkt = got  # (readings and INFOs of other sessions are ignored)
            if pkt is None and time.monotonic() > end:
                self.close()
                raise LinkError(f"link: no answer from {self.addr[0]}:{self.addr[1]} within "
                                f"{self.connect_timeout:g} s (is the device server running?)")
        if P.kind(pkt) == P.ERROR:
            self.close()
            code, _, msg = P.parse_error(pkt)
            hint = " (pass takeover=True, `rhi run --takeover`, to take it over)" if code == P.E_BUSY else ""
            raise LinkError(f"link: device refused: {P.ERROR_NAMES.get(code, 'ERROR')}: {msg}{hint}")
        try:
            self.info = P.parse_info(pkt)
        except LinkError:
            if P.version(pkt) == P.VERSION and len(pkt) >= P.INFO_SIZE:  # a v1.1 device: told BYE (`close`)
                self.n = int.from_bytes(pkt[6:8], "little")
            self.close()
            raise
        self.n, self.sensors = int(self.info["n"]), list(self.info["sensors"])
        self._k = int(self.info["k"])
        self._size = P.READING_SIZE + 8 * (2 * self.n + self._k)
        self._values = np.frombuffer(self._rx, dtype="<f8", count=2 * self.n + self._k, offset=P.READING_SIZE)
        ends = np.cumsum([2 * self.n] + [w for _, w in self.sensors]).tolist()
        self._slices = [(name, slice(a, b)) for (name, _), a, b in zip(self.sensors, ends, ends[1:])]
        self._tx = bytearray(P.COMMAND_SIZE + 8 * self.n)
        self._tx_tau = np.frombuffer(self._tx, dtype="<f8", count=self.n, offset=P.COMMAND_SIZE)
        self._rest = spin_rest(self.spin)
        self._wall = not self.info.get("lockstep", False)  # a lock-step simulation's time stops while it waits
        if abs(self.info["rate"] - self.rate) > 1e-9 * self.rate:
            self.refuse(f"the device runs at {self.info['rate']:g} Hz, the loop at {self.rate:g} Hz")

    def refuse(self, why: str) -> None:
        """Refuse the device after its INFO: BYE (zero torque, end of session), close, and raise.

        Raises:
            LinkError: always, with `why`.
        """
        self.close()
        raise LinkError(f"link: {why}")

    def _send(self, pkt: bytes | bytearray) -> None:
        if self._sock is None:
            raise LinkError("link: not open")
        try:
            self._sock.send(pkt)
        except OSError as exc:
            raise LinkError(f"link: send to {self.addr[0]}:{self.addr[1]} failed: {exc}") from None
        self.stats["sent"] += 1

    def _recv(self, timeout: float) -> int:
        """Receive the next datagram into `_rx` within `timeout` [s]: its size, or -1 when none came."""
        s = self._sock
        if s is None:
            raise LinkError("link: not open")
        try:
            if not self._poll.poll(0) and (timeout <= 0 or not wait_readable(s, timeout)):
                return -1
            return s.recv_into(self._rx, 0, socket.MSG_DONTWAIT)
        except BlockingIOError:
            return -1
        except OSError as exc:  # e.g. ECONNREFUSED: the device process is gone
            raise LinkError(f"link: {self.addr[0]}:{self.addr[1]} unreachable: {exc}") from None

    def _wait(self, end: float) -> int:
        """Receive the next datagram into `_rx` by the monotonic time `end` [s] at the latest: its size, or -1.

        Asleep in `select` until one arrives; `spin`: polling the non-blocking socket on a busy core (asleep in
        the waits `spin_rest` says are due, where the kernel would otherwise throttle a real-time loop).
        """
        now = time.monotonic()
        if not self.spin:
            return self._recv(max(end - now, 0.0))
        if self._rest.due(now):
            size = self._recv(max(end - now, 0.0))
            self._rest.slept(time.monotonic() - now)
            return size
        s = self._sock
        while True:
            try:
                return s.recv_into(self._rx, 0, socket.MSG_DONTWAIT)  # type: ignore[union-attr]
            except BlockingIOError:
                if time.monotonic() >= end:
                    return -1
            except OSError as exc:
                raise LinkError(f"link: {self.addr[0]}:{self.addr[1]} unreachable: {exc}") from None

    def read(self) -> Reading:
        """The newest reading that arrived; waits up to `timeout` for one newer than the last returned.

        Raises:
            LinkError: the device is unreachable, sent no reading at all within `timeout` after `open`, reordered
                readings, or reports unknown status bits.
            SessionLost: another host took the device over.
        """
        if self._sock is None:
            raise LinkError("link: read() before open()")
        newest = None
        end = time.monotonic() + self.timeout
        while True:
            size = self._recv(0.0) if newest is not None else self._wait(end)
            if size < 0:
                if newest is not None or time.monotonic() >= end:
                    break
                continue
            r = self._parse(size, time.monotonic())
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

    def _parse(self, size: int, now: float) -> Reading | None:
        """The reading in the first `size` bytes of `_rx` (None: another message, malformed or foreign)."""
        rx = self._rx
        if size != self._size or not rx.startswith(P.READING):  # not a well-formed reading of this device
            self._other(bytes(rx[:size]))
            return None
        _, ver, status, session, seq, cmd_seq, nn, kk, t = P.reading_header(rx)
        if ver != P.VERSION:
            raise LinkError(f"device: reading of protocol wire version {ver}, this host speaks v{P.NAME} "
                            f"(wire version {P.VERSION})")
        if nn != self.n or kk != self._k:
            self.stats["invalid"] += 1
            return None
        if session != self.session:
            self.stats["foreign"] += 1
            return None
        if status & ~P.STATUS_FLAGS:
            raise LinkError(f"link: reading {seq} has status bits 0x{status & ~P.STATUS_FLAGS:04x} that protocol "
                            f"v{P.NAME} does not define")
        self.stats["received"] += 1
        if self._last_seq is not None:
            if P.newer(seq, self._last_seq):
                self.stats["lost"] += ((seq - self._last_seq) & P.NO_SEQ) - 1
            else:
                self.stats["reordered"] += 1
                raise LinkError(f"link: out-of-order datagram: reading {seq} arrived after reading {self._last_seq}")
        self._last_seq = seq
        v = self._values.astype(float)  # a copy: the reading keeps its values when the next datagram arrives
        n = self.n
        sensors = {name: v[at] for name, at in self._slices}
        if not self._wall:
            return Reading(t, seq, v[:n], v[n:2 * n], sensors, status, -1 if cmd_seq == P.NO_SEQ else cmd_seq)
        return Reading(t, seq, v[:n], v[n:2 * n], sensors, status, -1 if cmd_seq == P.NO_SEQ else cmd_seq, "", now,
                       self._age(cmd_seq, now))

    def _other(self, pkt: bytes) -> None:
        """A datagram that is not a reading of this device's size: an error to raise, a malformed reading counted."""
        if P.kind(pkt) == P.ERROR:
            code, session, msg = P.parse_error(pkt)
            if code == P.E_SESSION_LOST and session == self.session:
                raise SessionLost(f"SESSION_LOST: {msg}")
            if session in (0, self.session):
                raise LinkError(f"link: device error: {P.ERROR_NAMES.get(code, 'ERROR')}: {msg}")
        elif P.kind(pkt) == P.READING and P.parse_reading(pkt, self.n, self._k) is None:  # (raises on a version)
            self.stats["invalid"] += 1
        # anything else (e.g. a repeated INFO) is ignored

    def _age(self, cmd_seq: int, now: float) -> float:
        """Arrival time minus the send time of command `cmd_seq` (of the first command while none is echoed)."""
        if cmd_seq == P.NO_SEQ:
            return math.nan if self._first_sent is None else now - self._first_sent
        i = cmd_seq % self._RING
        return now - self._sent_t[i] if self._sent_seq[i] == cmd_seq else math.inf  # inf: older than the ring

    def write(self, tau, *, enable: bool, flags: int = 0) -> None:
        """Send a COMMAND answering the last reading; `flags` adds ESTOP/RESET bits."""
        if self._sock is None:
            raise LinkError("link: write() before open()")
        tau = np.asarray(tau, dtype=float)
        if tau.shape != (self.n,):
            raise InvalidInput(f"tau: expected shape ({self.n},), got {tau.shape}")
        ack = self._last.seq if self._last is not None else P.NO_SEQ
        self._seq = (self._seq + 1) & P.NO_SEQ
        t = time.monotonic()
        P.command_into(self._tx, self.session, self._seq, ack, flags | (P.ENABLE if enable else 0), t)
        self._tx_tau[:] = tau
        self._send(self._tx)
        i = self._seq % self._RING
        self._sent_seq[i], self._sent_t[i] = self._seq, t
        if self._first_sent is None:
            self._first_sent = t

    def close(self) -> None:
        """Zero torque, motors disabled, BYE (after any refusal too); then close the socket (idempotent)."""
        s, self._sock = self._sock, None
        if s is None:
            return
        if self.n:
            for _ in range(3):
                try:
                    s.send(P.command(self.session, self._seq + 1, P.NO_SEQ, P.BYE, time.monotonic(), np.zeros(self.n)))
                except OSError:
                    break
        s.close()
