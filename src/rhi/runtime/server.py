"""The device side of the protocol: any local link (the MuJoCo plant) served over UDP, with a watchdog.

`DeviceServer` does what a real device's driver does (docs/protocol.md §4): it opens, refuses
or hands over sessions on HELLO and answers INFO, applies the newest valid command of the
session (clamped to the device's torque limits), steps the device at its own rate, sends a
reading every period, and owns a watchdog: no valid command for `watchdog` seconds gives zero
torque and the WATCHDOG flag until the next valid command. An ESTOP command latches zero
torque until RESET; a device fault latches FAULT.

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
from rhi.runtime.realtime import check_realtime, realtime_thread, spin_rest, wait_readable, wait_until
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
        spin: the device loop waits on a busy core, never asleep (`rhi.runtime.realtime.wait_until`).
        cpu_latency: a PM QoS wake-up latency [s] held while serving (`rhi.runtime.realtime.realtime_thread`).
        session_timeout: a session without a valid command for this long [s] ends (another host may then open
            one without TAKEOVER).
    """

    def __init__(self, link: DeviceLink, device, *, host: str = "127.0.0.1", port: int = 0, watchdog: float = 0.02,
                 lockstep: bool = False, drop=None, reorder_at: float | None = None, log=None,
                 exit_on_bye: bool = False, cpu: int | None = None, priority: int | None = None,
                 spin: bool = False, cpu_latency: float | None = None, session_timeout: float = 1.0) -> None:
        check_realtime(cpu, priority, cpu_latency)
        self.cpu, self.priority, self.spin, self.cpu_latency = cpu, priority, bool(spin), cpu_latency
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
        self.session: int | None = None
        self.session_timeout = scalar("session_timeout", session_timeout, positive=True)
        self.n = device.n
        self.stats = {"readings": 0, "commands": 0, "invalid": 0, "foreign": 0, "stale_commands": 0, "refused": 0,
                      "takeovers": 0, "dropped": 0, "watchdog_trips": 0}
        self._cmd_seq: int | None = None  # the last command taken in this session
        self._last_valid = 0.0  # when the session's HELLO or last valid command arrived (monotonic [s])
        self._new = False  # a session opened since the loop last looked
        self._events: list[tuple[str, str]] = []
        self._log_path = log
        self._stop = False
        self._enabled = False
        self.exit_on_bye = exit_on_bye

    def stop(self) -> None:
        """Ask `serve` to return after the current period (thread/signal safe)."""
        self._stop = True

    # ---------------------------------------------------------------- receive
    def _poll(self, timeout: float) -> tuple[int, int, int, np.ndarray] | None:
        """Handle every waiting datagram (waiting up to `timeout` for the first); the newest valid command.

        HELLOs open, refuse or take over sessions (docs/protocol.md §4); a command counts only when it comes from
        the session's host with the session's id and a sequence number newer than the last one taken.
        """
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
                self._hello(pkt, addr)
                continue
            v = P.parse_command(pkt, self.n) if kind == P.COMMAND else None
            if v is None or addr != self.client or v[0] != self.session:
                self.stats["invalid" if v is None else "foreign"] += 1
                continue
            _, seq, ack, flags, _, tau = v
            if self._cmd_seq is not None and not P.newer(seq, self._cmd_seq):
                self.stats["stale_commands"] += 1  # a duplicate or an older command: ignored
                continue
            self._cmd_seq = seq
            self.stats["commands"] += 1
            self._last_valid = time.monotonic()
            newest = (seq, ack, flags, tau)
            if flags & P.BYE:  # the session ends now: a HELLO in this same drain may open the next one
                self._end()

    def _hello(self, pkt: bytes, addr) -> None:
        """Open, repeat, refuse or take over a session (docs/protocol.md §4)."""
        if P.version(pkt) == P.V1_0:
            self.stats["refused"] += 1
            self.sock.sendto(P.error_v1_0(f"protocol v1.0 is not served: this device speaks v{P.NAME} (wire version "
                                          f"{P.VERSION}, docs/protocol.md); update the host"), addr)
            return
        h = P.parse_hello(pkt)
        if isinstance(h, str):
            self.stats["refused"] += 1
            self.sock.sendto(P.error(P.E_VERSION if P.version(pkt) != P.VERSION else P.E_HELLO, 0, h), addr)
            return
        session, flags = h
        if session == self.session and addr == self.client:
            self.sock.sendto(self._info(), addr)  # a repeated HELLO: INFO again, nothing resets
            return
        old = self.client
        if old is not None and self.session is not None and time.monotonic() - self._last_valid <= self.session_timeout:
            if not flags & P.TAKEOVER:
                self.stats["refused"] += 1
                self.sock.sendto(P.error(P.E_BUSY, session, f"device busy: a session of {old[0]}:{old[1]} is active; "
                                         "HELLO with TAKEOVER ends it"), addr)
                return
            self.stats["takeovers"] += 1
            self.sock.sendto(P.error(P.E_SESSION_LOST, self.session, f"the device was taken over by {addr[0]}:"
                                     f"{addr[1]}"), old)
            self._events.append(("takeover", f"session of {old[0]}:{old[1]} taken over by {addr[0]}:{addr[1]}: "
                                 "zero torque"))
        self.client, self.session, self._new = addr, session, True
        self._cmd_seq, self._last_valid = None, time.monotonic()
        self.sock.sendto(self._info(), addr)

    def _end(self) -> None:
        """End the session (BYE, session timeout): no more readings until the next HELLO."""
        self.client = self.session = None

    def _info(self) -> bytes:
        r = self.link.read()
        sensors = [(k, int(np.size(v))) for k, v in r.sensors.items()]
        self._sensors = [k for k, _ in sensors]
        return P.info(self.n, sensors, self.rate, self.watchdog,
                      {"device": self.device.name, "joint_names": list(self.device.joint_names),
                       "torque_min": self.lo.tolist(), "torque_max": self.hi.tolist(), "lockstep": self.lockstep},
                      self.session or 0)

    # ------------------------------------------------------------------ serve
    def serve(self, duration: float | None = None) -> dict:
        """Run the device until `duration` [s] of device time, `stop()`, or a BYE from the client.

        Returns the statistics (readings sent, commands, invalid datagrams, watchdog trips ...).
        """
        period = 1.0 / self.rate
        lw = LogWriter(layout(self.n, getattr(self.device, "m", 0)), self._log_path,
                       meta={"device": self.device.name, "rate": self.rate, "source": "device-server"})
        c = lw.cols
        zero = np.zeros(self.n)
        tau, last_cmd = zero, None
        estop = fault = watchdog = False
        held = None
        self._info()  # sensor layout
        k = rseq = 0
        end = None if duration is None else int(round(duration * self.rate))
        try:
            with realtime_thread(self.cpu, self.priority, self.cpu_latency):
                rest = spin_rest(self.spin)
                # the first reading goes out as soon as a client said HELLO
                while self.client is None and not self._stop:
                    self._poll(0.05)
                t0, k0 = time.monotonic(), 0
                while not self._stop and (end is None or k < end):
                    r = self.link.read()
                    for kind, detail in self._events:
                        lw.event(r.t, kind, detail, k)
                    self._events.clear()
                    if self._new:  # a new session: readings from 0, nothing echoed, watchdog disarmed, zero torque
                        self._new, rseq, tau, last_cmd, watchdog, self._enabled = False, 0, zero, None, False, False
                        lw.event(r.t, "session", f"session {self.session or 0:016x} of {self.client}", k)
                    status = int(r.status) & Status.SIMULATED
                    if r.status & Status.FAULT and not fault:
                        fault = True
                        lw.event(r.t, "fault", f"device fault: {r.detail}", k)
                    enabled = last_cmd is not None and not (watchdog or estop or fault) and self._enabled
                    status |= (Status.ENABLED if enabled else 0) | (Status.WATCHDOG if watchdog else 0) \
                        | (Status.ESTOP if estop else 0) | (Status.FAULT if fault else 0)
                    echo = P.NO_SEQ if self._cmd_seq is None else self._cmd_seq
                    pkt = P.reading(self.session or 0, rseq, echo, status, r.t,
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
                        while got is None and (time.monotonic() < wait_end or last_cmd is None) and not self._stop \
                                and not self._new:
                            got = self._poll(max(wait_end - time.monotonic(), 0.0))
                            if got is not None and got[1] != P.NO_SEQ and not P.newer(got[1], rseq - 2) \
                                    and not got[2] & P.BYE:
                                got = None  # a stale command from before the previous reading
                    else:
                        wait_until(deadline - 2e-4, self.spin, rest)
                        got = self._poll(max(deadline - time.monotonic(), 0.0))
                    rseq = (rseq + 1) & P.NO_SEQ
                    now = time.monotonic()
                    if self._new:
                        got = None  # a takeover in this period: the new session starts at the next one
                    if got is not None:
                        seq, ack, flags, tau_cmd = got
                        last_cmd = now
                        if flags & P.BYE:
                            lw.event(r.t, "bye", "the host closed the link: zero torque", k)
                            self._enabled, tau, last_cmd = False, zero, None
                            self.link.write(tau, enable=False)
                            if self.exit_on_bye:
                                break
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
                        tau = np.minimum(np.maximum(tau_cmd, self.lo), self.hi)
                    elif last_cmd is not None and not watchdog and now - last_cmd > self.watchdog:
                        watchdog = True
                        self.stats["watchdog_trips"] += 1
                        lw.event(r.t, "watchdog", f"no valid command for {1e3 * (now - last_cmd):.1f} ms "
                                 f"(watchdog {1e3 * self.watchdog:g} ms): zero torque", k)
                    on = last_cmd is not None and self._enabled and not (watchdog or estop or fault or self._new)
                    apply = tau if on else zero
                    ts = time.monotonic()
                    self.link.write(apply, enable=on)
                    row = lw.row()
                    row[c["t"]], row[c["q"]], row[c["dq"]], row[c["tau"]] = r.t, r.q, r.dq, apply
                    row[c["seq"]] = -1 if echo == P.NO_SEQ else echo
                    row[c["wall"]], row[c["t_write"]] = ts - t0, time.monotonic() - ts
                    row[c["late"]] = max(0.0, now - deadline) if not self.lockstep else 0.0
                    row[c["safety"]] = float(status & ~int(Status.SIMULATED) & ~int(Status.ENABLED))
                    if "ft" in r.sensors:
                        row[c["ft"]] = r.sensors["ft"]
                    k += 1
                    if self.client is not None and now - self._last_valid > self.session_timeout:
                        lw.event(r.t, "session_timeout", f"no valid command for {self.session_timeout:g} s: "
                                 "session ended", k)
                        self._end()
                        self._enabled, tau, last_cmd = False, zero, None
                        while self.client is None and not self._stop:
                            self._poll(0.05)
                        t0, k0 = time.monotonic(), k
                        continue
                    if not self.lockstep:
                        wait_until(t0 + (k - k0) * period, self.spin, rest)
        finally:
            self.link.write(zero, enable=False)
            for kind, detail in self._events:
                lw.event(float("nan"), kind, detail, k)
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
