"""How a concept tells the compiled tick what it is, and which route a controller's tick takes.

The compiled tick (`rhi.control.tick`) does not recognise types: it asks each primary law and each
objective for its ``compiled(device)`` form — a `CompiledLaw` or a `CompiledObjective`, one of the kinds
its kernels compute, or None — and computes in Python what answers None (or has no ``compiled``).
A user's objective without ``compiled`` runs on the composed route (its gradient in Python each tick);
the controller says so (`NullSpaceController.route`) and warns once (`RouteWarning`).

The routes, fastest first:

- ``"whole"``: the whole tick in one compiled call (device terms, primary law, steps 2–6, passivity);
- ``"composed"``: `Device.terms` and the primary law's ``forces`` in Python, objectives without a
  compiled form by their ``gradient_at`` in Python, steps 2–6 compiled;
- ``"reference"``: every tick in `rhi.control.reference` (asked for, an allocation without a compiled
  branch, or a scheduled objective without a compiled form, `rhi.control.schedule`).
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Callable
from typing import Literal

import numpy as np

from rhi.errors import RouteWarning


@dataclasses.dataclass(frozen=True, eq=False)
class CompiledLaw:
    """A primary law as the compiled whole tick computes it (the laws of `rhi.control.primary`).

    Attributes:
        kind: "force" (`ForceRendering`), "spring" (`SpringPalpation`) or "free" (`ImpedanceControl` without
            a desired inertia).
        damping: (m, m) task damping B [N s/m].
        gain: force gain (1 but for "force").
        coriolis: compensate the task-space Coriolis force.
        gravity: compensate G_x.
        viscous: (n,) joint viscous friction compensated [N m s/rad], or None without friction.
        coulomb: (n,) joint Coulomb friction compensated [N m], or None.
        velocity_scale: velocity of the Coulomb term's smooth sign [rad/s].
        stiffness: spring stiffness [N/m] ("spring").
        x0: (m,) spring rest position [m] ("spring"), else None.
        normal: (m,) the spring's unit normal, or None (every direction).
    """

    kind: Literal["force", "spring", "free"]
    damping: np.ndarray
    gain: float = 1.0
    coriolis: bool = True
    gravity: bool = True
    viscous: np.ndarray | None = None
    coulomb: np.ndarray | None = None
    velocity_scale: float = 0.0
    stiffness: float = 0.0
    x0: np.ndarray | None = None
    normal: np.ndarray | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class CompiledObjective:
    """An objective as the compiled tick computes it.

    Attributes:
        kind: "vme" (JBLD matching of J Jᵀ to `desired`, eqs. 3.22–3.23; both compiled routes), "fme"
            (JBLD matching of the torque-weighted FME to `desired`, eqs. 6.9–6.10, with weights `w2`, fixed or,
            with `live`, the one `live()` gives at each tick; the whole tick), "fme_schedule" (a scheduled
            objective, `rhi.control.schedule`: FME matching to Ω `desired` + (1 − Ω) `stiff` with the controller's
            torque weights, Ω from the ASO by `schedule`,
            eqs. 6.14–6.19; both compiled routes), "barrier" (`rhi.control.JointLimitBarrier` with `barrier`;
            the whole tick), "vme_live" (JBLD matching of J^q J^qᵀ to the (m, m) SPD desired that `live()` gives
            at each tick, or a fixed `desired` without `live`, e.g. the slave's ME of `rhi.control.TMIMatching`,
            eq. 5.11; the whole tick) or
            "manipulability" (−log μ(J^q) with `log`, else −μ(J^q), eq. 5.14; the whole tick).
        desired: (m, m) SPD desired ellipsoid ("vme", "fme", "vme_live" without `live`; M_Free^des of
            "fme_schedule").
        w2: (n,) torque weights 1/T_i² [1/(N m)²] ("fme").
        stiff: (m, m) SPD M_Stiff^des ("fme_schedule").
        schedule: (‖M_Free − M_Stiff‖_F, ε₁, ε₂, ρ [s]) of the transition ("fme_schedule", eqs. 6.15–6.19).
        barrier: (shape "quadratic" | "inverse", margin δ [rad], weight w, hold ΔT [s] of the sampled-exact form,
            0: the gradient) ("barrier").
        penalty: k_q of the joint-limit penalised Jacobian J^q = J diag(P(q)) (eqs. 4.19–4.20); None: J^q = J
            ("vme_live", "manipulability").
        live: () -> (m, m) the desired ellipsoid of the tick ("vme_live", "fme").
        slave: the slave `rhi.sim.Plant` whose encoders `live` reads, D = J_s J_sᵀ at them ("vme_live"; None: another
            source), so that `rhi.sim`'s compiled loop computes D from its own teleoperated slave.
        log: −log μ instead of −μ ("manipulability").
        source: the intent estimator whose u gives the desired a û ûᵀ + b (I − û ûᵀ), (a, b) = `axes`
            ("vme_live" of `rhi.control.intent_control.IntentVME`, "fme" of `IntentFME`), so that the compiled
            loop computes it (`rhi.control._compiled.intent.desired`).
        axes: (a, b), the desired's eigenvalues along and across u (with `source`): (1, β) for M_des of eq. 3.23,
            (𝒦, ζ) for M_Stiff^des (eq. 6.13), (ζ, 𝒦) for M_Free^des (eq. 6.12).
    """

    kind: Literal["vme", "fme", "fme_schedule", "barrier", "vme_live", "manipulability"]
    desired: np.ndarray | None = None
    w2: np.ndarray | None = None
    stiff: np.ndarray | None = None
    schedule: tuple[float, float, float, float] | None = None
    barrier: tuple[str, float, float, float] | None = None
    penalty: float | None = None
    live: Callable[[], np.ndarray] | None = None
    slave: object | None = None
    log: bool = False
    source: object | None = None
    axes: tuple[float, float] = (1.0, 0.0)


@dataclasses.dataclass(frozen=True, eq=False)
class CompiledIntent:
    """An intent estimator as `rhi.control._compiled.intent.update` computes its tick (planar tasks, m = 2).

    Attributes:
        kind: "known", "filtered", "hmm" or "path" (a known direction along a polyline path).
        settings: its settings by the names of `rhi.control._compiled.intent.SETTINGS` (others 0).
        table: (k, m) the HMM's primitives, or the path's segment velocities [m/s]; None: none.
        knots: (segments + 1,) the path's arc length at each waypoint [m]; None: none.
    """

    kind: Literal["known", "filtered", "hmm", "path"]
    settings: dict[str, float] = dataclasses.field(default_factory=dict)
    table: np.ndarray | None = None
    knots: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class Route:
    """Which implementation runs a controller's tick, and why not the whole compiled tick.

    Attributes:
        name: "whole", "composed" or "reference" (see the module).
        reason: why not "whole" ("" on the whole tick).
    """

    name: Literal["whole", "composed", "reference"]
    reason: str = ""

    def __str__(self) -> str:
        return self.name if not self.reason else f"{self.name} ({self.reason})"


_WARNED: set[str] = set()


def warn_route(route: Route) -> None:
    """Warn (`RouteWarning`), once per process and reason, that a tick that asked for speed runs on `route`."""
    if route.name == "whole" or route.reason in _WARNED:
        return
    _WARNED.add(route.reason)
    warnings.warn(f"controller: the tick runs on the {route.name} route, not the whole compiled tick: {route.reason}",
                  RouteWarning, stacklevel=3)


__all__ = ["CompiledIntent", "CompiledLaw", "CompiledObjective", "Route", "warn_route"]
