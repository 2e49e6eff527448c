"""The rhi device protocol, version 1: datagrams between a control host and a haptic device.

The normative description is docs/protocol.md; this module is its Python implementation.
All fields are little-endian; floats are IEEE-754 binary64; units are SI.
"""

from __future__ import annotations

import json
import math
import struct

import numpy as np

from rhi.errors import LinkError

VERSION = 1

HELLO, INFO, COMMAND, READING, ERROR = b"RHIH", b"RHII", b"RHIC", b"RHIR", b"RHIE"

# command flags
ENABLE, ESTOP, RESET, BYE = 1, 2, 4, 8
NO_SEQ = 0xFFFFFFFF

_HELLO = struct.Struct("<4sHH")  # magic, version, reserved
_INFO = struct.Struct("<4sHHHHdd")  # magic, version, n, k, reserved, rate [Hz], watchdog [s]; + JSON
_CMD = struct.Struct("<4sHHIIHHd")  # magic, version, flags, seq, ack, n, reserved, t_host [s]; + tau[n]
_READ = struct.Struct("<4sHHIIHHd")  # magic, version, status, seq, cmd_seq, n, k, t_dev [s]; + q[n] dq[n] s[k]
_ERR = struct.Struct("<4sHH")  # magic, version, reserved; + UTF-8 message


def hello() -> bytes:
    """A HELLO packet (host → device)."""
    return _HELLO.pack(HELLO, VERSION, 0)


def info(n: int, sensors: list[tuple[str, int]], rate: float, watchdog: float, meta: dict) -> bytes:
    """An INFO packet (device → host): n motors, sensor widths, rate [Hz], watchdog [s] and a JSON description."""
    k = sum(w for _, w in sensors)
    body = json.dumps({**meta, "sensors": sensors}).encode()
    return _INFO.pack(INFO, VERSION, n, k, 0, rate, watchdog) + body


def command(seq: int, ack: int, flags: int, t_host: float, tau: np.ndarray) -> bytes:
    """A COMMAND packet (host → device): sequence numbers, flags, host time [s] and torques τ (n,) [N m]."""
    tau = np.ascontiguousarray(tau, dtype="<f8")
    return _CMD.pack(COMMAND, VERSION, flags, seq & NO_SEQ, ack & NO_SEQ, len(tau), 0, t_host) + tau.tobytes()


def reading(seq: int, cmd_seq: int, status: int, t_dev: float, q, dq, s) -> bytes:
    """A READING packet (device → host): sequence numbers, status, device time [s], q (n,), q̇ (n,), sensors (k,)."""
    q = np.ascontiguousarray(q, dtype="<f8")
    body = q.tobytes() + np.ascontiguousarray(dq, dtype="<f8").tobytes() + np.ascontiguousarray(s, dtype="<f8").tobytes()
    return _READ.pack(READING, VERSION, status, seq & NO_SEQ, cmd_seq & NO_SEQ, len(q), len(s) if s is not None else 0,
                      t_dev) + body


def error(message: str) -> bytes:
    """An ERROR packet (device → host) carrying `message` (at most 1000 bytes)."""
    return _ERR.pack(ERROR, VERSION, 0) + message.encode()[:1000]


def kind(pkt: bytes) -> bytes:
    """The packet's magic (b"" for a datagram too short to have one)."""
    return pkt[:4] if len(pkt) >= 8 else b""


def version(pkt: bytes) -> int:
    """The packet's protocol version (its header's second field)."""
    return struct.unpack_from("<H", pkt, 4)[0]


def parse_info(pkt: bytes) -> dict:
    """INFO → {"version", "n", "k", "rate", "watchdog", "sensors": [[name, width]], ...meta}.

    Raises:
        LinkError: a short, foreign or other-version packet.
    """
    if len(pkt) < _INFO.size or pkt[:4] != INFO:
        raise LinkError(f"device: expected an INFO packet, got {pkt[:4]!r} ({len(pkt)} bytes)")
    magic, ver, n, k, _, rate, wd = _INFO.unpack_from(pkt)
    if ver != VERSION:
        raise LinkError(f"device: speaks protocol version {ver}, this host speaks {VERSION}")
    try:
        meta = json.loads(pkt[_INFO.size:].decode())
    except ValueError as exc:
        raise LinkError(f"device: INFO description is not JSON: {exc}") from None
    if sum(int(w) for _, w in meta.get("sensors", [])) != k:
        raise LinkError(f"device: INFO sensor widths do not add up to k={k}")
    return {**meta, "version": ver, "n": n, "k": k, "rate": rate, "watchdog": wd}


def parse_command(pkt: bytes, n: int) -> tuple[int, int, int, float, np.ndarray] | None:
    """COMMAND → (seq, ack, flags, t_host, tau (n,)), or None if it is not a valid command.

    Valid: version 1, n motors, finite torques (an invalid packet is ignored and does not feed the watchdog).
    """
    if len(pkt) != _CMD.size + 8 * n or pkt[:4] != COMMAND:
        return None
    magic, ver, flags, seq, ack, nn, _, t_host = _CMD.unpack_from(pkt)
    if ver != VERSION or nn != n:
        return None
    tau = np.frombuffer(pkt, dtype="<f8", count=n, offset=_CMD.size).astype(float)
    if not math.isfinite(float(tau @ tau)):
        return None
    return seq, ack, flags, t_host, tau


def parse_reading(pkt: bytes, n: int, k: int) -> tuple[int, int, int, float, np.ndarray, np.ndarray, np.ndarray] | None:
    """READING → (seq, cmd_seq, status, t_dev, q (n,), dq (n,), s (k,)), or None if malformed.

    Raises:
        LinkError: a reading of another protocol version.
    """
    if len(pkt) != _READ.size + 8 * (2 * n + k) or pkt[:4] != READING:
        return None
    magic, ver, status, seq, cmd_seq, nn, kk, t_dev = _READ.unpack_from(pkt)
    if ver != VERSION:
        raise LinkError(f"device: reading of protocol version {ver}, this host speaks {VERSION}")
    if nn != n or kk != k:
        return None
    v = np.frombuffer(pkt, dtype="<f8", count=2 * n + k, offset=_READ.size).astype(float)
    return seq, cmd_seq, status, t_dev, v[:n], v[n:2 * n], v[2 * n:]
