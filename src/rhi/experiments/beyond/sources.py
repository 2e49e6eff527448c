"""Beyond the thesis: where a run's energy comes from — the motor-port work of each torque source, tick by tick.

The controller's torque at tick k is a sum of sources (`rhi.control.reference.reference_tick`'s
parts: the primary task torque, the allocation's null-space torque, the safety torques, each
null-space objective, the null-space energy tank's damper; the passivity layer is what the
sent torque adds to them). Each is held over the sample like the whole torque, so its work
on the mechanism over the interval is exactly ``part(k)ᵀ(q(k+1) − q(k))`` with the encoders'
displacement measured in the plant. `source_work` replays a logged run's inputs
(t, q, q̇, the rendered force) through a twin of its controller (its compiled tick split by
`rhi.control.sources`, or the reference), checks that the twin sends the logged torque, and
integrates each source's work.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rhi.control import ControllerConfig, JointLimitBarrier, NullSpaceController
from rhi.control.barrier import limit_rows
from rhi.control.sources import TickSources
from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.experiments.result import Row

#: The name of the passivity layer's share (the sent torque less the tick's parts).
PASSIVITY = "passivity controller"
#: Sources whose work the safety torques do.
SAFETY = ("damping", "barrier")


def source_work(dev: Device, config: ControllerConfig, log) -> tuple[dict[str, float], float]:
    """The work [J] of each torque source over a logged run, and the largest replay error [N m].

    Args and twin as `tick_work`.

    Returns:
        ({source: Σ part(k)ᵀ(q(k+1) − q(k))} [J], max_k |τ_twin(k) − τ_log(k)| [N m]).

    Raises:
        InvalidInput: a log with fewer than two ticks.
    """
    names, work, err = tick_work(dev, config, log)
    return dict(zip(names, work.sum(axis=0).tolist())), err


def tick_work(dev: Device, config: ControllerConfig, log) -> tuple[list[str], np.ndarray, float]:
    """The work [J] of each torque source over each hold interval of a logged run, and the largest replay error.

    The twin is the controller itself (its whole compiled tick, split by `rhi.control.sources.TickSources`;
    its fallback ticks by the reference), else (a tick the compiled split cannot decide, a controller
    whose tick is not the whole compiled one) a reference twin (``implementation="reference"``).

    Args:
        dev: the controller's device.
        config: the controller's configuration.
        log: the run's `rhi.sim.Log` (t, q, q̇, τ and the rendered force F_env of every tick).

    Returns:
        (the sources, (N − 1, sources) part(k)ᵀ(q(k+1) − q(k)) [J] for each of the N ticks but the last,
        max_k |τ_twin(k) − τ_log(k)| [N m]).

    Raises:
        InvalidInput: a log with fewer than two ticks.
    """
    if len(log.t) < 2:
        raise InvalidInput("log: needs at least two ticks to book any work")
    compiled = _compiled_work(dev, config, log)
    if compiled is not None:
        return compiled
    twin = NullSpaceController(dev, dataclasses.replace(config, implementation="reference"))
    twin.sources = {}
    dq_step = np.diff(log.q, axis=0)
    rows: list[dict[str, float]] = []
    err = 0.0
    for k in range(len(log.t) - 1):
        tau = twin.step(float(log.t[k]), log.q[k], log.dq[k], {"force": log.F_env[k], "ft": log.ft[k]})
        parts = dict(twin.sources)
        parts[PASSIVITY] = tau - sum(parts.values())
        rows.append({name: float(p @ dq_step[k]) for name, p in parts.items()})
        err = max(err, float(np.max(np.abs(tau - log.tau[k]))))
    names = list(dict.fromkeys(name for r in rows for name in r))
    return names, np.array([[r.get(name, 0.0) for name in names] for r in rows]), err


def _compiled_work(dev: Device, config: ControllerConfig, log) -> tuple[list[str], np.ndarray, float] | None:
    """`tick_work` with the controller's own compiled tick as the twin; None where a tick is not split there."""
    twin = NullSpaceController(dev, config)
    split = TickSources(twin)
    if split.reason:
        return None
    names = split.names
    N = len(log.t) - 1
    parts = np.zeros((N, len(names) + 1, dev.n))
    row = np.zeros((len(names), dev.n))  # a stopped controller's tick keeps the last parts (as the reference twin)
    err = 0.0
    state = twin.state
    for k in range(N):
        q, dq = log.q[k], log.dq[k]
        twin.sources = {}
        ticks = state.ticks
        tau = twin.step(float(log.t[k]), q, dq, {"force": log.F_env[k], "ft": log.ft[k]})
        if twin.sources:  # the controller's fallback: the reference ran this tick
            row = np.array([twin.sources[name] for name in names])
        elif state.ticks != ticks:
            out = split(q, dq)
            if out is None:
                return None
            row = out
        parts[k, :-1] = row
        parts[k, -1] = tau - row.sum(axis=0)
        err = max(err, float(np.max(np.abs(tau - log.tau[k]))))
    return [*names, PASSIVITY], np.einsum("ksn,kn->ks", parts, np.diff(log.q, axis=0)), err


