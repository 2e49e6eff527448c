"""A UDP proxy process between a control host and a device, for fault injection over a real socket.

python tests/udp_proxy.py DEVICE_PORT [--delay S] [--hold START END] [--freeze START END]

Listens on a free loopback port (printed on the first line of stdout) and forwards datagrams both ways,
the first sender being the host. --delay: every datagram, both ways, leaves S seconds after it arrived (a
constant link delay). --hold: readings (device → host) that arrive between START and END seconds after the
first one are held and all released at END (a reading that arrives late). --freeze: from the first reading
at least START seconds after the first one whose joints move (some |q̇_i| above 0.01 rad/s) until END, every
reading carries that reading's values (q, q̇, sensors) with its own header (sequence numbers, device time and
command echo advancing): frozen sensors.
"""

from __future__ import annotations

import argparse
import heapq
import select
import socket
import struct
import time

ap = argparse.ArgumentParser()
ap.add_argument("device_port", type=int)
ap.add_argument("--delay", type=float, default=0.0)
ap.add_argument("--hold", type=float, nargs=2)
ap.add_argument("--freeze", type=float, nargs=2)
a = ap.parse_args()
dev = ("127.0.0.1", a.device_port)
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1], flush=True)
host = None
first = None
queue: list[tuple[float, int, bytes, tuple[str, int]]] = []
HEAD = 36  # a READING's header (rhi.runtime.protocol._READ): n at byte 24, then q, q̇, sensors as float64
frozen: bytes | None = None  # the values every reading carries while --freeze holds them
n = 0
while True:
    now = time.monotonic()
    while queue and queue[0][0] <= now:
        _, _, pkt, to = heapq.heappop(queue)
        try:
            s.sendto(pkt, to)
        except OSError:
            pass
    wait = max(0.0, queue[0][0] - now) if queue else 0.05
    if not select.select([s], [], [], wait)[0]:
        continue
    try:
        pkt, addr = s.recvfrom(65536)
    except OSError:
        continue
    now = time.monotonic()
    if addr == dev:
        if host is None:
            continue
        to = host
        if first is None:
            first = now
        due = now + a.delay
        if a.hold and first + a.hold[0] <= now < first + a.hold[1]:
            due = max(due, first + a.hold[1])
        if a.freeze and pkt[:4] == b"RHIR" and len(pkt) > HEAD and first + a.freeze[0] <= now < first + a.freeze[1]:
            if frozen is None:
                n = struct.unpack_from("<H", pkt, 24)[0]
                if max(abs(v) for v in struct.unpack_from(f"<{n}d", pkt, HEAD + 8 * n)) > 0.01:
                    frozen = pkt[HEAD:]
            if frozen is not None:
                pkt = pkt[:HEAD] + frozen
    else:
        host, to, due = addr, dev, now + a.delay
    n += 1
    heapq.heappush(queue, (due, n, pkt, to))
