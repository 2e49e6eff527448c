"""The §3.5 protocol: 2AFC trials by the method of constant stimuli, the responses, simulated observers."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from rhi.errors import InvalidInput

#: reference stiffness of §3.5 [N/m].
REFERENCE_STIFFNESS = 50.0
#: comparison stimuli of §3.5 [% of the reference].
COMPARISON_PERCENT = (-35.0, -25.0, -15.0, -5.0, 0.0, 5.0, 15.0, 25.0, 35.0)
#: the three haptic interfaces of §3.5.
DEVICES = ("RHI", "PHANToM", "Rehab")
#: repetitions of every comparison per device and subject (§3.5).
REPETITIONS = 10
#: z such that Φ(z) = 0.75: for a cumulative Gaussian of s.d. σ, JND = Z75 σ.
Z75 = 0.6744897501960817

MEASURES = ("pse", "lt", "ut", "jnd", "wf")


@dataclasses.dataclass(frozen=True)
class Trial:
    """One 2AFC trial of the method of constant stimuli.

    Attributes:
        subject: subject identifier.
        device: haptic interface the pair is felt through.
        index: position of the trial in the subject's whole session (0-based).
        block: position of the device's block in the subject's session (0-based).
        reference: reference stiffness [N/m].
        comparison: comparison stiffness [N/m].
        comparison_percent: comparison relative to the reference [%].
        comparison_first: whether the comparison is probed first in the pair.
    """

    subject: str
    device: str
    index: int
    block: int
    reference: float
    comparison: float
    comparison_percent: float
    comparison_first: bool


def protocol(
    subjects: int | Sequence[str] = 10,
    devices: Sequence[str] = DEVICES,
    *,
    reference: float = REFERENCE_STIFFNESS,
    comparison_percent: Sequence[float] = COMPARISON_PERCENT,
    repetitions: int = REPETITIONS,
    shuffle_devices: bool = True,
    seed: int = 0,
    first_index: int = 0,
) -> list[Trial]:
    """The trial list of the §3.5 experiment, in presentation order.

    Every subject works through one block per device; within a block each
    comparison appears ``repetitions`` times in random order, and which spring of
    a pair comes first is a fair coin. The thesis does not state the device order
    or the order within a pair; we randomise both (counterbalancing) and make
    each subject's session depend only on ``(seed, subject position)``, so adding
    a subject does not reshuffle the others (`first_index` is the position of the
    first subject: ``protocol(["S03"], first_index=2)`` is S03's session of
    ``protocol(10)``, which a study enrolling one participant at a time uses).

    Args:
        subjects: number of subjects (named "S01", "S02", ...) or their names.
        devices: device names, one block each.
        reference: reference stiffness [N/m] (thesis: 50 N/m).
        comparison_percent: comparisons in % of the reference (thesis: 0, ±5, ±15, ±25, ±35).
        repetitions: presentations of every comparison per device (thesis: 10).
        shuffle_devices: randomise the device order per subject (else as given).
        seed: seed of the ordering.
        first_index: position of the first subject (>= 0).

    Returns:
        list of `Trial`: ``len(subjects) · len(devices) · len(comparison_percent) · repetitions``
        trials, grouped by subject, each subject's trials in presentation order.

    Raises:
        InvalidInput: no subjects or devices, duplicate names, non-positive
            reference or repetitions, or a comparison at or below -100 %.
    """
    if isinstance(subjects, int | np.integer):
        if subjects < 1:
            raise InvalidInput(f"subjects: need at least one subject, got {subjects}")
        names = [f"S{i + 1:02d}" for i in range(int(subjects))]
    else:
        names = [str(s) for s in subjects]
    devs = [str(d) for d in devices]
    for arg, items in (("subjects", names), ("devices", devs)):
        if not items:
            raise InvalidInput(f"{arg}: empty")
        if len(set(items)) != len(items):
            raise InvalidInput(f"{arg}: duplicate names in {items}")
    if not (math.isfinite(reference) and reference > 0):
        raise InvalidInput(f"reference: must be a positive stiffness in N/m, got {reference!r}")
    pct = np.asarray(comparison_percent, dtype=float)
    if pct.ndim != 1 or pct.size == 0 or not np.isfinite(pct).all() or (pct <= -100).any():
        raise InvalidInput(f"comparison_percent: need finite values above -100 %, got {comparison_percent!r}")
    if int(repetitions) != repetitions or repetitions < 1:
        raise InvalidInput(f"repetitions: must be a positive integer, got {repetitions!r}")
    if int(first_index) != first_index or first_index < 0:
        raise InvalidInput(f"first_index: must be an integer >= 0, got {first_index!r}")

    trials: list[Trial] = []
    base = np.repeat(pct, int(repetitions))
    for s_idx, subject in enumerate(names):
        rng = np.random.default_rng([int(seed), int(first_index) + s_idx])
        order = rng.permutation(len(devs)) if shuffle_devices else np.arange(len(devs))
        index = 0
        for block, d_idx in enumerate(order):
            p = base[rng.permutation(base.size)]
            first = rng.random(base.size) < 0.5
            for k in range(base.size):
                trials.append(
                    Trial(
                        subject=subject,
                        device=devs[d_idx],
                        index=index,
                        block=block,
                        reference=float(reference),
                        comparison=float(reference * (1.0 + p[k] / 100.0)),
                        comparison_percent=float(p[k]),
                        comparison_first=bool(first[k]),
                    )
                )
                index += 1
    return trials


# --------------------------------------------------------------------------- responses


@dataclasses.dataclass(frozen=True)
class Responses:
    """Responses of a stiffness-discrimination experiment, one entry per trial.

    Attributes:
        subject: (T,) subject identifiers (str).
        device: (T,) device names (str).
        comparison: (T,) comparison stiffness [N/m].
        response: (T,) 1 if the comparison was judged stiffer than the reference, else 0.
        line: (T,) source line of each trial in a CSV file, or -1 (for error messages).
    """

    subject: np.ndarray
    device: np.ndarray
    comparison: np.ndarray
    response: np.ndarray
    line: np.ndarray = dataclasses.field(default=None, repr=False)  # type: ignore[arg-type]  # None: filled in __post_init__

    def __post_init__(self) -> None:
        subj = np.asarray(self.subject, dtype=object).astype(str)
        dev = np.asarray(self.device, dtype=object).astype(str)
        try:
            comp = np.asarray(self.comparison, dtype=float)
        except (TypeError, ValueError):
            raise InvalidInput("comparison: cannot be read as numbers") from None
        resp_raw = np.asarray(self.response)
        n = comp.shape[0] if comp.ndim == 1 else -1
        for name, arr in (("subject", subj), ("device", dev), ("comparison", comp), ("response", resp_raw)):
            if arr.ndim != 1 or arr.shape[0] != n:
                raise InvalidInput(f"{name}: expected shape ({n},) like comparison, got {arr.shape}")
        line = np.full(n, -1, dtype=int) if self.line is None else np.asarray(self.line, dtype=int)
        if line.shape != (n,):
            raise InvalidInput(f"line: expected shape ({n},), got {line.shape}")

        def where(i: int) -> str:
            return f"line {line[i]}" if line[i] >= 0 else f"trial {i}"

        bad = np.flatnonzero(~np.isfinite(comp) | (comp <= 0))
        if bad.size:
            i = int(bad[0])
            raise InvalidInput(f"{where(i)}, column 'comparison': {comp[i]!r} is not a positive stiffness")
        try:
            resp = resp_raw.astype(float)
        except (TypeError, ValueError):
            resp = np.full(n, np.nan)
        bad = np.flatnonzero(~np.isin(resp, (0.0, 1.0)))
        if bad.size:
            i = int(bad[0])
            raise InvalidInput(f"{where(i)}, column 'response': {resp_raw[i]!r} is not 0 or 1")
        object.__setattr__(self, "subject", subj)
        object.__setattr__(self, "device", dev)
        object.__setattr__(self, "comparison", comp)
        object.__setattr__(self, "response", resp.astype(np.int8))
        object.__setattr__(self, "line", line)

    def __len__(self) -> int:
        return int(self.comparison.shape[0])

    @classmethod
    def from_trials(cls, trials: Sequence[Trial], response: ArrayLike) -> Responses:
        """Join a `protocol` trial list with its responses (1 = comparison judged stiffer).

        Args:
            trials: (T,) trials.
            response: (T,) responses in {0, 1}.
        """
        r = np.asarray(response)
        if r.shape != (len(trials),):
            raise InvalidInput(f"response: expected shape ({len(trials)},) like trials, got {r.shape}")
        return cls(
            subject=np.array([t.subject for t in trials], dtype=object),
            device=np.array([t.device for t in trials], dtype=object),
            comparison=np.array([t.comparison for t in trials], dtype=float),
            response=r,
        )

    def groups(self) -> dict[tuple[str, str], np.ndarray]:
        """Indices of the trials of every (subject, device), in order of first appearance."""
        out: dict[tuple[str, str], list[int]] = {}
        for i, key in enumerate(zip(self.subject.tolist(), self.device.tolist())):
            out.setdefault(key, []).append(i)
        return {k: np.asarray(v) for k, v in out.items()}

    def select(self, subject: str, device: str) -> tuple[np.ndarray, np.ndarray]:
        """(comparison [N/m], response) of one subject and device."""
        m = (self.subject == str(subject)) & (self.device == str(device))
        if not m.any():
            raise InvalidInput(f"subject/device: no trials for subject {subject!r} on device {device!r}")
        return self.comparison[m], self.response[m]


def pool(comparison: ArrayLike, response: ArrayLike) -> np.ndarray:
    """Trials pooled per stimulus level: psignifit's ``[level, n_stiffer, n_trials]`` rows.

    Args:
        comparison: (T,) comparison stiffness [N/m].
        response: (T,) 0/1.

    Returns:
        (k, 3) array, levels ascending.
    """
    c = np.asarray(comparison, dtype=float)
    r = np.asarray(response, dtype=float)
    levels, inv = np.unique(c, return_inverse=True)
    n = np.bincount(inv, minlength=levels.size).astype(float)
    k = np.bincount(inv, weights=r, minlength=levels.size)
    return np.column_stack([levels, k, n])


def simulate_responses(
    trials: Sequence[Trial],
    *,
    pse: float | Mapping[tuple[str, str], float],
    jnd: float | Mapping[tuple[str, str], float],
    lapse: float = 0.0,
    seed: int = 0,
) -> Responses:
    """Synthetic responses from a known cumulative-Gaussian observer (for tests and power studies).

    ``P(comparison judged stiffer) = λ + (1 − 2λ) Φ((c − PSE) / σ)`` with
    ``σ = JND / z₀.₇₅``, so the lapse-free function has exactly the given PSE and
    JND (eq. 3.26). Independent of any physics: the perceptual model of the
    simulated-device experiment lives in `rhi.sim`.

    Args:
        trials: trial list (e.g. from `protocol`).
        pse: PSE [N/m], one value or a mapping ``(subject, device) -> PSE``.
        jnd: JND [N/m] > 0, one value or a mapping ``(subject, device) -> JND``.
        lapse: lapse rate λ in [0, 0.5) at both ends.
        seed: seed of the Bernoulli draws.

    Returns:
        `Responses` in the order of ``trials``.

    Raises:
        InvalidInput: non-positive JND, lapse outside [0, 0.5), or a mapping without
            an entry for some (subject, device).
    """
    from scipy.stats import norm

    if not (0.0 <= lapse < 0.5):
        raise InvalidInput(f"lapse: must lie in [0, 0.5), got {lapse!r}")

    def value(name: str, spec: Any, t: Trial) -> float:
        if isinstance(spec, Mapping):
            try:
                return float(spec[(t.subject, t.device)])
            except KeyError:
                raise InvalidInput(f"{name}: no value for subject {t.subject!r}, device {t.device!r}") from None
        return float(spec)

    c = np.array([t.comparison for t in trials], dtype=float)
    mu = np.array([value("pse", pse, t) for t in trials])
    j = np.array([value("jnd", jnd, t) for t in trials])
    if not np.isfinite(mu).all() or not (np.isfinite(j).all() and (j > 0).all()):
        raise InvalidInput("pse/jnd: need finite values and a positive JND")
    p = lapse + (1.0 - 2.0 * lapse) * norm.cdf((c - mu) / (j / Z75))
    rng = np.random.default_rng(seed)
    return Responses.from_trials(trials, (rng.random(c.size) < p).astype(np.int8))
