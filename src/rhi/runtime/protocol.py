"""The rhi device protocol, version 1.1 (wire version 2): datagrams between a control host and a haptic device.

The normative description is docs/protocol.md; this module is its Python implementation (the C one is
kit/c/rhi_device.c). All fields are little-endian; floats are IEEE-754 binary64; units are SI. Every
message after HELLO carries the session id the host drew for its HELLO.
"""

from __future__ import annotations

import json
import math
import struct

import numpy as np

from rhi.errors import LinkError

VERSION = 2  # protocol v1.1 on the wire (v1.0 sent 1)
NAME = "1.1"
V1_0 = 1

HELLO, INFO, COMMAND, READING, ERROR = b"RHIH", b"RHII", b"RHIC", b"RHIR", b"RHIE"

# command flags (bits 4..15 reserved: a command with any of them set is invalid)
ENABLE, ESTOP, RESET, BYE = 1, 2, 4, 8
COMMAND_FLAGS = ENABLE | ESTOP | RESET | BYE
# reading status flags (rhi.runtime.link.Status); any other bit is a device fault at the host
STATUS_FLAGS = 1 | 2 | 4 | 8 | 16
# HELLO flags
TAKEOVER = 1
HELLO_FLAGS = TAKEOVER
# ERROR codes
E_VERSION, E_HELLO, E_BUSY, E_SESSION_LOST = 1, 2, 3, 4
ERROR_NAMES = {E_VERSION: "VERSION", E_HELLO: "BAD_HELLO", E_BUSY: "BUSY", E_SESSION_LOST: "SESSION_LOST"}
NO_SEQ = 0xFFFFFFFF

_HEAD = struct.Struct("<4sHH")  # magic, version, a message-specific u16
_HELLO = struct.Struct("<4sHHQ")  # magic, version, flags, session
_INFO = struct.Struct("<4sHHHHddQ")  # magic, version, n, k, reserved, rate [Hz], watchdog [s], session; + JSON
_CMD = struct.Struct("<4sHHQIIHHd")  # magic, version, flags, session, seq, ack, n, reserved, t_host [s]; + tau[n]
_READ = struct.Struct("<4sHHQIIHHd")  # magic, version, status, session, seq, cmd_seq, n, k, t_dev [s]; + q dq s
_ERR = struct.Struct("<4sHHQ")  # magic, version, code, session; + UTF-8 message

HELLO_SIZE, INFO_SIZE, COMMAND_SIZE, READING_SIZE, ERROR_SIZE = (_HELLO.size, _INFO.size, _CMD.size, _READ.size,
                                                                _ERR.size)


def hello(session: int, flags: int = 0) -> bytes:
    """A HELLO packet (host → device) opening `session` (u64, not 0); `flags`: TAKEOVER."""
    return _HELLO.pack(HELLO, VERSION, flags, session)


def info(n: int, sensors: list[tuple[str, int]], rate: float, watchdog: float, meta: dict, session: int) -> bytes:
    """An INFO packet (device → host): n motors, sensor widths, rate [Hz], watchdog [s], the session, a JSON description."""
    k = sum(w for _, w in sensors)
    body = json.dumps({**meta, "sensors": sensors}).encode()
    return _INFO.pack(INFO, VERSION, n, k, 0, rate, watchdog, session) + body


def command(session: int, seq: int, ack: int, flags: int, t_host: float, tau: np.ndarray) -> bytes:
    """A COMMAND packet (host → device): session, sequence numbers, flags, host time [s], torques τ (n,) [N m]."""
    tau = np.ascontiguousarray(tau, dtype="<f8")
    return _CMD.pack(COMMAND, VERSION, flags, session, seq & NO_SEQ, ack & NO_SEQ, len(tau), 0, t_host) + tau.tobytes()


def command_into(buf: bytearray, session: int, seq: int, ack: int, flags: int, t_host: float) -> None:
    """Write a COMMAND's header into `buf` (36 + 8n bytes) in place; its torques go to the n floats after it."""
    _CMD.pack_into(buf, 0, COMMAND, VERSION, flags, session, seq & NO_SEQ, ack & NO_SEQ, (len(buf) - _CMD.size) // 8, 0,
                   t_host)


