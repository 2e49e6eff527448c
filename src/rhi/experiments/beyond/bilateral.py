"""Beyond the thesis (§8.2): bilateral position–force teleoperation with delay, kept passive by the TDPA.

The rhi4 master in a simulated hand drives the `rehab_slave` into tissue (a one-sided
spring in the slave's MuJoCo plant); the slave's F/T force is rendered on the master. The
channel delays each direction by 0 to 200 ms (plus seeded jitter and loss). For each
delay, with and without the time-domain passivity approach (`rhi.runtime.tdpa`): the energy
the teleoperator hands the hand and the tissue, measured from the physical signals at both
ports (`BilateralLog.generated`; the TDPA's own books beside it), the peak and the
oscillation of the contact force, the force the hand feels in the held contact, the slave's
set-point drift, the position and force tracking errors, and the TMI of chapter 4. A
lock-step simulation (deterministic); the same Master/Slave run as two processes over UDP
with `rhi.runtime.run`.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
from rhi.devices.model import device
from rhi.experiments.arguments import checked
from rhi.experiments.parts import Part, Plan, run_plan
from rhi.experiments.result import Result, Row, Table
from rhi.runtime.bilateral import BilateralLog, simulate_bilateral
from rhi.runtime.channel import ChannelConfig
from rhi.runtime.tdpa import TDPA
from rhi.sim import Hand, HandPath, Plant, Wall

Q_MASTER = np.array([-0.63, 0.25, 0.28, 0.09])  # rad, the ch5 start of rhi4
Q_SLAVE = np.radians([30.0, 70.0])  # rad, mid-range of the rehab slave (its linear limit holds)
CONTACT = 0.05  # N: |F_e| above this counts as contact
#: The hand's stroke: 2 cm towards the tissue (1 cm away), 2 cm along its surface, 2 cm back, at 2 cm/s [m].
STROKE = np.array([[0.0, 0.0], [0.0, 0.02], [0.02, 0.02], [0.02, 0.0]])
SPEED = 0.02
#: The slide along the surface [s]: the held contact where the force the hand feels is measured.
SLIDE = (1.25, 2.0)
#: When the hand's reference leaves the tissue (halfway out) [s].
OFF = 2.5


def scenario(delay: float, passivity: bool, *, stiffness: float = 1000.0, duration: float = 6.0,
             jitter: float = 0.0, loss: float = 0.0, seed: int = 0, tdpa: TDPA | None = None,
             slave=None) -> BilateralLog:
    """One run: the hand strokes the master along `STROKE` at `SPEED` (into the tissue, along it, out), then holds.

    `tdpa`: the TDPA's settings where `passivity` (default `TDPA()`); `slave`: the slave's class
    (`simulate_bilateral`).
    """
    dm, ds = device("rhi4"), device("rehab_slave")
    mp, sp = Plant(dm), Plant(ds)
    mp.reset(Q_MASTER)
    sp.reset(Q_SLAVE)
    x0, xs0 = dm.fk(Q_MASTER), ds.fk(Q_SLAVE)
    ctrl = NullSpaceController(dm, ControllerConfig(ForceRendering(damping=0.01, passivity=None), saturation="ascm",
                                                    damping=0.1))
    hand = Hand(HandPath(x0 + STROKE, speed=SPEED), stiffness=300.0)
    fwd = ChannelConfig(delay=delay, jitter=jitter, loss=loss, seed=2 * seed + 1)
    bwd = ChannelConfig(delay=delay, jitter=jitter, loss=loss, seed=2 * seed + 2)
    tissue = Wall(xs0 + [0, 0.01], np.array([0.0, 1.0]), stiffness)
    return simulate_bilateral(mp, ctrl, sp, duration=duration, hand=hand, tissue=tissue,
                              forward=fwd, backward=bwd, passivity=(tdpa or TDPA()) if passivity else None,
                              slave=slave)


def metrics(log: BilateralLog) -> dict[str, float]:
    """Energy (physical and booked), contact force, force felt, drift, oscillation, tracking errors and TMI of a run.

    The held contact is the contact during the hand's slide along the tissue (`SLIDE`); the drift at the end
    of the run is what is left after the hand has left the tissue.
    """
    F = np.linalg.norm(log.F_e, axis=1)
    contact = F > CONTACT
    target = log.x_s[0] + (log.x_m - log.x_m[0])  # where a perfect slave would be now
    e_pos = np.linalg.norm(log.x_s - target, axis=1)
    e_force = np.linalg.norm(log.F_m - log.F_e, axis=1)
    smooth = np.convolve(F, np.ones(100) / 100, mode="same")
    first = int(np.argmax(contact)) if contact.any() else len(F)
    breaks = int(np.sum(contact[first:-1] & ~contact[first + 1:]))
    rms = lambda v, w: float(np.sqrt(np.mean(v[w] ** 2))) if w.any() else float("nan")  # noqa: E731
    held = contact & (log.t >= SLIDE[0]) & (log.t <= SLIDE[1])
    drift = 1e3 * np.linalg.norm(log.drift, axis=1)
    F_felt = float(np.mean(np.linalg.norm(log.F_m[held], axis=1))) if held.any() else float("nan")
    F_held = float(np.mean(F[held])) if held.any() else float("nan")
    return {
        "generated_mJ": 1e3 * float(log.generated[-1]),
        "generated_max_mJ": 1e3 * float(log.generated.max()),
        "observed_mJ": 1e3 * float(log.observed[-1]),
        "force_held": F_held,
        "force_felt": F_felt,
        "felt_ratio": F_felt / F_held if held.any() else float("nan"),
        "drift_max_mm": float(drift.max()),
        "drift_final_mm": float(drift[-1]),
        "t_end": float(log.t[-1]),
        "peak_force": float(F.max()),
        "oscillation": rms(F - smooth, contact),
        "contact_breaks": breaks,
        "pos_err_free_mm": 1e3 * rms(e_pos, ~contact),
        "pos_err_contact_mm": 1e3 * rms(e_pos, contact),
        "force_err_contact": rms(e_force, contact),
        "lag_mm": 1e3 * float(np.linalg.norm(log.x_d - target, axis=1).max()),
        "tmi_mean": float(np.nanmean(log.tmi)),
    }


DELAYS = (0.0, 0.01, 0.05, 0.1, 0.2)


@checked
def teleoperation_delay(*, delays=DELAYS, stiffness: float = 1000.0, duration: float = 5.0, jitter: float = 0.01,
                        loss: float = 0.1, extra_stiffness=(50.0, 2000.0),
                        progress: Callable[[int, int], None] | None = None) -> Result:
    """Energy and transparency of delayed bilateral teleoperation, without and with the TDPA.

    The runs are independent (`teleoperation_delay_plan`: `rhi reproduce` runs them side by side).

    Args:
        delays: one-way delays [s].
        stiffness: tissue stiffness K_e [N/m].
        duration: run length [s].
        jitter: largest extra delay [s] (delayed runs only).
        loss: packet loss fraction (delayed runs only).
        extra_stiffness: further tissue stiffnesses at the longest delay [N/m].
        progress: callback(done, total) in runs.
    """
    return run_plan(teleoperation_delay_plan(delays=delays, stiffness=stiffness, duration=duration, jitter=jitter,
                                             loss=loss, extra_stiffness=extra_stiffness), progress)


def _key(d: float, pc: bool, k: float) -> str:
    return f"{1e3 * d:.0f}ms_{k:.0f}_{'tdpa' if pc else 'none'}"


@checked
def teleoperation_delay_plan(*, delays=DELAYS, stiffness: float = 1000.0, duration: float = 5.0, jitter: float = 0.01,
                             loss: float = 0.1, extra_stiffness=(50.0, 2000.0)) -> Plan:
    """`teleoperation_delay` as independent parts, one per run (arguments as `teleoperation_delay`)."""
    cases = [(d, pc, stiffness) for d in delays for pc in (False, True)]
    cases += [(max(delays), pc, k) for k in extra_stiffness for pc in (False, True)]
    return Plan([Part(_key(d, pc, k), functools.partial(delay_case, d, pc, k, duration=duration, jitter=jitter,
                                                        loss=loss)) for d, pc, k in cases],
                functools.partial(_merge, cases=tuple(cases), jitter=jitter, loss=loss))


def delay_case(d: float, pc: bool, k: float, *, duration: float, jitter: float, loss: float,
               progress: Callable[[int, int], None] | None = None) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """One run of `teleoperation_delay` (a `Part` of its plan): (`metrics`, decimated arrays).

    Args:
        d: one-way delay [s].
        pc: with the TDPA.
        k: tissue stiffness [N/m].
        duration: run length [s].
        jitter: largest extra delay [s] (delayed runs only).
        loss: packet loss fraction (delayed runs only).
        progress: called with (1, 1) when done.
    """
    log = scenario(d, pc, stiffness=k, duration=duration, jitter=jitter if d > 0 else 0.0, loss=loss if d > 0 else 0.0)
    key, every = _key(d, pc, k), 5
    arrays = {f"{key}_{name}": getattr(log, name)[::every]
              for name in ("t", "generated", "observed", "F_e", "F_m", "x_m", "x_s", "drift")}
    if progress is not None:
        progress(1, 1)
    return metrics(log), arrays


def _merge(outputs: list[tuple[dict[str, float], dict[str, np.ndarray]]], *, cases, jitter: float,
           loss: float) -> Result:
    rows_e, rows_t, rows_f, arrays = [], [], [], {}
    ref = next((r["force_held"] for (d, pc, _), (r, _) in zip(cases, outputs) if d == 0 and pc), None)
    for (d, pc, k), (r, arr) in zip(cases, outputs):
        tag = f"{1e3 * d:.0f} ms, K_e {k:.0f} N/m, {'TDPA' if pc else 'no passivity control'}"
        rows_e += [Row(f"energy the teleoperator handed the hand and the tissue (measured), {tag}", 1.0 if pc else None,
                       r["generated_mJ"], "mJ", "−(W_hand + W_env) at the end; rhi's bound with the TDPA: ≤ 1 mJ",
                       bound="max" if pc else None),
                   Row(f"largest at any time (measured), {tag}", 1.0 if pc else None, r["generated_max_mJ"], "mJ",
                       bound="max" if pc else None),
                   Row(f"energy booked by the TDPA's observers E_out − E_in, {tag}", None, r["observed_mJ"], "mJ"),
                   Row(f"peak contact force, {tag}", None, r["peak_force"], "N"),
                   Row(f"contact-force oscillation (RMS about its 0.1 s mean), {tag}", None, r["oscillation"], "N"),
                   Row(f"contact losses during the contact, {tag}", None, r["contact_breaks"], "")]
        rows_t += [Row(f"position error in free motion (RMS), {tag}", None, r["pos_err_free_mm"], "mm"),
                   Row(f"position error in contact (RMS), {tag}", None, r["pos_err_contact_mm"], "mm"),
                   Row(f"force error in contact |F_m − F_e| (RMS), {tag}", None, r["force_err_contact"], "N"),
                   Row(f"largest set-point offset from the master's current position, {tag}", None, r["lag_mm"],
                       "mm", "delay lag, plus the TDPA's drift where it acts"),
                   Row(f"mean TMI along the run, {tag}", None, r["tmi_mean"], "")]
        if pc:
            rows_f += [Row(f"contact force at the slave during the slide, {tag}", None, r["force_held"], "N"),
                       Row(f"force on the hand during the slide, {tag}", None, r["force_felt"], "N",
                           f"{100 * r['force_felt'] / ref:.0f} % of the undelayed contact force" if ref else ""),
                       Row(f"largest set-point drift, {tag}", 10.0 if d == 0.1 else None, r["drift_max_mm"], "mm",
                           "rhi's bound at 100 ms: ≤ 10 mm" if d == 0.1 else "", bound="max" if d == 0.1 else None),
                       Row(f"drift at the end of the run, t = {r['t_end']:.1f} s (the hand off the tissue since about "
                           f"{OFF:g} s), {tag}", 0.1 if d == 0.1 and r["t_end"] >= OFF + 2 else None,
                           r["drift_final_mm"], "mm", "rhi's bound at 100 ms, 2 s after: ≤ 0.1 mm" if d == 0.1 else "",
                           bound="max" if d == 0.1 and r["t_end"] >= OFF + 2 else None)]
        arrays.update(arr)
    res = {(d, pc, k): r for (d, pc, k), (r, _) in zip(cases, outputs)}
    notes = [
        "Position–force architecture; the channel delays each direction by the stated time plus a seeded uniform "
        f"jitter of up to {1e3 * jitter:g} ms and loses {100 * loss:g} % of the packets (delayed runs only). The hand "
        f"strokes the master {SPEED * 1e2:g} cm/s into the tissue, along it and out, then holds still.",
        "Energy is measured from the physical signals at both ports of the teleoperator: the hand's work on the master "
        "and the tissue's work on the slave, each from the plant's force and motion at every physics step "
        "(`BilateralLog.generated`); the TDPA's own books are reported beside it and can disagree with it (they "
        "book the channel's ports, and what the bounded controllers could not take out).",
        "Without passivity control the delayed channel generates energy: the slave's contact force comes back late, "
        "so the master renders it while the hand already moves the other way, and the rendered force does work on "
        "the hand that nothing in the loop paid for.",
        "The TDPA (Ryu et al. 2010, `rhi.runtime.tdpa`) bounds each side's output energy by the input energy the other "
        "side reported; the master's damper is bounded (force, damping, and half the handle's smallest apparent mass "
        "per sample) and carries what it could not take out to the next samples; the slave's set-point backs off "
        "along the contact force (drift) and returns to the master's position while energy is in hand "
        "(Artigas et al. 2010's drift compensation).",
    ]
    per = [(d, res[(d, True, k)]) for (d, pc, k) in cases if pc and k == cases[0][2]]
    if per:
        notes.append("With the TDPA, per delay: " + "; ".join(
            f"{1e3 * d:.0f} ms: {r['generated_max_mJ']:.3g} mJ at most handed out, the hand feels {r['force_felt']:.2f} N "
            f"of the slave's {r['force_held']:.2f} N, drift up to {r['drift_max_mm']:.1f} mm and "
            f"{r['drift_final_mm']:.2f} mm at the end" for d, r in per) + ".")
    return Result("beyond.teleoperation_delay", "Bilateral teleoperation with delay (beyond the thesis, §8.2)",
                  [Table("Energy and stability", rows_e), Table("Transparency", rows_t),
                   Table("Force felt and drift with the TDPA", rows_f)], arrays, notes)
