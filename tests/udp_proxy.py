"""A UDP proxy process between a control host and a device, for fault injection over a real socket.

python tests/udp_proxy.py DEVICE_PORT [--delay S] [--hold START END]

Listens on a free loopback port (printed on the first line of stdout) and forwards datagrams both ways,
the first sender being the host. --delay: every datagram, both ways, leaves S seconds after it arrived (a
constant link delay). --hold: readings (device → host) that arrive between START and END seconds after the
first one are held and all released at END (a reading that arrives late).
"""

from __future__ import annotations

import argparse
import heapq
import select
import socket
import time

ap = argparse.ArgumentParser()
ap.add_argument("device_port", type=int)
ap.add_argument("--delay", type=float, default=0.0)
ap.add_argument("--hold", type=float, nargs=2)
a = ap.parse_args()
dev = ("127.0.0.1", a.device_port)
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
s.bind(("127.0.0.1", 0))
print(s.getsockname()[1], flush=True)
host = None
first = None
queue: list[tuple[float, int, bytes, tuple[str, int]]] = []
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
    else:
        host, to, due = addr, dev, now + a.delay
    n += 1
    heapq.heappush(queue, (due, n, pkt, to))
