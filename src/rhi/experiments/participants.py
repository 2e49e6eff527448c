"""Simulated participants for study protocols: the §3.5 observer through the simulated devices, end to end.

`simulated_study` runs `rhi study simulate`: it builds the stimulus lookup of `rhi.experiments.ch3.discrimination`
(one MuJoCo palpation through each condition's device per comparison stiffness and stroke duration), lets a
`WeberObserver` (`simulated_observers`) answer every trial of every participant's protocol sequence
(`rhi.study.simulate.simulate`, written into participant folders when asked), and analyses the responses as
`rhi study analyze` does (`rhi.study.results.fit_conditions`). For the §3.6 protocol and the same seed, the
trials, answers and numbers are those of `rhi.experiments.ch3.psychophysics`. The power of the one-way ANOVA
at Table 3.3's effect size (its WF means and s.d.) for the simulated number of participants per condition
comes with it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rhi import thesis as T
from rhi.analysis import psychophysics as pp
from rhi.errors import InvalidInput
from rhi.experiments.ch3.discrimination import DURATIONS, WeberObserver, stimulus_table
from rhi.experiments.ch3.measures import DEVICE_NAMES
from rhi.experiments.setups import Progress
from rhi.study.protocol import Protocol
from rhi.study.results import fit_conditions, responses_of
from rhi.study.simulate import anova_power, cohens_f, f_from_anova, simulate

#: the controller each simulated device runs (`rhi.experiments.ch3.discrimination.palpate`): its run configuration.
_CH3_CONFIG = {"RHI": "ch3_vme", "PHANToM": None, "Rehab": None}


@dataclasses.dataclass(frozen=True)
class SimulatedStudy:
    """A simulated study: rows, the analysis, the observers, the lookup, the power at the thesis's effect.

    Attributes:
        rows: responses.csv rows of every trial.
        analysis: `rhi.analysis.psychophysics.StudyAnalysis` of the scored trials.
        weber: (participants,) intrinsic Weber fractions of the simulated observers.
        table: the stimulus lookup (`stimulus_table`, keyed by condition).
        power: power of the one-way ANOVA on WF at Table 3.3's means and s.d. with this many per condition.
    """

    rows: list[dict[str, Any]]
    analysis: pp.StudyAnalysis
    weber: np.ndarray
    table: dict[str, np.ndarray]
    power: float


def _palpation_names(protocol: Protocol) -> dict[str, str]:
    """{condition: simulated device of `palpate`}; conditions the §3.5 set-up does not simulate are refused."""
    by_model = {v: k for k, v in DEVICE_NAMES.items()}
    out = {}
    for i, c in enumerate(protocol.conditions):
        name = by_model.get(c.device)
        if name is None or c.params or c.config != _CH3_CONFIG[name]:
            raise InvalidInput(f"conditions[{i}]: the simulated participant feels the §3.5 devices only "
                               f"(rhi4 with config 'ch3_vme', phantom or rehab without config or params), got "
                               f"device {c.device!r}, config {c.config!r}, params {c.params}")
        out[c.name] = name
    return out


def stimulus_grid(protocol: Protocol) -> list[float]:
    """Comparisons [%] of the lookup: the protocol's constant stimuli, or its adaptive range every step (and 0)."""
    st = protocol.stimulus
    if st["method"] == "constant":
        pct = sorted(float(p) for p in st["comparisons_percent"])
    else:
        step = st.get("step_percent", 5.0)
        pct = np.arange(st["min_percent"], st["max_percent"] + 0.5 * step, step).tolist()
        pct = sorted(set(round(p, 9) for p in pct) | {0.0})
    if 0.0 not in pct:
        raise InvalidInput("stimulus.comparisons_percent: the simulated observer needs 0 (the reference) among them")
    return pct


