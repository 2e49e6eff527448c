"""Types of the `rhi` command's flags: each refuses a bad value with argparse's clean one-line error (exit 2).

Ports, hosts, durations, rates, angles, counts and lists of numbers are checked when the command line is read,
before any work starts; `Parser` prints one line (no usage block) for every error.
"""

from __future__ import annotations

import argparse
import ipaddress
import math
import re
from typing import NoReturn


class Parser(argparse.ArgumentParser):
    """An `argparse.ArgumentParser` whose errors are one line: ``prog: error: message`` (exit status 2)."""

    def error(self, message: str) -> NoReturn:
        """Print the error on one line and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message}\n")


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def finite(text: str) -> float:
    """A finite real number."""
    v = _number(text)
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return v


def positive(text: str) -> float:
    """A finite number > 0 (a duration [s], a rate [Hz])."""
    v = finite(text)
    if not v > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return v


def duration(text: str) -> float:
    """A duration [s] > 0 and at most `rhi._validate.MAX_DURATION` (1e6 s, as `rhi.runtime.run` accepts)."""
    from rhi._validate import MAX_DURATION

    v = positive(text)
    if v > MAX_DURATION:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_DURATION:g} s, got {text!r}")
    return v


def rate(text: str) -> float:
    """A loop rate [Hz] in [10, 100 000] (the plausibility bounds of a configuration's ``[run] rate``)."""
    v = finite(text)
    if not 10.0 <= v <= 1e5:
        raise argparse.ArgumentTypeError(f"must be in [10, 100000] Hz, got {text!r}")
    return v


def watchdog_ms(text: str) -> float:
    """A watchdog time [ms] > 0 and at most 10 000 (a longer one guards nothing)."""
    v = positive(text)
    if v > 10_000:
        raise argparse.ArgumentTypeError(f"must be at most 10000 ms, got {text!r}")
    return v


def elevation(text: str) -> float:
    """A camera elevation [deg] in [-90, 90]."""
    v = finite(text)
    if not -90.0 <= v <= 90.0:
        raise argparse.ArgumentTypeError(f"must be in [-90, 90] degrees, got {text!r}")
    return v


def nonnegative(text: str) -> float:
    """A finite number >= 0."""
    v = finite(text)
    if not v >= 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return v


def _integer(text: str, least: int, most: int | None = None) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if v < least or (most is not None and v > most):
        raise argparse.ArgumentTypeError(f"must be in {least}..{most if most is not None else ''}, got {v}")
    return v


def count(text: str) -> int:
    """An integer >= 1 (jobs, workers)."""
    return _integer(text, 1)


def cpu_latency(text: str) -> float:
    """A wake-up latency in µs, 0..1 000 000, returned in seconds (`rhi.runtime.run`'s `cpu_latency`)."""
    v = finite(text)
    if not 0.0 <= v <= 1e6:
        raise argparse.ArgumentTypeError(f"must be between 0 and 1000000 µs, got {text!r}")
    return v * 1e-6


def cpu(text: str) -> int:
    """A CPU number (>= 0)."""
    return _integer(text, 0)


def priority(text: str) -> int:
    """A SCHED_FIFO priority, 1..99."""
    return _integer(text, 1, 99)


def pixels(text: str) -> int:
    """An image size [px], 1..8192."""
    return _integer(text, 1, 8192)


def port(text: str) -> int:
    """A TCP/UDP port, 0..65535 (0: any free port)."""
    return _integer(text, 0, 65535)


_LABEL = re.compile(r"^(?!-)[A-Za-z0-9-]{1,63}(?<!-)$")


def host(text: str) -> str:
    """An address to listen on: an IPv4 or IPv6 address or a host name (RFC 1123) of this machine.

    A dotted quad must be a valid IPv4 address, and the address must be one this machine can bind
    (checked with a throwaway socket), so that a server never starts on an address it cannot serve.
    """
    import socket

    try:
        ipaddress.ip_address(text)
    except ValueError:
        labels = text.rstrip(".").split(".")
        if (len(text) > 253 or not all(_LABEL.match(x) for x in labels)
                or all(x.isdigit() for x in labels)):  # 256.0.0.1: a malformed address, not a name
            raise argparse.ArgumentTypeError(f"expected an IP address or a host name, got {text!r}") from None
    try:
        family, kind, proto, _, addr = socket.getaddrinfo(text, 0, type=socket.SOCK_STREAM)[0]
        with socket.socket(family, kind, proto) as s:
            s.bind(addr)
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"cannot listen on {text!r} ({exc.strerror or exc})") from None
    return text


def floats(text: str) -> list[float]:
    """Finite numbers separated by commas or spaces, e.g. ``0.1,-0.2``."""
    try:
        vals = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected numbers separated by commas or spaces, got {text!r}") from None
    if not vals or not all(map(math.isfinite, vals)):
        raise argparse.ArgumentTypeError(f"expected finite numbers separated by commas or spaces, got {text!r}")
    return vals
