"""The parts of one tick of `rhi.runtime.run` inside the loop over UDP and back to back, each timed (issue 29).

A copy of `run`'s tick body with `time.perf_counter_ns` between its parts: the link's read (datagram in hand
→ `Reading`), the step (`rhi.runtime.step`: `--step compiled`, `FastStep`, one compiled call; `--step python`,
`ReferenceStep`) cut into its Python before the compiled call (the step's kernel, or the controller's whole tick
on the Python step), that call itself and the Python after it, the write (a COMMAND datagram sent) and the log
row. It runs bench_runtime's controller (the ch7 stack):

- in the loop: against kit/c's reference device over UDP at `--rate`, waiting asleep for each datagram
  (its datagrams are recorded);
- back to back: the recorded datagrams sent from a socket in this process right before each read;
- after an idle pause before each datagram (each of `--pauses` [µs]), asleep (`time.sleep`) or spinning
  on the clock: how the step's parts grow with the time the core spent on something else.

Prints each part's median per mode [µs], the step's (pre + kernel + post, `run`'s `t_step`) p50/p99/p99.9,
and the step's median over the back-to-back one.

    PYTHONPATH=src python benchmarks/bench_runtime_parts.py [--rate 1000] [--duration 4] [--pauses 100 300 900]
        [--cpu 1] [--device-cpu 0] [--priority 50] [--step compiled|python]
"""

from __future__ import annotations

import argparse
import select
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_runtime as b  # noqa: E402

from rhi.runtime import protocol as P  # noqa: E402
from rhi.runtime.realtime import realtime_thread  # noqa: E402
from rhi.runtime.safety import Safety  # noqa: E402
from rhi.runtime.step import FastStep, ReferenceStep  # noqa: E402
from rhi.runtime.udp import UDPLink  # noqa: E402
from rhi.sim.log import LogWriter, layout  # noqa: E402
from rhi.sim.loop import Kinematics  # noqa: E402

PARTS = ("read", "pre", "kernel", "post", "write", "row")
STEP = slice(1, 4)  # pre .. post: `run`'s t_step
ns = time.perf_counter_ns


def ticks(link: UDPLink, N: int, compiled: bool, before=None, record: list[bytes] | None = None) -> np.ndarray:
    """N ticks of a fresh controller on `link`: (N, len(PARTS)) durations [ns]; `before(i)` runs before tick i."""
    dev, ctrl, safety, wall, _ = b.setup(None)
    ctrl.warmup()
    guard, kin = Safety(dev, safety), Kinematics(dev, wall)
    step = (FastStep if compiled else ReferenceStep)(guard, kin, ctrl)
    step.attach(link)
    n = dev.n
    # the compiled call timed: the step's kernel (its entry point, found when it was made) or the whole tick's
    owner: Any = step if compiled else ctrl._kernel
    w = LogWriter(layout(n, dev.m, 0), None)
    names = [name for name, _ in w.columns]
    at = int(np.cumsum([0] + [width for _, width in w.columns])[names.index("tau")])
    out = np.zeros((N, len(PARTS)), dtype=np.int64)
    stamp = [0, 0]
    sock: Any = link._sock
    inner: Any = None

    def timed(*args):
        stamp[0] = ns()
        status = inner(*args)
        stamp[1] = ns()
        return status

    for i in range(N):
        if i == 1:  # (the whole tick's entry point is found at the first tick)
            inner, owner._call = owner._call, timed
        if before is not None:
            before(i)
        select.select([sock], [], [], 0.05)
        t0 = ns()
        r = link.read()
        if record is not None:
            record.append(bytes(link._rx[:link._size]))
        t1 = ns()
        tau, _, _ = step(r, time.monotonic())
        t2 = ns()
        link.write(tau, enable=guard.fault is None)
        t3 = ns()
        row = w.row()
        row[0] = r.t
        row[at:at + n] = tau
        t4 = ns()
        if i == 0 or stamp[0] < t1:  # no compiled call this tick
            stamp[:] = [t2, t2]
        out[i] = (t1 - t0, stamp[0] - t1, stamp[1] - stamp[0], t2 - stamp[1], t3 - t2, t4 - t3)
    if inner is not None:
        owner._call = inner
    if guard.fault is not None:
        print(f"  (fault: {guard.fault})")
    return out