def simulated_observers(
    protocol: Protocol,
    participants: int,
    *,
    weber_mean: float = 0.08,
    weber_sd: float = 0.02,
    lapse: float = 0.0,
    durations: Sequence[float] = DURATIONS,
    table: dict[str, np.ndarray] | None = None,
    progress: Progress | None = None,
) -> WeberObserver:
    """The §3.5 observers of a discrimination protocol's participants, feeling its conditions' simulated devices.

    One `WeberObserver` (seeded by the protocol's seed) answers every trial of `participants` participants in
    presentation order, by condition name, from the lookup of one MuJoCo palpation per (condition's device,
    comparison stiffness, stroke duration) (`stimulus_table`; its ``table`` attribute, keyed by condition).

    Args:
        protocol: a discrimination protocol whose conditions are the §3.5 devices.
        participants: how many participants it answers for (enrolment indices 0, 1, ...).
        weber_mean: mean intrinsic Weber fraction of the observers.
        weber_sd: its s.d.
        lapse: the observers' lapse rate.
        durations: stroke durations of the lookup [s].
        table: a precomputed lookup keyed by condition (skips the simulations).
        progress: callback(done, total) over the simulations.

    Raises:
        InvalidInput: not a discrimination protocol, or conditions the §3.5 set-up does not simulate.
    """
    if protocol.kind != "discrimination_2afc":
        raise InvalidInput(f"protocol: simulated participants exist for discrimination tasks; {protocol.name} is a "
                           f"{protocol.kind} task")
    names = _palpation_names(protocol)
    if table is None:
        conds = protocol.condition_names
        lookup = stimulus_table(tuple(names[c] for c in conds), reference=protocol.stimulus["reference"],
                                comparison_percent=stimulus_grid(protocol), durations=durations, progress=progress)
        table = {k: v for k, v in lookup.items() if k in ("stiffness", "durations")}
        for c in conds:
            table[c], table[f"{c}_speed"] = lookup[names[c]], lookup[f"{names[c]}_speed"]
    return WeberObserver(table, participants, reference=protocol.stimulus["reference"], weber_mean=weber_mean,
                         weber_sd=weber_sd, lapse=lapse, seed=protocol.seed)


def simulated_study(
    protocol: Protocol,
    participants: int = 10,
    *,
    out: str | Path | None = None,
    weber_mean: float = 0.08,
    weber_sd: float = 0.02,
    lapse: float = 0.0,
    durations: Sequence[float] = DURATIONS,
    overdispersion: bool = True,
    table: dict[str, np.ndarray] | None = None,
    progress: Progress | None = None,
) -> SimulatedStudy:
    """Simulate a discrimination protocol end to end with §3.5 observers (see the module docstring).

    Args:
        protocol: a discrimination protocol whose conditions are the §3.5 devices.
        participants: simulated participants.
        out: study folder for the participant folders (None: in memory).
        weber_mean: mean intrinsic Weber fraction of the observers (`WeberObserver`).
        weber_sd: its s.d.
        lapse: the observers' lapse rate.
        durations: stroke durations of the lookup [s].
        overdispersion: psignifit's η.
        table: a precomputed lookup keyed by condition (skips the simulations).
        progress: callback(done, total) over simulations, then fits.
    """
    obs = simulated_observers(protocol, participants, weber_mean=weber_mean, weber_sd=weber_sd, lapse=lapse,
                              durations=durations, table=table, progress=progress)
    rows = simulate(protocol, participants, obs, out=out)
    rows_text = [{k: "" if v is None else str(v) for k, v in r.items()} | {"completion_time": ""} for r in rows]
    analysis = fit_conditions(responses_of(rows_text), conditions=protocol.condition_names,
                              overdispersion=overdispersion)
    wf = T.TABLE_3_3["wf"]
    f = cohens_f([float(v[0]) for v in wf.values()], [float(v[1]) for v in wf.values()])
    power = anova_power(f, len(wf), participants) if participants >= 2 else float("nan")
    return SimulatedStudy(rows=rows, analysis=analysis, weber=obs.weber, table=obs.table, power=power)


#: the ch. 5 scenario (`rhi.experiments.ch5.tracking.w_scenario`) of a condition: by its run configuration and device.
_CH5_SCENARIO = {("rhi4", "ch5_tmi"): "s1", ("rhi4", "ch5_manipulability"): "s2", ("rehab", None): "s3"}


def _path_run(item: tuple) -> dict[str, float]:
    """§5.5 measures of one simulated path-following run: (scenario key, speed [m/s], task table, start configurations)."""
    from rhi.experiments.ch5 import setup
    from rhi.experiments.ch5.tracking import w_scenario

    key, speed, task, start = item
    kw = {"center": tuple(task["center"][:2]), "width": task["width"], "height": task["height"]}
    stats, _ = w_scenario(key, start=start, scale=1.0, speed=speed, settle=1.0, k_q=setup.K_Q, gain=setup.GAIN,
                          damping=setup.NULL_DAMPING, friction="thesis", ellipses=2, **kw)
    return {"tracking_error": stats["path_rms"], "effort": stats["work"],
            "completion_time": setup.w_reference(speed=speed, **kw).duration}


