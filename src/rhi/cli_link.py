"""What the commands that drive a device share: the link of `--link`, the status line, output checks, real-time flags.

Used by `rhi run` and `rhi device-server` (`rhi.cli`) and `rhi identify` (`rhi.cli_identify`).
"""

from __future__ import annotations

import time

from rhi import cli_args as A, plugins
from rhi.errors import InvalidInput

#: the device side of a run configuration needs no [controller] (`rhi device-server`; `rhi identify`, whose
#: programme is the controller)
NO_CONTROLLER = {"controller": {"primary": {"law": "force_rendering"}}}


def link(url: str, rate: float, cfg, realtime: bool, spin: bool = False, device_name: str | None = None,
          takeover: bool = False):
    """The device link of `--link`: "sim" (the configuration's simulated device) or udp://HOST:PORT.

    In real time a tick waits at most one period for a reading; without (`--fast`, e.g. against a lock-step
    device server) a reading may take up to 1 s and the device 10 s to answer.
    """
    if url == "sim":
        return cfg.sim_link(rate=rate)
    if not url.startswith("udp://"):  # a plugin's scheme (rhi.plugins, rhi.links)
        return plugins.link(url, rate=rate, config=cfg, realtime=realtime)
    from rhi.runtime.udp import UDPLink, parse_url

    try:
        host, port = parse_url(url)
    except InvalidInput as exc:
        raise InvalidInput(f"--link: {exc}") from None
    link = UDPLink(host, port, rate=rate, spin=spin, timeout=1.0 / rate, takeover=takeover) if realtime else \
        UDPLink(host, port, rate=rate, timeout=1.0, connect_timeout=10.0, spin=spin, takeover=takeover)
    return SameDevice(link, cfg.device, device_name)


class SameDevice:
    """A link whose `open` also checks the device against the configuration's (a refusal says BYE).

    Its motors, and its INFO "device" name: the configuration's device, or `name` (`--device-name`).
    """

    def __init__(self, link, device, name: str | None = None) -> None:
        self._link, self._device, self._name = link, device, name

    def __getattr__(self, name: str):
        return getattr(self._link, name)

    def open(self) -> None:
        """Open the link; refuse (BYE) a device whose motors or name differ from the configuration's."""
        self._link.open()
        info, dev = self._link.info, self._device
        name, want = info.get("device"), self._name or dev.name
        if self._link.n != dev.n:
            self._link.refuse(f"the device has {self._link.n} motors, the configuration's {dev.name!r} has {dev.n}")
        if name != want:
            self._link.refuse(f"the device calls itself {name!r}, the configuration controls {dev.name!r}; if it is "
                              f"that device, accept its name with --device-name {name}")


class Status:
    """The live status line: rewritten in place on a terminal, one line every `every` seconds when piped."""

    def __init__(self, stream, limit: float | None, every: float = 5.0) -> None:
        self.stream, self.tty, self.every = stream, stream.isatty(), every
        self.limit, self.clock = limit, time.monotonic
        self.t0 = self.last = self.clock()
        self.k0 = 0
        self.width = 0

    def __call__(self, s: dict) -> None:
        """Show the run's status `s` (`rhi.runtime.run`'s progress callback)."""
        now = self.clock()
        if not self.tty and now - self.last < self.every:
            return
        rate = (s["ticks"] - self.k0) / max(now - self.last, 1e-9)
        self.last, self.k0 = now, s["ticks"]
        end = f"/{self.limit:g}" if self.limit else ""
        line = (f"t {s['t']:8.2f}{end} s  rate {rate:7.1f} Hz  missed {s['missed']}  "
                f"max|τ|/limit {s['max_torque_ratio']:.2f}  V {s['V']:.3f}  fault {s['fault'] or '-'}")
        if self.tty:
            self.stream.write("\r" + line.ljust(self.width))
            self.width = len(line)
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self) -> None:
        """End the rewritten line (on a terminal)."""
        if self.tty and self.width:
            self.stream.write("\n")
            self.stream.flush()


def add_realtime(p, what: str) -> None:
    """Add --cpu, --priority, --cpu-latency and --spin for `what` (e.g. "the control loop") to parser `p`."""
    p.add_argument("--cpu", type=A.cpu, help=f"pin {what} to this CPU (e.g. one no other busy process uses)")
    p.add_argument("--priority", type=A.priority, help=f"SCHED_FIFO priority 1..99 of {what} (needs CAP_SYS_NICE "
                   "or an rtprio limit; a warning otherwise)")
    p.add_argument("--cpu-latency", type=A.cpu_latency, metavar="US",
                   help=f"while {what} runs, keep every core's wake-up under US µs (Linux PM QoS, /dev/cpu_dma_latency; "
                   "0: no deep idle state between ticks; needs root, a warning otherwise)")
    p.add_argument("--spin", action="store_true", help=f"{what} waits for each tick on a busy core instead of "
                   "asleep: steadier, shorter ticks for one core at 100 %% (use with --cpu)")
