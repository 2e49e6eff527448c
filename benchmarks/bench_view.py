"""Does the browser view disturb the 1 kHz loop? Missed deadlines with and without `rhi.viz.View` attached.

The runtime (`rhi.runtime.run` over `SimLink`, real time, 1 kHz) runs the full ch7 controller of
`bench_runtime.py` (wall rendering, ASO-switched FME matching, ASCM, VME tertiary) in rounds:

- ``none``: no view (the baseline);
- ``thread``: a `View` in the same process polling the loop's `Telemetry` at 45 frames/s, with a
  WebSocket client connected that receives every frame (what a browser tab costs the server);
- ``process``: the same view in its own process (`RemoteView`, fed through `SharedTelemetry`), the
  way `rhi run --view` and `rhi view` attach it.

Rounds alternate (none, thread, process, none, ...) so all see the same machine load. Prints, per mode,
the missed deadlines (% of ticks), p99 of the tick time and the frames per second the client
received, and the ratios against `none` measured in this run. The issue's target is
< 0.1 % missed with the view attached.

    PYTHONPATH=src python benchmarks/bench_view.py [--duration 10] [--rounds 3] [--pin] [--priority 50]

The WebSocket client that stands in for the browser tab runs in its own process, as a browser does.
`--pin` puts the loop on CPU 0 and the view's process and the client on the other CPUs (what
`rhi run --view --cpu 0` does); `--priority` runs the loop under SCHED_FIFO.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time

import numpy as np
from bench_runtime import controller, plant_and_hand

import rhi
from rhi.runtime import SafetyConfig, SimLink, Telemetry, run


def _count(port: int, frames, stop) -> None:
    import viser
    from websockets.sync.client import connect

    ws = connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None)
    while not stop.is_set():
        try:
            ws.recv(timeout=0.2)
            frames.value += 1
        except TimeoutError:
            continue
        except Exception:  # noqa: BLE001 - the server went away
            break
    ws.close()


class FrameCounter:
    """A WebSocket client of the view, in its own process as a browser tab is, counting what the server sends."""

    def __init__(self, port: int, cpus: set[int] | None = None) -> None:
        ctx = mp.get_context("spawn")
        self._frames, self._stop = ctx.Value("q", 0), ctx.Event()
        self.process = ctx.Process(target=_count, args=(port, self._frames, self._stop), daemon=True)
        self.process.start()
        if cpus:
            os.sched_setaffinity(self.process.pid, cpus)

    @property
    def frames(self) -> int:
        return int(self._frames.value)

    def close(self) -> None:
        self._stop.set()
        self.process.join(5)


def one(mode: str, duration: float, pin: bool = False, priority: int | None = None) -> dict:
    others = set(os.sched_getaffinity(0)) - {0} if pin else None  # the view and its client beside the loop's CPU
    dev = rhi.device("rhi4")
    ctrl = controller(dev)
    plant, hand, wall = plant_and_hand(dev, duration)
    view = client = tel = None
    if mode == "thread":
        from rhi.viz.view import View

        tel = Telemetry()
        view = View(dev, tel, virtual=wall, fme=ctrl.schedule[1], q0=plant.q, port=0).start()  # the loop's process
    elif mode == "process":
        from rhi.viz.remote import RemoteView

        view = RemoteView(dev, virtual=wall, fme=ctrl.schedule[1], q0=plant.q, port=0, cpus=others)
        tel = view.telemetry
    if view is not None:
        client = FrameCounter(view.port, others)
        time.sleep(1.0)  # the client's first (scene) messages
        f0 = client.frames
    t0 = time.monotonic()
    try:
        res = run(SimLink(plant, hand=hand), ctrl, duration=duration, virtual=wall, telemetry=tel,
                  safety=SafetyConfig(range_margin=0.3), cpu=0 if pin else None, priority=priority)
    finally:
        wall_s = time.monotonic() - t0
        if view is not None:
            frames = client.frames - f0
            client.close()
            view.close()
    s = res.summary
    return {"missed_pct": s["missed_pct"], "ticks": s["ticks"], "tick_p99_us": 1e6 * s["tick"]["p99"],
            "client_fps": frames / wall_s if view is not None else float("nan"), "fault": s["fault"]}


MODES = ("none", "thread", "process")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=10.0, help="seconds per round")
    ap.add_argument("--rounds", type=int, default=3, help="rounds per mode (alternating)")
    ap.add_argument("--pin", action="store_true", help="the loop on CPU 0; the view and its client on the others")
    ap.add_argument("--priority", type=int, help="SCHED_FIFO priority of the loop (root or CAP_SYS_NICE)")
    a = ap.parse_args()
    out: dict[str, list[dict]] = {k: [] for k in MODES}
    for r in range(a.rounds):
        for mode in MODES:
            res = one(mode, a.duration, a.pin, a.priority)
            out[mode].append(res)
            print(f"  round {r + 1} {mode:>7}: missed {res['missed_pct']:7.3f} %  tick p99 {res['tick_p99_us']:7.0f} µs"
                  + (f"  client {res['client_fps']:5.1f} frames/s" if mode != "none" else "")
                  + (f"  fault: {res['fault']}" if res["fault"] else ""), flush=True)
    m = {k: float(np.mean([r["missed_pct"] for r in v])) for k, v in out.items()}
    p99 = {k: float(np.mean([r["tick_p99_us"] for r in v])) for k, v in out.items()}
    print(f"\nmean of {a.rounds} rounds x {a.duration:g} s (target with the view attached: < 0.1 % missed)")
    for k in MODES:
        fps = np.mean([r["client_fps"] for r in out[k]])
        print(f"  {k:>7}: missed {m[k]:7.3f} % (x{m[k] / max(m['none'], 1e-9):5.2f} of none)   "
              f"tick p99 {p99[k]:7.0f} µs (x{p99[k] / p99['none']:5.2f})" + (f"   {fps:5.1f} frames/s" if k != "none"
                                                                             else ""))


if __name__ == "__main__":
    main()
