"""The allocation protocol: what a torque-allocation strategy provides, and the registry of strategies by name.

Every strategy solves the same problem (thesis §7.3): place ``τ(α, y) = α a + b + Z y`` in
the torque box, with ``a = Jᵀ F_render`` the scalable torque, ``b`` the unscaled one and ``Z``
an orthonormal basis of the null-space torques (`rhi.control.saturation.null_basis`), so the
task force is ``J#ᵀ(α a + b)``. A strategy is an `AllocationMethod`: a name (the
``ControllerConfig(saturation=...)`` string), the readable `allocate` on the basis (the
reference the controller's oracle runs), whether the safety torque acts whatever it holds, and
the code of its branch in the compiled tick (`rhi.control._compiled.step`), or None where every
tick runs through the reference. `Allocator` is the dataclass each strategy module registers.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Protocol

import numpy as np

from rhi.errors import InvalidInput


@dataclasses.dataclass(frozen=True)
class Allocation:
    """A joint-torque allocation within the torque box.

    Attributes:
        tau: (n,) joint torques [N m], within the limits.
        alpha: force scaling α ∈ [0, 1] of the rendered force (eq. 7.9).
        saturated: (n,) bool, the selection matrix 𝒮 of ASCM (joints held at a limit).
        tau_null: (n,) null-space part N τ_N [N m].
        method: name of the strategy that made it ("none", "scaling", "ascm", "lp", ...).
        clipped: whether a last-resort clip to the box was needed (b itself infeasible).
    """

    tau: np.ndarray
    alpha: float
    saturated: np.ndarray
    tau_null: np.ndarray
    method: str
    clipped: bool = False


class AllocationMethod(Protocol):
    """A torque-allocation strategy of the null-space controller (``ControllerConfig.saturation``).

    Attributes:
        name: the ``saturation`` string that selects it.
        safe: the controller's safety torque (null-space damping, joint-limit barriers) acts whatever
            the allocation holds (`rhi.control.safety`); False keeps chapter 6's Algorithm 2 as it is
            (simple scaling, whose FME term and limit barrier balance each other there).
        kernel: code of its branch in the compiled tick (`rhi.control._compiled.step`: NONE, SCALING,
            ASCM, ACTIVE_SET), or None: the controller runs every tick through `rhi.control.reference`.
    """

    @property
    def name(self) -> str:
        """The ``saturation`` string."""
        ...

    @property
    def safe(self) -> bool:
        """Whether the safety torque acts whatever the allocation holds."""
        ...

    @property
    def kernel(self) -> int | None:
        """Code of the compiled tick's branch, or None."""
        ...

    def allocate(self, a: np.ndarray, b: np.ndarray, Z: np.ndarray, *, torque_min: np.ndarray,
                 torque_max: np.ndarray) -> Allocation:
        """The allocation of ``α a + b + Z y`` in the box (a, b: (n,) [N m]; Z: (n, r); limits (n,) [N m])."""
        ...


@dataclasses.dataclass(frozen=True)
class Allocator:
    """An `AllocationMethod` from a function: what each strategy module registers.

    Attributes:
        name: the ``saturation`` string.
        function: ``(a, b, Z, *, torque_min, torque_max) -> Allocation``.
        safe: see `AllocationMethod`.
        kernel: see `AllocationMethod`.
    """

    name: str
    function: Callable[..., Allocation]
    safe: bool = True
    kernel: int | None = None

    def allocate(self, a, b, Z, *, torque_min, torque_max) -> Allocation:
        """``function(a, b, Z, torque_min=..., torque_max=...)``."""
        return self.function(a, b, Z, torque_min=torque_min, torque_max=torque_max)


_METHODS: dict[str, AllocationMethod] = {}


def register(method: AllocationMethod, *, name: str | None = None) -> AllocationMethod:
    """Make `method` selectable as ``ControllerConfig(saturation=name)``; returns it.

    Args:
        method: the strategy.
        name: the ``saturation`` string; default ``method.name``. Another string is an alias of a strategy
            registered under its own name (the one bundled: ``"active_set"``, `rhi.control.allocation.lp`).

    Raises:
        InvalidInput: another strategy already has that name.
    """
    key = method.name if name is None else name
    old = _METHODS.get(key)
    if old is not None and old is not method:
        raise InvalidInput(f"method: an allocation strategy named {key!r} is already registered")
    _METHODS[key] = method
    return method


def method_names() -> tuple[str, ...]:
    """The ``saturation`` strings of the registered strategies (aliases included), in registration order."""
    return tuple(_METHODS)


def allocation_method(saturation: str | AllocationMethod, *, argument: str = "saturation") -> AllocationMethod:
    """The strategy a ``saturation`` setting names (a registered name, or a strategy object itself).

    Raises:
        InvalidInput: an unknown name, naming `argument` and the known names.
    """
    if isinstance(saturation, str):
        method = _METHODS.get(saturation)
        if method is None:
            raise InvalidInput(f"{argument}: expected one of {', '.join(map(repr, _METHODS))}, got {saturation!r}")
        return method
    if not (isinstance(getattr(saturation, "name", None), str) and callable(getattr(saturation, "allocate", None))):
        raise InvalidInput(f"{argument}: expected a strategy name or an AllocationMethod, got {saturation!r:.80}")
    return saturation


__all__ = ["Allocation", "AllocationMethod", "Allocator", "allocation_method", "method_names", "register"]