def barrier_generated(dev: Device, barrier: JointLimitBarrier, gain: float, log, *, sampled: bool) -> float:
    """The energy [J] the barrier's held torque generates over a logged run: Σ τ_b(k)ᵀΔq(k) + gain Δν_lim.

    τ_b(k) = −gain ∇ν_lim(q(k)) (sample-and-hold of the gradient) or, `sampled`, −gain ∇̄ν_lim (the
    discrete gradient along ΔT q̇(k), `JointLimitBarrier.sampled_gradient`, ΔT the log's sample), with
    Δq(k) the plant's encoder displacement: the barrier's own port before any projection, zero for a
    potential's exact sampled form. Positive: energy the sampling put in.

    Args:
        dev: the device.
        barrier: the barrier (its ``hold`` is ignored: `sampled` says which form, with ΔT the log's sample).
        gain: its gain [N m].
        log: the run's `rhi.sim.Log` (t, q, q̇).
        sampled: book the discrete gradient (else the gradient at q(k)).
    """
    C, lower, upper = limit_rows(dev)
    c = log.q @ C.T  # (N, r) every tick's limit rows at once
    d = np.concatenate([c - lower, upper - c], axis=1)  # distances to the lower, then the upper limits
    if sampled:
        step = float(log.t[1] - log.t[0]) * (log.dq[:-1] @ C.T)
        g = barrier.side_divided(d[:-1], np.concatenate([step, -step], axis=1))
    else:
        g = barrier.side_slopes(d[:-1])
    r = C.shape[0]
    dc = np.diff(c, axis=0)  # Δ(C q): ∂ν/∂q ᵀΔq = Σ_r (g_lo − g_hi) Δ(C q)_r
    work = -gain * float(np.sum((g[:, :r] - g[:, r:]) * dc))
    nu = barrier.side_values(d[[0, -1]]).sum(axis=1)
    return work + gain * float(nu[1] - nu[0])


def objective_work(work: dict[str, float]) -> float:
    """The null-space objectives' work together [J]."""
    return sum(v for k, v in work.items() if k.startswith("objective"))


def null_work(work: dict[str, float]) -> float:
    """The null-space side's net work [J]: allocation, safety torques, the tank's damper and the objectives."""
    return sum(v for k, v in work.items() if k not in ("task", "gravity", PASSIVITY, "box clip"))


def rows(work: dict[str, float], label: str) -> list[Row]:
    """Table rows: the work of each source, the objectives' and the null-space side's net work [J]."""
    out = [Row(f"  {name}, {label}", None, w, "J") for name, w in work.items()]
    out += [Row(f"objectives together, {label}", None, objective_work(work), "J"),
            Row(f"null-space side net (allocation, safety, tank damper, objectives), {label}", None,
                null_work(work), "J", "positive: energy the null space put into the mechanism")]
    return out


__all__ = ["PASSIVITY", "SAFETY", "barrier_generated", "null_work", "objective_work", "rows", "source_work", "tick_work"]
