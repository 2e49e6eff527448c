"""Identification records: position and force along u per sample, projected, simulated or read from CSV."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from rhi._validate import as_array, unit_vector
from rhi.analysis._csv import read_rows
from rhi.analysis.sysid.signals import MIN_SAMPLES, UNIFORM_TOLERANCE
from rhi.errors import InvalidInput

FloatArray = np.ndarray


@dataclasses.dataclass(frozen=True)
class Record:
    """One identification trial: position and force along ``u`` sampled in time.

    Attributes:
        time: (N,) strictly increasing, uniformly sampled time [s].
        position: (N,) end-effector position along ``u`` [m] (any origin).
        force: (N,) external force along ``u`` [N].
        label: trial name used in error messages and results.
    """

    time: FloatArray
    position: FloatArray
    force: FloatArray
    label: str = ""

    def __post_init__(self) -> None:
        name = f"record {self.label!r}" if self.label else "record"
        t = as_array(f"{name}.time", self.time, shape_tail=(None,))
        x = as_array(f"{name}.position", self.position, shape_tail=(None,))
        f = as_array(f"{name}.force", self.force, shape_tail=(None,))
        if t.ndim != 1 or x.shape != t.shape or f.shape != t.shape:
            raise InvalidInput(
                f"{name}: time, position and force must be 1-D of equal length, "
                f"got shapes {t.shape}, {x.shape}, {f.shape}"
            )
        if t.size < MIN_SAMPLES:
            raise InvalidInput(f"{name}: {t.size} samples; need at least {MIN_SAMPLES}")
        dt = np.diff(t)
        if (dt <= 0).any():
            i = int(np.flatnonzero(dt <= 0)[0]) + 1
            raise InvalidInput(
                f"{name}.time: not strictly increasing at sample {i} ({float(t[i - 1])!r} then {float(t[i])!r})"
            )
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "position", x)
        object.__setattr__(self, "force", f)

    @property
    def sample_rate(self) -> float:
        """Sampling rate [Hz] from the median interval."""
        return 1.0 / float(np.median(np.diff(self.time)))

    def is_uniform(self, tolerance: float = UNIFORM_TOLERANCE) -> bool:
        """Whether every sampling interval is within ``tolerance`` (relative) of the median."""
        dt = np.diff(self.time)
        med = np.median(dt)
        return bool(np.all(np.abs(dt - med) <= tolerance * med))

    def resampled(self, rate: float) -> Record:
        """The record linearly interpolated onto a uniform grid of ``rate`` [Hz]."""
        if not (math.isfinite(rate) and rate > 0):
            raise InvalidInput(f"rate: must be a positive sampling rate in Hz, got {rate!r}")
        t = np.arange(self.time[0], self.time[-1] + 0.5 / rate, 1.0 / rate)
        t = t[t <= self.time[-1]]
        return Record(t, np.interp(t, self.time, self.position), np.interp(t, self.time, self.force), self.label)


def project(positions: ArrayLike, forces: ArrayLike, u: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Project Cartesian trajectories and forces onto a direction: ``x = p·û``, ``F = f·û``.

    Args:
        positions: (..., N, m) end-effector positions [m] (e.g. from forward kinematics).
        forces: (..., N, m) external forces [N] in the same frame, or (..., N) already along ``u``.
        u: (m,) direction (normalised internally, must be non-zero).

    Returns:
        ``(x, F)``: (..., N) position along ``û`` [m] and (..., N) force along ``û`` [N].

    Raises:
        InvalidInput: mismatched shapes, non-finite entries or zero-length ``u``.
    """
    p = as_array("positions", positions, ndim_min=2)
    u = unit_vector("u", u, p.shape[-1])
    if u.ndim != 1:
        raise InvalidInput(f"u: expected shape ({p.shape[-1]},), got {u.shape}")
    f = as_array("forces", forces, ndim_min=1)
    x = p @ u
    if f.shape == p.shape:
        F = f @ u
    elif f.shape == x.shape:
        F = f
    else:
        raise InvalidInput(f"forces: expected shape {p.shape} or {x.shape} to match positions, got {f.shape}")
    return x, F




def simulate_record(
    mass: float,
    damping: float,
    force: float,
    *,
    duration: float,
    rate: float = 1000.0,
    offset: float = 0.0,
    position_noise: float = 0.0,
    force_noise: float = 0.0,
    seed: int | Sequence[int] | None = None,
    label: str = "",
) -> Record:
    """A synthetic trial: ``M ẍ + Φ ẋ + c = F`` from rest, integrated by ``scipy.integrate.solve_ivp``.

    A test and teaching aid, not the physics simulation (that is `rhi.sim`): the
    true parameters are known, so `identify` can be checked against them.

    Args:
        mass: M [kg] > 0.
        damping: Φ [N s/m] >= 0.
        force: constant external force F [N] applied from t = 0.
        duration: record length [s].
        rate: sampling rate [Hz].
        offset: constant opposing force c [N].
        position_noise: standard deviation of white noise added to the position [m].
        force_noise: standard deviation of white noise added to the force [N].
        seed: seed of the noise generator (required when any noise is non-zero); give
            every trial its own seed, e.g. ``(seed, trial)``: trials with identical
            noise are not independent, and the cluster-robust errors of `identify`
            assume independent trials.
        label: trial name.

    Returns:
        `Record` sampled at ``rate`` on [0, duration].
    """
    from scipy.integrate import solve_ivp

    for name, val, ok in (
        ("mass", mass, mass > 0),
        ("damping", damping, damping >= 0),
        ("duration", duration, duration > 0),
        ("rate", rate, rate > 0),
        ("position_noise", position_noise, position_noise >= 0),
        ("force_noise", force_noise, force_noise >= 0),
    ):
        if not (math.isfinite(val) and ok):
            raise InvalidInput(f"{name}: invalid value {val!r}")
    if (position_noise > 0 or force_noise > 0) and seed is None:
        raise InvalidInput("seed: required when noise is added (reproducible runs)")
    t = np.arange(0.0, duration + 0.5 / rate, 1.0 / rate)

    def rhs(_t, s):
        return [s[1], (force - offset - damping * s[1]) / mass]

    sol = solve_ivp(rhs, (0.0, t[-1]), [0.0, 0.0], t_eval=t, method="DOP853", rtol=1e-10, atol=1e-13)
    x = sol.y[0]
    f = np.full_like(t, force)
    if position_noise > 0 or force_noise > 0:
        rng = np.random.default_rng(seed)
        x = x + position_noise * rng.standard_normal(t.size)
        f = f + force_noise * rng.standard_normal(t.size)
    return Record(t, x, f, label)


