"""`supervise`: runs under a browser view's control — faults shown and reset, pause and resume.

`rhi.runtime.run` ends at the first fault with zero torque (the safety layer latches). Under a view,
the user should see why, and go on: `supervise` runs the loop again and again. A fault's kind, reason
and device time go to the terminal and to the view's status line; the view's reset button re-arms a
fresh safety layer and restarts from the configuration's start (`restart` rebuilds the link: the
plant at q0, the mouse hand released); pause ends the current run with zero torque (an e-stop named
"paused in the view") and resume starts the next one where the device is. Ctrl-C, SIGTERM or the
end of `duration` end the session.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from rhi._lifetime import STOP_SIGNALS
from rhi.runtime import RunResult, Safety, SafetyConfig
from rhi.viz.commands import ViewCommands

PAUSE = "paused in the view"
RESET = "reset in the view"
STOP = "session stopped in the view"


def _watch(commands: ViewCommands, guard: Safety, resets: int, done: threading.Event, asked: list[str]) -> None:
    """Say "live" at the run's first checked reading; turn the view's pause and reset into an e-stop (50 Hz)."""
    live = False
    while not done.wait(0.02):
        if not live and guard.last_t is not None:
            live = True
            commands.set_status("live")
        if commands.stopped or commands.resets != resets or commands.paused:
            asked.append(STOP if commands.stopped else RESET if commands.resets != resets else PAUSE)
            guard.estop(asked[0])
            return


def supervise(run_once: Callable[[Safety, float | None], RunResult], commands: ViewCommands, device,
              restart: Callable[[], None], *, config: SafetyConfig | None = None, duration: float | None = None,
              say: Callable[[str], None] = print, poll: float = 0.05) -> list[RunResult]:
    """Run `run_once(safety, duration_left)` until the duration is used up or the user stops the session.

    Args:
        run_once: one `rhi.runtime.run` with the given `Safety` and duration [s] (None: unbounded).
        commands: the view's `ViewCommands` (pause, reset; the status line is written here).
        device: the model the safety layer checks against.
        restart: put the device back at its configuration's start (a fresh simulated link, the hand let go).
        config: the safety limits.
        duration: total run time over all runs [s] (device time); None: until Ctrl-C.
        say: where a fault's line goes (the terminal).
        poll: how often a paused or faulted session looks for the user's resume or reset [s].

    Returns:
        The results of every run, in order.
    """
    results: list[RunResult] = []
    left = duration
    resets = commands.resets
    while left is None or left > 0:
        guard = Safety(device, config)
        done, asked = threading.Event(), list[str]()
        watcher = threading.Thread(target=_watch, args=(commands, guard, resets, done, asked), daemon=True,
                                   name="rhi-view-commands")
        # "live" only once the run has ticked (the watcher says it): until then the run loads its kernels
        commands.set_status("starting …" if not results else "restarting …")
        watcher.start()
        try:
            try:
                res = run_once(guard, left)
            finally:
                done.set()
                watcher.join()
        except BaseException as exc:  # the session ends: the page must not keep saying "starting" or "live"
            commands.set_status(f"stopped: {type(exc).__name__}: {exc}")
            raise
        results.append(res)
        log = res.log
        if left is not None and len(log):
            left -= float(log.t[-1] - log.t[0]) + 1.0 / res.summary.get("rate", 1000.0)
        fault, kind = res.fault, res.summary.get("fault_kind")
        if fault is None:
            break  # the duration ran out
        ours = kind == "estop" and bool(asked) and asked[0] in fault
        if (kind == "estop" and not ours) or (ours and asked[0] == STOP):
            commands.set_status(f"stopped: {fault}")
            break  # Ctrl-C, SIGTERM, the page's stop: the session ends
        if ours and asked[0] == PAUSE:
            commands.set_status("paused (press resume)")
            while commands.paused and commands.resets == resets and not commands.stopped and not STOP_SIGNALS:
                time.sleep(poll)
        else:
            t = float(log.t[-1]) if len(log) else 0.0
            if not ours:
                line = f"fault ({kind}) at t = {t:.3f} s: {fault}"
                say(f"rhi view: {line} — press reset in the view to re-arm and restart")
                commands.set_status(f"{line} — press reset")
                while commands.resets == resets and not commands.stopped and not STOP_SIGNALS:
                    time.sleep(poll)  # a stop signal (rhi._lifetime) goes on: the next run e-stops at once
        if commands.stopped:
            commands.set_status("stopped in the view")
            break
        if commands.resets != resets:
            resets = commands.resets
            restart()
            say("rhi view: reset — safety re-armed, restarted from the start")
    return results
