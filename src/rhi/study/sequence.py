"""A participant's trial sequence: conditions in blocks, stimuli, pair order and rests, seeded per participant.

Participant i (0-based, in enrolment order) of a protocol with seed s gets the sequence drawn from
``numpy.random.default_rng([s, i])`` only, so it is reproducible and independent of every other participant.
The method of constant stimuli uses `rhi.analysis.psychophysics.protocol` (the §3.5 order: one block per
condition, the comparisons × repetitions permuted within it, which sample comes first a fair coin), so a
simulated study of N participants is trial for trial ``protocol(N, ...)``. Adaptive methods fix the conditions,
blocks and pair order here and leave the stimulus to the run (`rhi.study.adaptive`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rhi.analysis import psychophysics as pp
from rhi.errors import InvalidInput
from rhi.study.protocol import Protocol


@dataclasses.dataclass(frozen=True)
class PlannedTrial:
    """One trial of a participant's session.

    Attributes:
        index: position in the session (0-based).
        block: position of the condition's block (0-based).
        condition: condition name.
        training: an unscored training trial.
        percent: comparison [% of the reference]; None where an adaptive method decides it at run time or the
            task has no stimulus.
        reference: reference stimulus (e.g. stiffness [N/m]); None without stimuli.
        comparison_first: the comparison is probed first in the pair.
        rest: "" (none), "rest" (optional, before this trial) or "long_rest" (required).
        rest_seconds: length of that rest [s].
    """

    index: int
    block: int
    condition: str
    training: bool
    percent: float | None
    reference: float | None
    comparison_first: bool
    rest: str = ""
    rest_seconds: float = 0.0


def _rests(trials: list[PlannedTrial], blocks: dict) -> list[PlannedTrial]:
    out = []
    every, long_every = blocks["rest_every"], blocks["long_rest_every"]
    for t in trials:
        k = t.index
        if k and long_every and k % long_every == 0:
            t = dataclasses.replace(t, rest="long_rest", rest_seconds=blocks["long_rest_seconds"])
        elif k and every and k % every == 0:
            t = dataclasses.replace(t, rest="rest", rest_seconds=blocks["rest_seconds"])
        out.append(t)
    return out


def _training(rng: np.random.Generator, protocol: Protocol, n: int) -> list[tuple[float | None, bool]]:
    """(percent, comparison first) of `n` training trials: the easiest comparisons, alternating sign."""
    st = protocol.stimulus
    if st["method"] == "none":
        return [(None, False)] * n
    lo, hi = (min(st["comparisons_percent"]), max(st["comparisons_percent"])) if st["method"] == "constant" else \
        (st["min_percent"], st["max_percent"])
    return [(float(hi if k % 2 == 0 else lo), bool(rng.random() < 0.5)) for k in range(n)]


def plan(protocol: Protocol, participant: int) -> list[PlannedTrial]:
    """The trial sequence of participant `participant` (0-based enrolment index) of `protocol`.

    Raises:
        InvalidInput: a negative participant index.
    """
    if int(participant) != participant or participant < 0:
        raise InvalidInput(f"participant: the enrolment index must be an integer >= 0, got {participant!r}")
    st, names = protocol.stimulus, protocol.condition_names
    shuffle = protocol.order["conditions"] == "random"
    ref_first = protocol.order["pair"] == "reference_first"
    n_train = protocol.blocks["training"]
    train_rng = np.random.default_rng([protocol.seed, int(participant), 1])
    rows: list[tuple[int, str, bool, float | None, bool]] = []  # block, condition, training, percent, first
    if st["method"] == "constant":
        trials = pp.protocol([f"P{participant}"], names, reference=st["reference"],
                             comparison_percent=st["comparisons_percent"], repetitions=st["repetitions"],
                             shuffle_devices=shuffle, seed=protocol.seed, first_index=int(participant))
        block = -1
        for t in trials:
            if t.block != block:
                block = t.block
                rows += [(block, t.device, True, p, f) for p, f in _training(train_rng, protocol, n_train)]
            rows.append((t.block, t.device, False, t.comparison_percent, t.comparison_first))
    else:
        rng = np.random.default_rng([protocol.seed, int(participant)])
        order = rng.permutation(len(names)) if shuffle else np.arange(len(names))
        n = st["repetitions"] if st["method"] == "none" else st["trials"]
        for block, c in enumerate(order):
            first = rng.random(n) < 0.5
            rows += [(block, names[c], True, p, f) for p, f in _training(train_rng, protocol, n_train)]
            rows += [(block, names[c], False, None, bool(first[k]) and st["method"] != "none") for k in range(n)]
    ref = None if st["method"] == "none" else float(st["reference"])
    out = [PlannedTrial(index=k, block=b, condition=c, training=tr, percent=p, reference=ref,
                        comparison_first=bool(f) and not ref_first)
           for k, (b, c, tr, p, f) in enumerate(rows)]
    return _rests(out, protocol.blocks)


__all__ = ["PlannedTrial", "plan"]