_POSITION_AXES = ("x", "y", "z")
_FORCE_AXES = ("fx", "fy", "fz")


def from_csv(path: str | Path, *, u: ArrayLike | None = None) -> list[Record]:
    """Read a user's recorded identification trials from a CSV file.

    The header names the columns (case and surrounding spaces ignored):

    - ``time`` [s], strictly increasing within a trial;
    - the position: ``position`` (already along ``u``) [m], or Cartesian
      ``x, y(, z)`` [m] projected onto ``u``;
    - the force: ``force`` (along ``u``) [N], or ``fx, fy(, fz)`` [N] projected onto ``u``;
    - optionally ``trial``: a label; rows with the same label form one record
      (in file order), so ten trials may share one file.

    Args:
        path: CSV file.
        u: (m,) direction, required when positions or forces are Cartesian.

    Returns:
        list of `Record`, one per trial, in order of first appearance.

    Raises:
        InvalidInput: unreadable file, missing column, a non-numeric or non-finite
            value (naming the line and column), time not increasing (naming the
            line), or a trial with fewer than `MIN_SAMPLES` rows.
    """
    path, cols, index, body = read_rows(path)
    if "time" not in index:
        raise InvalidInput(f"{path.name}: missing column 'time' (found {cols})")

    def cartesian(axes: Sequence[str]) -> list[str]:
        present = [a for a in axes if a in index]
        return present if present[:2] == list(axes[:2]) else []

    if "position" in index:
        pos_cols = ["position"]
    else:
        pos_cols = cartesian(_POSITION_AXES)
        if not pos_cols:
            raise InvalidInput(f"{path.name}: missing column 'position' (or Cartesian 'x', 'y'[, 'z']); found {cols}")
    if "force" in index:
        force_cols = ["force"]
    else:
        force_cols = cartesian(_FORCE_AXES)
        if not force_cols:
            raise InvalidInput(f"{path.name}: missing column 'force' (or Cartesian 'fx', 'fy'[, 'fz']); found {cols}")
    m = max(len(pos_cols), len(force_cols))
    if m > 1:
        if u is None:
            raise InvalidInput(f"u: required to project the Cartesian columns {pos_cols + force_cols} of {path.name}")
        u_vec = unit_vector("u", u)
        if u_vec.shape != (m,):
            raise InvalidInput(
                f"u: expected {m} components for columns {pos_cols + force_cols}, got shape {u_vec.shape}"
            )
        if 1 < len(pos_cols) != m or 1 < len(force_cols) != m:
            raise InvalidInput(
                f"{path.name}: position columns {pos_cols} and force columns {force_cols} differ in dimension"
            )
    numeric = ["time", *pos_cols, *force_cols]
    trial_i = index.get("trial")

    groups: dict[str, list[tuple[int, list[float]]]] = {}
    for line, row in body:
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) < len(cols):
            raise InvalidInput(f"{path.name}, line {line}: {len(row)} fields; the header has {len(cols)}")
        vals = []
        for c in numeric:
            text = row[index[c]].strip()
            try:
                v = float(text)
            except ValueError:
                raise InvalidInput(f"{path.name}, line {line}, column '{c}': {text!r} is not a number") from None
            if not math.isfinite(v):
                raise InvalidInput(f"{path.name}, line {line}, column '{c}': non-finite value {text!r}")
            vals.append(v)
        label = row[trial_i].strip() if trial_i is not None else ""
        groups.setdefault(label, []).append((line, vals))
    if not groups:
        raise InvalidInput(f"{path.name}: no data rows")

    records = []
    for label, items in groups.items():
        name = f"trial {label!r}" if label else "the file"
        if len(items) < MIN_SAMPLES:
            raise InvalidInput(f"{path.name}: {name} has {len(items)} rows; need at least {MIN_SAMPLES}")
        lines = [ln for ln, _ in items]
        data = np.array([v for _, v in items])
        t = data[:, 0]
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            j = int(bad[0]) + 1
            raise InvalidInput(
                f"{path.name}, line {lines[j]}, column 'time': {float(t[j])!r} does not increase "
                f"(previous row of {name}: {float(t[j - 1])!r})"
            )
        pos = data[:, 1 : 1 + len(pos_cols)]
        frc = data[:, 1 + len(pos_cols) :]
        x = pos[:, 0] if len(pos_cols) == 1 else pos @ u_vec
        f = frc[:, 0] if len(force_cols) == 1 else frc @ u_vec
        records.append(Record(t, x, f, label))
    return records
