"""One exception hierarchy for rhi.

Every error names the offending argument and what was wrong with it. Each class
also derives from the matching built-in exception so generic handlers still work.
"""

from __future__ import annotations


class RhiError(Exception):
    """Base class of every error raised by rhi."""


class InvalidInput(RhiError, ValueError):
    """An argument has the wrong shape, a non-finite value or an invalid value."""


class NotSPD(InvalidInput):
    """A matrix that must be symmetric positive definite is not."""


class InfeasibleLimits(InvalidInput):
    """Limits are inconsistent (e.g. a minimum above its maximum)."""


class UnknownDevice(RhiError, KeyError):
    """No bundled device has the requested name."""

    def __str__(self) -> str:  # KeyError would print the repr of the message
        return str(self.args[0]) if self.args else ""


class ModelError(RhiError):
    """A robot description (URDF or device file) is malformed or inconsistent."""


class Unreachable(RhiError):
    """An inverse-kinematics target lies outside the reachable workspace."""


class Singular(RhiError, ArithmeticError):
    """A Jacobian or inertia matrix is singular where an inverse is required."""


class LinkError(RhiError, ConnectionError):
    """A device link failed: the device is unreachable or silent, or it speaks another protocol version."""


class RouteWarning(UserWarning):
    """A controller that asked for the compiled tick runs a slower route (`rhi.control.compiled.Route` says why)."""