def reading_header(buf) -> tuple[bytes, int, int, int, int, int, int, int, float]:
    """A READING's header fields from the start of `buf`: (magic, version, status, session, seq, cmd_seq, n, k, t_dev)."""
    return _READ.unpack_from(buf)


def reading(session: int, seq: int, cmd_seq: int, status: int, t_dev: float, q, dq, s) -> bytes:
    """A READING packet (device → host): session, sequence numbers, status, device time [s], q, q̇ (n,), sensors (k,)."""
    q = np.ascontiguousarray(q, dtype="<f8")
    s = np.zeros(0) if s is None else np.ascontiguousarray(s, dtype="<f8")
    body = q.tobytes() + np.ascontiguousarray(dq, dtype="<f8").tobytes() + s.tobytes()
    return _READ.pack(READING, VERSION, status, session, seq & NO_SEQ, cmd_seq & NO_SEQ, len(q), len(s), t_dev) + body


def error(code: int, session: int, message: str) -> bytes:
    """An ERROR packet (device → host): a code (E_*), the session it concerns (0: none), a message (≤ 1000 bytes)."""
    return _ERR.pack(ERROR, VERSION, code, session) + message.encode()[:1000]


def error_v1_0(message: str) -> bytes:
    """An ERROR in protocol v1.0's layout (8-byte header, version 1), so that a v1.0 host can print the refusal."""
    return _HEAD.pack(ERROR, V1_0, 0) + message.encode()[:1000]


def kind(pkt: bytes) -> bytes:
    """The packet's magic (b"" for a datagram too short to have a header)."""
    return pkt[:4] if len(pkt) >= _HEAD.size else b""


def version(pkt: bytes) -> int:
    """The packet's protocol version (its header's second field)."""
    return struct.unpack_from("<H", pkt, 4)[0]


def newer(seq: int, last: int) -> bool:
    """Whether sequence number `seq` follows `last` (serial-number arithmetic on u32: 1 ≤ seq − last < 2³¹)."""
    return 0 < ((seq - last) & NO_SEQ) < 0x80000000


def parse_hello(pkt: bytes) -> tuple[int, int] | str:
    """HELLO → (session, flags), or the reason it is not a valid v1.1 HELLO (the device answers ERROR with it)."""
    ver = version(pkt)
    if ver != VERSION:
        return f"protocol version {ver} not supported; this device speaks v{NAME} (wire version {VERSION})"
    if len(pkt) != _HELLO.size:
        return f"HELLO of {len(pkt)} bytes; v{NAME} HELLO is exactly {_HELLO.size} bytes"
    _, _, flags, session = _HELLO.unpack(pkt)
    if session == 0:
        return "HELLO with session id 0; draw a random non-zero u64"
    if flags & ~HELLO_FLAGS:
        return f"HELLO with unknown flag bits 0x{flags & ~HELLO_FLAGS:04x}"
    return session, flags


def parse_error(pkt: bytes) -> tuple[int, int, str]:
    """ERROR → (code, session, message); a v1.0-layout ERROR gives code 0 and session 0."""
    if version(pkt) == VERSION and len(pkt) >= _ERR.size:
        _, _, code, session = _ERR.unpack_from(pkt)
        return code, session, pkt[_ERR.size:].decode(errors="replace")
    return 0, 0, pkt[_HEAD.size:].decode(errors="replace")