@dataclasses.dataclass(frozen=True)
class SimulatedTaskStudy:
    """A simulated path-following study: rows, the §5.5 analysis, the users' speeds, the power at §5.5's effect.

    Attributes:
        rows: responses.csv rows of every run.
        analysis: `rhi.study.results.TaskAnalysis`.
        speed: (participants,) each simulated user's path speed [m/s].
        power: power of the one-way ANOVA at the effect of §5.5's F(2, 21) = 3.57 on the execution time.
    """

    rows: list[dict[str, Any]]
    analysis: Any
    speed: np.ndarray
    power: float


class _Runs:
    """A `Performer` answering from precomputed runs {(participant, trial): measures}."""

    def __init__(self, runs: dict[tuple[int, int], dict[str, float]]) -> None:
        self.runs = runs

    def perform(self, subject: int, condition: str, trial: int) -> dict[str, float]:
        return self.runs[(subject, trial)]


def simulated_path_study(protocol: Protocol, participants: int = 8, *, out: str | Path | None = None,
                         speed_sd: float = 0.2, run_sd: float = 0.05,
                         progress: Progress | None = None) -> SimulatedTaskStudy:
    """Simulate a path-following protocol with the §5.4 teleoperation simulation as the users.

    Each simulated user follows the W at a speed of their own, ``task.speed · (1 + speed_sd ε)`` (ε ~ N(0, 1),
    clipped to ≥ 0.5 · task.speed), varied per run by ``run_sd``; every run is one `w_scenario` of chapter 5
    (the master driven by the simulated hand, the slave following by teleoperation) for the condition's
    scenario; its measures: the slave's RMS distance to the path, the user's work (eq. 5.15) and the path's
    duration. The runs are independent and run on the default executor.

    Raises:
        InvalidInput: conditions that are not the ch. 5 scenarios (rhi4 with ch5_tmi or ch5_manipulability,
            rehab without a configuration), or a ``[teleoperation]`` other than ch. 5's (rehab_slave, K_p 2000 N/m,
            K_d 60 N s/m, no scaling or offset: `rhi.sim.Teleoperation`'s defaults).
    """
    from rhi.design.executors import parallel_map
    from rhi.experiments.ch5.setup import w_reference
    from rhi.experiments.ch5.tracking import w_start
    from rhi.study.results import analyse_task
    from rhi.study.sequence import plan

    if protocol.kind != "path_following":
        raise InvalidInput(f"protocol: {protocol.name} is not a path-following task")
    keys = {}
    for i, c in enumerate(protocol.conditions):
        key = _CH5_SCENARIO.get((c.device, c.config))
        if key is None:
            raise InvalidInput(f"conditions[{i}]: the simulated users run the ch. 5 scenarios only (rhi4 with config "
                               f"ch5_tmi or ch5_manipulability, rehab without), got {c.device!r}, {c.config!r}")
        keys[c.name] = key
    tele = protocol.teleoperation or {}
    ch5 = {"slave": "rehab_slave", "slave_params": {}, "kp": 2000.0, "kd": 60.0, "scale": 1.0}
    for k, v in ch5.items():
        if tele.get(k) != v:
            raise InvalidInput(f"teleoperation.{k}: the simulated users teleoperate ch. 5's slave set-up only "
                               f"({k} = {v!r}), got {tele.get(k)!r}")
    if np.any(tele["offset"] != 0.0):
        raise InvalidInput(f"teleoperation.offset: the simulated users teleoperate ch. 5's slave set-up only "
                           f"(no offset), got {tele['offset'].tolist()}")
    rng = np.random.default_rng([protocol.seed, 2])
    base = protocol.task["speed"]
    speed = np.maximum(base * (1.0 + speed_sd * rng.standard_normal(int(participants))), 0.5 * base)
    task = protocol.task
    start = w_start(w_reference(tuple(task["center"][:2]), task["width"], task["height"], base))  # the W, checked once
    items, where = [], []
    for i in range(int(participants)):
        for t in plan(protocol, i):
            v = float(speed[i] * max(1.0 + run_sd * rng.standard_normal(), 0.5))
            items.append((keys[t.condition], v, task, start))
            where.append((i, t.index))
    runs = dict(zip(where, parallel_map(_path_run, items, progress=progress)))
    rows = simulate(protocol, participants, _Runs(runs), out=out)
    text = [{k: "" if r.get(k) is None else str(r[k]) for k in r} | {"response": ""} for r in rows]
    analysis = analyse_task(text, protocol.condition_names)
    F = T.ANOVA_5["time"][0]
    power = anova_power(f_from_anova(float(F), 2, 21), len(protocol.conditions), participants)
    return SimulatedTaskStudy(rows=rows, analysis=analysis, speed=speed, power=power)


__all__ = ["SimulatedStudy", "SimulatedTaskStudy", "simulated_observers", "simulated_path_study", "simulated_study",
           "stimulus_grid"]
