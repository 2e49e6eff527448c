"""`UDPLink.read` on the datagrams a device may send, from a socket in this process (no clocks, no processes).

Each case queues its datagrams on loopback before `read`, so `read` finds them at once: which reading it
returns, what it counts, what it refuses, and that a reading keeps its values after the next datagram.
"""

from __future__ import annotations

import socket
import threading

import numpy as np
import pytest

from rhi.errors import LinkError
from rhi.runtime import protocol as P
from rhi.runtime.udp import SessionLost, UDPLink

N, SENSORS = 4, [("ft", 6), ("x", 2)]
K = sum(w for _, w in SENSORS)


@pytest.fixture
def pair():
    """(link, send, session, device socket): an open `UDPLink`, a function sending the device's datagrams to it."""
    dev = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    dev.bind(("127.0.0.1", 0))
    box = {}

    def answer() -> None:
        pkt, addr = dev.recvfrom(100)
        box["addr"], box["session"] = addr, int.from_bytes(pkt[8:16], "little")
        dev.sendto(P.info(N, SENSORS, 1000.0, 0.1, {"device": "fake"}, box["session"]), addr)

    th = threading.Thread(target=answer)
    th.start()
    link = UDPLink("127.0.0.1", dev.getsockname()[1], rate=1000.0, timeout=0.05)
    link.open()
    th.join()

    def send(pkt: bytes) -> None:
        dev.sendto(pkt, box["addr"])

    yield link, send, box["session"], dev
    link.close()
    dev.close()


def _reading(session: int, seq: int, scale: float = 1.0) -> bytes:
    v = scale * np.arange(2 * N + K, dtype=float)
    return P.reading(session, seq, P.NO_SEQ, 17, 1e-3 * seq, v[:N], v[N:2 * N], v[2 * N:])


def test_the_newest_valid_reading_is_returned_with_its_values(pair):
    link, send, session, _ = pair
    send(_reading(session, 1))
    r1 = link.read()
    np.testing.assert_array_equal(np.concatenate([r1.q, r1.dq, r1.sensors["ft"], r1.sensors["x"]]),
                                  np.arange(2 * N + K))
    assert (r1.seq, r1.t, r1.status, r1.cmd_seq) == (1, 1e-3, 17, -1)
    send(_reading(session, 2, 2.0))
    send(_reading(session, 3, 3.0))
    r3 = link.read()
    assert r3.seq == 3 and link.stats["skipped"] == 1
    np.testing.assert_array_equal(r3.q, 3.0 * np.arange(N))
    np.testing.assert_array_equal(r1.q, np.arange(N))  # the older reading kept its own values
    np.testing.assert_array_equal(r3.sensors["x"], 3.0 * np.arange(2 * N + 6, 2 * N + K))


def test_malformed_foreign_and_other_datagrams_are_counted_and_passed_over(pair):
    link, send, session, _ = pair
    good = _reading(session, 5)
    send(good[:-8])  # a cut reading
    send(good[:24] + (N + 1).to_bytes(2, "little") + good[26:])  # another n (the header at byte 24), same size
    send(_reading(session ^ 1, 6))  # another session's
    send(P.info(N, SENSORS, 1000.0, 0.1, {}, session))  # a repeated INFO
    send(b"RH")  # shorter than any header
    send(good)
    r = link.read()
    assert r.seq == 5
    assert (link.stats["invalid"], link.stats["foreign"], link.stats["received"]) == (2, 1, 1)


@pytest.mark.parametrize("make, error, match", [
    (lambda s: P.error(P.E_SESSION_LOST, s, "taken over"), SessionLost, "SESSION_LOST: taken over"),
    (lambda s: P.error(P.E_BUSY, 0, "busy"), LinkError, "device error: BUSY: busy"),
    (lambda s: _reading(s, 7)[:4] + (1).to_bytes(2, "little") + _reading(s, 7)[6:], LinkError, "wire version 1"),
    (lambda s: _reading(s, 7)[:4] + (1).to_bytes(2, "little") + _reading(s, 7)[6:-8], LinkError, "wire version 1"),
    (lambda s: P.reading(s, 8, 0, 1 << 6, 0.0, np.zeros(N), np.zeros(N), np.zeros(K)), LinkError, "status bits 0x0040"),
])
def test_errors_other_versions_and_unknown_status_bits_raise(pair, make, error, match):
    link, send, session, _ = pair
    send(make(session))
    with pytest.raises(error, match=match):
        link.read()


def test_a_reading_older_than_the_last_raises(pair):
    link, send, session, _ = pair
    send(_reading(session, 9))
    link.read()
    send(_reading(session, 8))
    with pytest.raises(LinkError, match="out-of-order datagram: reading 8 arrived after reading 9"):
        link.read()


def test_commands_carry_the_torques_and_the_last_reading(pair):
    link, send, session, dev = pair
    send(_reading(session, 4))
    link.read()
    tau = np.array([0.5, -1.0, 1e-3, 2.0])
    link.write(tau, enable=True)
    link.write(-tau, enable=False)
    for want, flags in ((tau, P.ENABLE), (-tau, 0)):
        got = P.parse_command(dev.recv(1000), N)
        assert got is not None
        assert got[:4] == (session, 1 if flags else 2, 4, flags)
        np.testing.assert_array_equal(got[5], want)