def parse_info(pkt: bytes) -> dict:
    """INFO → {"version", "session", "n", "k", "rate", "watchdog", "sensors": [[name, width]], ...meta}.

    Raises:
        LinkError: a short, foreign or other-version packet, or a description that does not add up.
    """
    if len(pkt) < _HEAD.size or pkt[:4] != INFO:
        raise LinkError(f"device: expected an INFO packet, got {pkt[:4]!r} ({len(pkt)} bytes)")
    ver = version(pkt)
    if ver != VERSION:
        old = " (v1.0: update the device to v1.1, e.g. from kit/c)" if ver == V1_0 else ""
        raise LinkError(f"device: speaks protocol wire version {ver}{old}; this host speaks v{NAME} "
                        f"(wire version {VERSION})")
    if len(pkt) < _INFO.size:
        raise LinkError(f"device: INFO of {len(pkt)} bytes, shorter than its {_INFO.size}-byte header")
    _, _, n, k, _, rate, wd, session = _INFO.unpack_from(pkt)
    try:
        meta = json.loads(pkt[_INFO.size:].decode())
    except (ValueError, RecursionError) as exc:  # not UTF-8, not JSON, nested too deep
        raise LinkError(f"device: INFO description is not a JSON object: {str(exc)[:200]}") from None
    pairs = meta.get("sensors") if isinstance(meta, dict) else None
    if not isinstance(pairs, list) or not all(
            isinstance(p, list) and len(p) == 2 and isinstance(p[0], str) and _is_int(p[1]) for p in pairs):
        raise LinkError(f"device: INFO description is not a JSON object with \"sensors\": [[name, width]] (a string "
                        f"and an integer each), got {str(meta)[:200]}")
    widths = [(a, b) for a, b in pairs]
    for key, ok, want in [("device", lambda v: isinstance(v, str), "a string"),
                          ("lockstep", lambda v: isinstance(v, bool), "true or false"),
                          ("joint_names", lambda v: isinstance(v, list) and len(v) == n
                           and all(isinstance(x, str) for x in v), f"a list of {n} strings"),
                          *[(t, lambda v: isinstance(v, list) and len(v) == n and all(
                              isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v),
                             f"a list of {n} finite numbers") for t in ("torque_min", "torque_max")]]:
        if key in meta and not ok(meta[key]):
            raise LinkError(f"device: INFO \"{key}\" must be {want}, got {str(meta[key])[:100]}")
    if sum(w for _, w in widths) != k or any(w <= 0 for _, w in widths):
        raise LinkError(f"device: INFO sensor widths {widths} do not add up to k={k}")
    if not (math.isfinite(rate) and rate > 0 and math.isfinite(wd) and wd > 0):
        raise LinkError(f"device: INFO rate {rate!r} Hz or watchdog {wd!r} s is not finite and positive")
    return {**meta, "sensors": widths, "version": ver, "session": session, "n": n, "k": k, "rate": rate,
            "watchdog": wd}


def _is_int(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def parse_command(pkt: bytes, n: int) -> tuple[int, int, int, int, float, np.ndarray] | None:
    """COMMAND → (session, seq, ack, flags, t_host, tau (n,)), or None if it is not a valid command.

    Valid: wire version 2, exactly 36 + 8n bytes, n motors, no reserved flag bit, every τᵢ finite (any size:
    the device clamps). An invalid packet is ignored and does not feed the watchdog.
    """
    if len(pkt) != _CMD.size + 8 * n or pkt[:4] != COMMAND:
        return None
    _, ver, flags, session, seq, ack, nn, _, t_host = _CMD.unpack_from(pkt)
    if ver != VERSION or nn != n or flags & ~COMMAND_FLAGS:
        return None
    tau = np.frombuffer(pkt, dtype="<f8", count=n, offset=_CMD.size).astype(float)
    if not np.isfinite(tau).all():
        return None
    return session, seq, ack, flags, t_host, tau


def parse_reading(pkt: bytes, n: int, k: int) -> tuple[int, int, int, int, float, np.ndarray, np.ndarray,
                                                        np.ndarray] | None:
    """READING → (session, seq, cmd_seq, status, t_dev, q (n,), dq (n,), s (k,)), or None if malformed.

    Raises:
        LinkError: a reading of another protocol version.
    """
    if len(pkt) >= _HEAD.size and pkt[:4] == READING and version(pkt) != VERSION:
        raise LinkError(f"device: reading of protocol wire version {version(pkt)}, this host speaks v{NAME} "
                        f"(wire version {VERSION})")
    if len(pkt) != _READ.size + 8 * (2 * n + k) or pkt[:4] != READING:
        return None
    _, _, status, session, seq, cmd_seq, nn, kk, t_dev = _READ.unpack_from(pkt)
    if nn != n or kk != k:
        return None
    v = np.frombuffer(pkt, dtype="<f8", count=2 * n + k, offset=_READ.size).astype(float)
    return session, seq, cmd_seq, status, t_dev, v[:n], v[n:2 * n], v[2 * n:]
