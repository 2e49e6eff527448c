"""The device side of the protocol: any local link (the MuJoCo plant) served over UDP, with a watchdog.

`DeviceServer` does what a real device's driver does (docs/protocol.md §5): it answers HELLO
with INFO, applies the newest valid command (clamped to the device's torque limits), steps the
device at its own rate, sends a reading every period, and owns a watchdog: no valid command
for `watchdog` seconds gives zero torque and the WATCHDOG flag until the next valid command.
An ESTOP command latches zero torque until RESET; a device fault latches FAULT.

`lockstep=True` is for tests and studies that must equal `rhi.sim.simulate` bit for bit: after
each reading the device waits (up to the watchdog time) for the command answering it instead
of free-running on its clock.
"""

from __future__ import annotations

import socket
import time

import numpy as np

from rhi._validate import scalar
from rhi.errors import InvalidInput
from rhi.runtime import protocol as P
from rhi.runtime.link import DeviceLink, Status
from rhi.runtime.loop import _realtime, check_realtime, wait_readable, wait_until
from rhi.sim.log import LogWriter, layout


class DeviceServer:
    """Serve `link` on UDP `host:port`.

    Args:
        link: the local device (e.g. `SimLink`); its `rate` is the device rate.
        device: the device model (torque limits for the device-side clamp).
        host, port: where to listen (port 0: any free port; see `port` after construction).
        watchdog: longest time without a valid command before zero torque [s] (default 20 ms).
        lockstep: wait for the command answering each reading (deterministic; simulation only).
        drop: (start, end) device-time window [s] in which readings are not sent (fault injection).
        reorder_at: device time [s] at which one reading is held back and sent after the next.
        log: a ``.rhilog`` path for the device-side log (applied torque, status in `safety`, events).
        exit_on_bye: return from `serve` when the host closes the link (else idle until the next HELLO).
        cpu: pin the device loop to this CPU (a clear warning where the OS refuses).
        priority: SCHED_FIFO priority (1–99) of the device loop (a clear warning where the OS refuses).
        spin: the device loop waits on a busy core, never asleep (`rhi.runtime.loop.wait_until`).
    """

    def __init__(self, link: DeviceLink, device, *, host: str = "127.0.0.1", port: int = 0, watchdog: float = 0.02,
                 lockstep: bool = False, drop=None, reorder_at: float | None = None, log=None,
                 exit_on_bye: bool = False, cpu: int | None = None, priority: int | None = None,
                 spin: bool = False) -> None:
        check_realtime(cpu, priority)
        self.cpu, self.priority, self.spin = cpu, priority, bool(spin)
        if not isinstance(port, int) or not 0 <= port < 65536:
            raise InvalidInput(f"port: expected an integer in 0..65535, got {port!r}")
        self.link, self.device = link, device
        self.rate = float(getattr(link, "rate", 1000.0))
        self.watchdog, self.lockstep = scalar("watchdog", watchdog, positive=True), bool(lockstep)
        self.drop, self.reorder_at = drop, reorder_at
        self.lo = np.asarray(device.torque_min, float)
        self.hi = np.asarray(device.torque_max, float)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            raise InvalidInput(f"port: cannot listen on {host}:{port}: {exc}") from None
        self.port = self.sock.getsockname()[1]
        self.client: tuple[str, int] | None = None
        self.n = device.n
        self.stats = {"readings": 0, "commands": 0, "invalid": 0, "refused": 0, "dropped": 0, "watchdog_trips": 0}
        self._log_path = log
        self._stop = False
        self._enabled = False
        self.exit_on_bye = exit_on_bye

    def stop(self) -> None:
        """Ask `serve` to return after the current period (thread/signal safe)."""
        self._stop = True

    # ---------------------------------------------------------------- receive
    def _poll(self, timeout: float) -> tuple[int, int, int, np.ndarray] | None:
        """Handle every waiting datagram (waiting up to `timeout` for the first); the newest valid command."""
        newest = None
        s = self.sock
        while True:
            if timeout > 0:
                if not wait_readable(s, timeout, self.spin):
                    return newest
                timeout = 0.0
            try:
                pkt, addr = s.recvfrom(65536, socket.MSG_DONTWAIT)
            except BlockingIOError:
                return newest
            except OSError:
                continue  # ICMP from a client that went away
            kind = P.kind(pkt)
            if kind == P.HELLO:
                if P.version(pkt) != P.VERSION:
                    self.stats["refused"] += 1
                    s.sendto(P.error(f"protocol version {P.version(pkt)} not supported; this device speaks "
                                     f"{P.VERSION}"), addr)
                    continue
                self.client = addr
                s.sendto(self._info(), addr)
                continue
            if kind == P.COMMAND and addr == self.client:
                v = P.parse_command(pkt, self.n)
                if v is None:
                    self.stats["invalid"] += 1
                    continue
                self.stats["commands"] += 1
                newest = (v[0], v[1], v[2], v[4])
            else:
                self.stats["invalid"] += 1

    def _info(self) -> bytes:
        r = self.link.read()
        sensors = [(k, int(np.size(v))) for k, v in r.sensors.items()]
        self._sensors = [k for k, _ in sensors]
        return P.info(self.n, sensors, self.rate, self.watchdog,
                      {"device": self.device.name, "joint_names": list(self.device.joint_names),
                       "torque_min": self.lo.tolist(), "torque_max": self.hi.tolist()})

    # ------------------------------------------------------------------ serve
    def serve(self, duration: float | None = None) -> dict:
        """Run the device until `duration` [s] of device time, `stop()`, or a BYE from the client.

        Returns the statistics (readings sent, commands, invalid datagrams, watchdog trips ...).
        """
        period = 1.0 / self.rate
        lw = LogWriter(layout(self.n, getattr(self.device, "m", 0)), self._log_path,
                       meta={"device": self.device.name, "rate": self.rate, "source": "device-server"})
        c = lw.cols
        tau, cmd_seq, last_cmd = np.zeros(self.n), -1, None
        estop = fault = False
        watchdog = False
        held = None
        self._info()  # sensor layout
        k = 0
        end = None if duration is None else int(round(duration * self.rate))
        try:
            with _realtime(self.cpu, self.priority, self.spin):
                # the first reading goes out as soon as a client said HELLO
                while self.client is None and not self._stop:
                    self._poll(0.05)
                t0, k0 = time.monotonic(), 0
                while not self._stop and (end is None or k < end):
                    r = self.link.read()
                    status = int(r.status) & Status.SIMULATED
                    if r.status & Status.FAULT and not fault:
                        fault = True
                        lw.event(r.t, "fault", f"device fault: {r.detail}", k)
                    enabled = last_cmd is not None and not (watchdog or estop or fault) and self._enabled
                    status |= (Status.ENABLED if enabled else 0) | (Status.WATCHDOG if watchdog else 0) \
                        | (Status.ESTOP if estop else 0) | (Status.FAULT if fault else 0)
                    pkt = P.reading(r.seq, cmd_seq, status, r.t,
                                    r.q, r.dq, np.concatenate([np.ravel(r.sensors[s]) for s in self._sensors]))
                    if self.drop is not None and self.drop[0] <= r.t < self.drop[1]:
                        self.stats["dropped"] += 1
                    elif self.reorder_at is not None and held is None and r.t >= self.reorder_at:
                        held, self.reorder_at = pkt, None
                    else:
                        self._send(pkt)
                        if held is not None:
                            self._send(held)
                            held = None
                    # wait for (lockstep) or collect (free-running) commands until the next period
                    deadline = t0 + (k - k0 + 1) * period
                    got = None
                    if self.lockstep:
                        wait_end = time.monotonic() + self.watchdog
                        while got is None and (time.monotonic() < wait_end or last_cmd is None) and not self._stop:
                            got = self._poll(max(wait_end - time.monotonic(), 0.0))
                            if got is not None and got[1] != P.NO_SEQ and got[1] < r.seq - 1:
                                got = None  # a stale command from before the previous reading
                    else:
                        wait_until(deadline - 2e-4, self.spin)
                        got = self._poll(max(deadline - time.monotonic(), 0.0))
                    now = time.monotonic()
                    if got is not None:
                        seq, ack, flags, tau_cmd = got
                        last_cmd = now
                        if flags & P.BYE:
                            lw.event(r.t, "bye", "the host closed the link: zero torque", k)
                            self._enabled, tau, last_cmd = False, np.zeros(self.n), None
                            self.link.write(tau, enable=False)
                            if self.exit_on_bye:
                                break
                            self.client = None
                            while self.client is None and not self._stop:  # idle until the next HELLO
                                self._poll(0.05)
                            t0, k0 = time.monotonic(), k
                            continue
                        if flags & P.ESTOP and not estop:
                            estop = True
                            lw.event(r.t, "estop", "e-stop requested by the host", k)
                        if flags & P.RESET:
                            estop = False
                        if watchdog:
                            lw.event(r.t, "watchdog_clear", "valid command received; watchdog cleared", k)
                        watchdog = False
                        self._enabled = bool(flags & P.ENABLE)
                        cmd_seq = seq
                        tau = np.minimum(np.maximum(tau_cmd, self.lo), self.hi)
                    elif last_cmd is not None and not watchdog and now - last_cmd > self.watchdog:
                        watchdog = True
                        self.stats["watchdog_trips"] += 1
                        lw.event(r.t, "watchdog", f"no valid command for {1e3 * (now - last_cmd):.1f} ms "
                                 f"(watchdog {1e3 * self.watchdog:g} ms): zero torque", k)
                    on = last_cmd is not None and self._enabled and not (watchdog or estop or fault)
                    apply = tau if on else np.zeros(self.n)
                    ts = time.monotonic()
                    self.link.write(apply, enable=on)
                    row = lw.row()
                    row[c["t"]], row[c["q"]], row[c["dq"]], row[c["tau"]] = r.t, r.q, r.dq, apply
                    row[c["seq"]], row[c["wall"]], row[c["t_write"]] = cmd_seq, ts - t0, time.monotonic() - ts
                    row[c["late"]] = max(0.0, now - deadline) if not self.lockstep else 0.0
                    row[c["safety"]] = float(status & ~int(Status.SIMULATED) & ~int(Status.ENABLED))
                    if "ft" in r.sensors:
                        row[c["ft"]] = r.sensors["ft"]
                    k += 1
                    if not self.lockstep:
                        wait_until(t0 + (k - k0) * period, self.spin)
        finally:
            self.link.write(np.zeros(self.n), enable=False)
            lw.close()
            self.sock.close()
        self.stats["ticks"] = k
        return dict(self.stats)

    def _send(self, pkt: bytes) -> None:
        if self.client is None:  # no host has said HELLO yet
            return
        try:
            self.sock.sendto(pkt, self.client)
            self.stats["readings"] += 1
        except OSError:
            pass  # the client is gone: the watchdog will trip