def in_loop(a, tmp: Path) -> tuple[np.ndarray, list[bytes], UDPLink]:
    dev, _, _, _, q0 = b.setup(None)
    proc, port = b.start_device("c", a.rate, a.duration, dev, q0, None, a.device_cpu, a.priority, tmp)
    link = UDPLink("127.0.0.1", port, rate=a.rate, timeout=0.005)
    record: list[bytes] = []
    try:
        with realtime_thread(a.cpu, a.priority):
            link.open()
            out = ticks(link, int(a.duration * a.rate), a.step == "compiled", record=record)
    finally:
        link.close()
        proc.terminate()
        proc.wait(10)
    return out, record, link


def replayed(a, record: list[bytes], device: UDPLink, pause: float, spin: bool) -> np.ndarray:
    """The recorded datagrams through a fresh link from a socket in this process, each after `pause` [s] idle."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 22)
    peer: dict = {}

    def answer() -> None:
        pkt, addr = sock.recvfrom(100)
        peer["addr"], peer["session"] = addr, int.from_bytes(pkt[8:16], "little")
        sock.sendto(P.info(device.n, device.sensors, a.rate, 0.1, {"device": "replay"}, peer["session"]), addr)

    th = threading.Thread(target=answer)
    th.start()
    link = UDPLink("127.0.0.1", sock.getsockname()[1], rate=a.rate, timeout=0.005)
    link.open()
    th.join()
    session = peer["session"].to_bytes(8, "little")
    pkts = [p[:8] + session + p[16:] for p in record]

    def before(i: int) -> None:
        if pause and not spin:
            time.sleep(pause)
        elif pause:
            end = time.perf_counter() + pause
            while time.perf_counter() < end:
                pass
        if i % 64 == 0:  # the commands sent back: dropped
            try:
                while True:
                    sock.recv(100, socket.MSG_DONTWAIT)
            except BlockingIOError:
                pass
        sock.sendto(pkts[i], peer["addr"])

    try:
        with realtime_thread(a.cpu, a.priority):
            return ticks(link, len(pkts), a.step == "compiled", before)
    finally:
        link.close()
        sock.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=1000.0, help="the device's rate [Hz]")
    ap.add_argument("--duration", type=float, default=4.0, help="seconds in the loop")
    ap.add_argument("--pauses", type=float, nargs="*", default=[100.0, 300.0, 900.0], help="idle pauses [µs]")
    ap.add_argument("--cpu", type=int, default=1, help="the host loop's CPU")
    ap.add_argument("--device-cpu", type=int, default=0, help="the device process's CPU")
    ap.add_argument("--priority", type=int, default=50, help="SCHED_FIFO priority of both loops (0: none)")
    ap.add_argument("--step", choices=("compiled", "python"), default="compiled",
                    help="run's step: FastStep (one compiled call) or ReferenceStep (Python around the whole tick)")
    a = ap.parse_args()
    a.priority = a.priority or None
    with tempfile.TemporaryDirectory() as tmp:
        loop, record, device = in_loop(a, Path(tmp))
    runs = [("in the loop", loop), ("back to back", replayed(a, record, device, 0.0, False))]
    for us in a.pauses:
        runs += [(f"{us:g} µs asleep", replayed(a, record, device, 1e-6 * us, False)),
                 (f"{us:g} µs spinning", replayed(a, record, device, 1e-6 * us, True))]
    base = np.median(runs[1][1][:, STEP].sum(1))
    print(f"one tick's parts at {a.rate:g} Hz, p50 [µs] (cpu {a.cpu}, device cpu {a.device_cpu}, SCHED_FIFO "
          f"{a.priority or 'off'}, {a.step} step); step = pre + kernel + post")
    print(f"  {'':18s}" + "".join(f"{p:>7s}" for p in PARTS) + f"{'step':>7s}{'p99':>7s}{'p99.9':>7s}{'/b2b':>7s}")
    for name, out in runs:
        step = out[:, STEP].sum(1)
        print(f"  {name:18s}" + "".join(f"{np.median(out[:, j]) / 1e3:7.1f}" for j in range(len(PARTS)))
              + "".join(f"{np.percentile(step, q) / 1e3:7.1f}" for q in (50, 99, 99.9))
              + f"{np.median(step) / base:6.2f}x")


if __name__ == "__main__":
    main()
