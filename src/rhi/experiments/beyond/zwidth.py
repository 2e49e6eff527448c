"""Beyond the thesis: the Z-width of rhi4 at 1 kHz, without and with passivity control, and what each keeps of the wall.

Colgate and Brown, "Factors affecting the Z-width of a haptic display", ICRA 1994: the
Z-width is the range of impedances a device renders passively. Here, the simulated rhi4
(MuJoCo plant, device friction) renders a one-sided virtual wall F = −max(K d + B ḋ, 0) n at
1 kHz (eq. 7.2, `ForceRendering`, ASCM, no null-space objectives) for a grid of stiffness K
and damping B, and the palpating hand of `rhi.experiments.beyond.passivity` strokes into it.
A wall counts as rendered passively when the hand's work W = ∫F_hᵀẋ dt, measured in the
plant, never falls below −1 mJ (the device starts at rest). Each passivity method of
`rhi.control.passivity.Passivity` (the series damper with energy bounding, the damper on the
deficit alone, energy bounding alone) runs the same grid; beside passivity, the
transparency: the peak force rendered, and its mean error against the ideal wall K δX
in contact.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence

import numpy as np

from rhi.control import ControllerConfig, ForceRendering, NullSpaceController, Passivity
from rhi.devices.model import device
from rhi.errors import InvalidInput
from rhi.experiments.arguments import checked
from rhi.experiments.beyond.passivity import B_D, HAND, TARGET_W
from rhi.experiments.parts import Part, Plan, run_plan
from rhi.experiments.result import Result, Row, Table
from rhi.sim import Hand, HandPath, Plant, Wall, simulate

#: The start (rhi4's ch5 start) and the wall's normal.
Q0 = (-0.63, 0.25, 0.28, 0.09)
U = (0.0, 1.0)
#: The grid: wall stiffness [N/m] and damping [N s/m].
STIFFNESS = (1e3, 2e3, 5e3, 1e4, 2e4, 5e4)
DAMPING = (0.0, 2.0, 5.0, 10.0)
#: "none" (no passivity control) and the methods of `Passivity` at the motor port.
METHODS: tuple[str, ...] = ("none", "damper_bounding", "damper", "bounding")
#: The stroke: from 2 mm outside the wall to 4 mm into it and back, at 5 cm/s [m], [m/s].
OUT, DEPTH, SPEED = 0.002, 0.004, 0.05


def wall_case(k: float, b: float, method: str, *, duration: float,
              progress: Callable[[int, int], None] | None = None) -> dict[str, float]:
    """One wall of the grid under one method: passivity (W) and transparency (peak and mean force error).

    Args:
        k: wall stiffness K [N/m].
        b: wall damping B [N s/m].
        method: "none" or a `Passivity.method`.
        duration: palpation time [s].
        progress: callback(done, total) in control ticks.
    """
    dev = device("rhi4")
    q0 = np.array(Q0)
    x0, u = dev.fk(q0), np.array(U)
    strokes = int(math.ceil(duration * SPEED / (OUT + DEPTH))) + 1
    hand = Hand(HandPath(np.array([x0] + [x0 - OUT * u, x0 + DEPTH * u] * strokes), speed=SPEED, start=0.05),
                stiffness=HAND[0], damping=HAND[1], max_force=HAND[2])
    pas = None if method == "none" else Passivity(method=method)  # type: ignore[arg-type]
    ctrl = NullSpaceController(dev, ControllerConfig(primary=ForceRendering(damping=B_D, passivity=pas),
                                                     damping=0.1, saturation="ascm"))
    plant = Plant(dev)
    plant.reset(q0)
    log = simulate(plant, ctrl, duration=duration, hand=hand, virtual=Wall(x0, u, k, damping=b), progress=progress)
    pen = (log.x - x0) @ u
    F = log.ft[:, :2] @ u  # the force the hand pushes along u = the force rendered to it [N]
    F_ideal = np.maximum(k * pen + b * (log.xdot @ u), 0.0) * (pen > 0)
    contact = F_ideal >= 0.5
    err = (F - F_ideal)[contact]
    return {"W": float(log.work[-1]), "W_min": float(np.min(log.work)), "peak": float(np.max(F)),
            "peak_ideal": float(np.max(F_ideal)), "mean_error": float(np.mean(err)) if err.size else math.nan,
            "rms_error": float(np.sqrt(np.mean(err**2))) if err.size else math.nan,
            "active": float(np.mean(log.alpha_pc > 0)) if pas is not None and log.alpha_pc is not None else 0.0,
            "fault": 0.0 if log.fault is None else 1.0}


@checked
def z_width_plan(*, stiffness: Sequence[float] = STIFFNESS, damping: Sequence[float] = DAMPING,
                 methods: Sequence[str] = METHODS, duration: float = 1.0) -> Plan:
    """`z_width` as independent parts, one per wall and method (arguments as `z_width`)."""
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise InvalidInput(f"duration: must be finite and > 0 [s], got {duration!r}")
    for name, vals in (("stiffness", stiffness), ("damping", damping)):
        if not vals or not all(isinstance(v, (int, float)) and math.isfinite(v) and v >= 0 for v in vals):
            raise InvalidInput(f"{name}: expected finite values >= 0, got {list(vals)!r}")
    for m in methods:
        if m not in METHODS:
            raise InvalidInput(f"methods: unknown method {m!r}; available: {', '.join(METHODS)}")
    if "none" not in methods:
        raise InvalidInput("methods: 'none' is the reference every method is compared with; include it")
    cases = [(float(k), float(b), m) for m in methods for k in stiffness for b in damping]
    n = int(round(duration * 1000))
    return Plan([Part(f"{m}_{k:g}_{b:g}", functools.partial(wall_case, k, b, m, duration=duration), n)
                 for k, b, m in cases],
                functools.partial(_merge, cases=tuple(cases), stiffness=tuple(stiffness), damping=tuple(damping),
                                  methods=tuple(methods), duration=duration))


@checked
def z_width(*, stiffness: Sequence[float] = STIFFNESS, damping: Sequence[float] = DAMPING,
            methods: Sequence[str] = METHODS, duration: float = 1.0,
            progress: Callable[[int, int], None] | None = None) -> Result:
    """The Z-width of rhi4 at 1 kHz per passivity method, and the force each keeps.

    Args:
        stiffness: wall stiffnesses K [N/m].
        damping: wall dampings B [N s/m].
        methods: "none" and methods of `Passivity` (`METHODS`).
        duration: palpation time per wall [s].
        progress: callback(done, total) in control ticks.

    Returns:
        Result "beyond.z_width": arrays ``{method}_{W_min, peak, peak_ideal, mean_error, rms_error, active,
        fault}`` of shape (len(stiffness), len(damping)) [J], [N], [1] (active: the share of ticks with the
        damper acting), ``stiffness``, ``damping``.

    Raises:
        InvalidInput: an empty or non-finite grid, an unknown method, a grid without "none".
    """
    return run_plan(z_width_plan(stiffness=stiffness, damping=damping, methods=methods, duration=duration), progress)


_LABEL = {"none": "no PC", "damper_bounding": "series damper + energy bounding",
          "damper": "series damper only (H&R's PC, the law never scaled, default)", "bounding": "energy bounding only"}


def _merge(outputs: list[dict[str, float]], *, cases, stiffness, damping, methods, duration) -> Result:
    shape = (len(stiffness), len(damping))
    keys = ("W_min", "peak", "peak_ideal", "mean_error", "rms_error", "active", "fault")
    arrays: dict[str, np.ndarray] = {f"{m}_{k}": np.full(shape, np.nan) for m in methods for k in keys}
    for (k, b, m), r in zip(cases, outputs):
        i, j = stiffness.index(k), damping.index(b)
        for key in keys:
            arrays[f"{m}_{key}"][i, j] = r[key]
    arrays["stiffness"], arrays["damping"] = np.array(stiffness), np.array(damping)
    passive = {m: arrays[f"{m}_W_min"] >= TARGET_W for m in methods}
    ref = passive["none"]
    rows_p, rows_t = [], []
    for m in methods:
        p = passive[m]
        k_max = [max((k for i, k in enumerate(stiffness) if p[i, j]), default=0.0) for j in range(len(damping))]
        rows_p += [Row(f"walls rendered passively, {_LABEL[m]}", None, float(p.sum()), "",
                       f"of {p.size}; stiffest passive K per B = {', '.join(f'{b:g}: {k:g}' for b, k in zip(damping, k_max))}"),
                   Row(f"lowest hand's work over the grid, {_LABEL[m]}", None, float(np.nanmin(arrays[f"{m}_W_min"])),
                       "J")]
        if m == "none":
            continue
        ratio = arrays[f"{m}_peak"] / arrays["none_peak"]
        keep = ratio[ref]
        rows_t += [
            Row(f"walls passive without PC where the peak force stays within 10 % of the no-PC wall's, {_LABEL[m]}",
                float(ref.sum()), float(np.sum(np.abs(keep - 1.0) <= 0.1)), "", "goal: all of them", bound="min"),
            Row(f"smallest peak force relative to the no-PC wall, passive walls, {_LABEL[m]}", None,
                100.0 * float(np.min(keep)) if keep.size else math.nan, "%"),
            Row(f"walls active without PC made passive, {_LABEL[m]}", None, float(np.sum(p & ~ref)), "",
                f"of {int(np.sum(~ref))}"),
            Row(f"ticks with the damper acting, walls passive without PC (largest), {_LABEL[m]}", None,
                100.0 * float(np.max(arrays[f"{m}_active"][ref])) if ref.any() else math.nan, "%"),
        ]
    for m in methods:
        for i, k in enumerate(stiffness):
            if k == min(stiffness, key=lambda s: abs(s - 1e3)):
                for j, b in enumerate(damping):
                    rows_t.append(Row(f"K {k:g} N/m, B {b:g} N s/m, {_LABEL[m]}: peak force (ideal "
                                      f"{arrays[f'{m}_peak_ideal'][i, j]:.1f} N)", None, arrays[f"{m}_peak"][i, j],
                                      "N", f"mean error {arrays[f'{m}_mean_error'][i, j]:+.2f} N, "
                                           f"RMS {arrays[f'{m}_rms_error'][i, j]:.2f} N"))
    notes = [
        f"rhi4 in MuJoCo (device friction), 1 kHz, ASCM, no null-space objectives, B^d = {B_D} N s/m; the hand "
        f"({HAND[0]:g} N/m, {HAND[1]:g} N s/m, ≤ {HAND[2]:g} N) strokes from {OUT * 1e3:g} mm outside the wall to "
        f"{DEPTH * 1e3:g} mm into it at {SPEED * 1e2:g} cm/s for {duration:g} s per wall. Passive: the hand's work, "
        f"measured in the plant, never below {TARGET_W * 1e3:g} mJ.",
        "Colgate and Brown's Z-width: the (K, B) region a sampled device renders passively. Energy bounding keeps "
        "the hand passive by scaling the law's torque; the series damper alone (H&R's PC, the default) leaves the "
        "law's force and dissipates the deficit through the motion.",
    ]
    return Result("beyond.z_width", "Beyond the thesis: Z-width of rhi4 at 1 kHz and the force each passivity "
                  "method keeps", [Table("Z-width: walls rendered passively (hand's work ≥ −1 mJ)", rows_p),
                                   Table("Transparency: rendered force against the ideal wall", rows_t)],
                  arrays, notes)
