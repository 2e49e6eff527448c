"""Planar kinematics of a haptic interface (master) and a slave for the design problem.

A master model takes design parameters and world targets and returns the IK
configuration, the task-frame Jacobian ``J_M^2D`` (eq. 4.26) and whether each target
was reached. Two models share that interface:

* `DeviceMaster`: any bundled device (`rhi.device(name, **params)`), IK by
  `Device.ik` warm-started from the previous (neighbouring) sample, ``J = jacobian(q)[:2]``.
* `Phantom3Master`: the closed form of eq. 4.25b for ``phantom3`` (vectorised; the
  elbow branch is unique because the parallelogram limit keeps θ2 − θ3 + 90° in
  [35°, 145°]). Tests check it against `DeviceMaster("phantom3")`.

`slave_jacobians` solves the slave once per workspace (the slave does not change with D).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from typing import Protocol

import numpy as np

from rhi.devices.model import Device, device
from rhi.devices.spec import bundled_spec
from rhi.errors import InvalidInput, Unreachable


def declared_bounds(name: str) -> dict[str, tuple[float, float]]:
    """The parameter bounds a bundled device declares in its device.toml: {name: (min, max)} [m or rad].

    Raises:
        UnknownDevice: no bundled device has that name.
    """
    return bundled_spec(name).parameter_bounds


@dataclasses.dataclass(frozen=True)
class Solution:
    """IK of a batch of targets. q: (N, n) [rad]; J: (N, 2, n) planar task Jacobian; ok: (N,) bool."""

    q: np.ndarray
    J: np.ndarray
    ok: np.ndarray
    q_min: np.ndarray
    q_max: np.ndarray


def _solve_device(dev: Device, targets: np.ndarray, q0: np.ndarray) -> Solution:
    """IK of each target (N, m) with warm start from the last solved neighbour."""
    n = len(targets)
    q = np.zeros((n, dev.n))
    ok = np.zeros(n, dtype=bool)
    guess = np.asarray(q0, dtype=float)
    for k, x in enumerate(targets):
        try:
            q[k] = dev.ik(x, guess, restarts=2, max_iter=60, tol=1e-9)
            ok[k] = True
            guess = q[k]
        except Unreachable:
            q[k] = guess
    J = dev.jacobian(q)[:, :2, :]
    return Solution(q, J, ok, dev.q_min, dev.q_max)


class Master(Protocol):
    """A haptic interface's kinematics for the design problem: IK at the targets for design parameters.

    A master may also provide ``radial_range(params) -> (lo, hi)`` [m] (needed by ``DesignProblem(r0="auto")``).
    """

    def solve(self, params: Mapping[str, float], targets: np.ndarray) -> Solution:
        """IK solution at targets (N, 2) [m] for the design `params`."""
        ...


@dataclasses.dataclass(frozen=True)
class DeviceMaster:
    """A bundled device as the design's master; the working plane height is the parameter `plane` (if any).

    Attributes:
        name: bundled device name.
        plane: name of the parameter that sets the height of the working plane (``z_ph`` for
            phantom3), or None for a planar device.
        q0: (n,) initial IK guess [rad] (None: mid-range).
    """

    name: str = "phantom3"
    plane: str | None = "z_ph"
    q0: tuple[float, ...] | None = None

    def bounds(self) -> dict[str, tuple[float, float]]:
        """Declared parameter bounds of the device (device.toml) [m or rad]."""
        return declared_bounds(self.name)

    def solve(self, params: Mapping[str, float], targets: np.ndarray) -> Solution:
        """IK at world targets (N, 2) [m] on the working plane; ``J[:, :2]`` is eq. 4.26's J_M^2D."""
        dev = device(self.name, **params)
        if self.plane is not None:
            z = dev.params.get(self.plane, 0.0)
            targets = np.column_stack([targets, np.full(len(targets), z)])
        q0 = np.array(self.q0) if self.q0 is not None else 0.5 * (np.clip(dev.q_min, -np.pi, None)
                                                                   + np.clip(dev.q_max, None, np.pi))
        return _solve_device(dev, targets, q0)


@dataclasses.dataclass(frozen=True)
class Phantom3Master:
    """Closed-form planar kinematics of phantom3 (eq. 4.25b) on the plane z = Z_PH, rotated by θz (eq. 4.26).

    Forward kinematics in the HI base frame: x = c1(l1c2 + l2s3), y = s1(l1c2 + l2s3),
    z = l1s2 − l2c3 (models/phantom3/README.md). Joint limits are read from the bundled
    device (including the parallelogram limit −55° <= θ2 − θ3 <= 55°).

    Attributes:
        l1: first link [m] (0.21 m, models/phantom3/README.md).
    """

    l1: float = 0.21
    name: str = "phantom3"

    def bounds(self) -> dict[str, tuple[float, float]]:
        """Declared parameter bounds of phantom3 (eq. 4.27; Z_PH derived, see its README) [m or rad]."""
        return declared_bounds(self.name)

    def _limits(self) -> tuple[np.ndarray, np.ndarray, float, float]:
        return _phantom3_limits()

    def radial_range(self, params: Mapping[str, float]) -> tuple[float, float]:
        """(min, max) horizontal distance from the yaw axis reachable on the plane z = z_ph within the limits [m].

        Exact: on the plane, r = l1 c2 + l2 s3 has no stationary point inside the joint-limit polygon of
        (θ2, θ3) (its Jacobian with z has determinant −l1 l2 cos(θ2 − θ3) ≠ 0 there, as |θ2 − θ3| <= 55°),
        so its extremes lie where the curve z_ph = l1 s2 − l2 c3 crosses an edge of the polygon: θ2 or θ3
        at a limit, or θ2 − θ3 at the parallelogram limit. (0, 0) if the plane is out of reach. Memoised
        on (l1, l2, z_ph): a θz-only design evaluates it once.
        """
        return _radial_range(float(self.l1), float(params.get("l2", 0.165)), float(params.get("z_ph", 0.0539)))

    def solve(self, params: Mapping[str, float], targets: np.ndarray) -> Solution:
        """IK at world targets (N, 2) [m] on the plane z = z_ph; J: (N, 2, 3) = [[cz, −sz, 0], [sz, cz, 0]] J_PH."""
        sol = self.solve_many([params], np.asarray(targets, dtype=float)[None])
        return Solution(sol.q[0], sol.J[0], sol.ok[0], sol.q_min, sol.q_max)

    def solve_many(self, params: Sequence[Mapping[str, float]], targets: np.ndarray) -> Solution:
        """`solve` for P designs at once: targets (P, N, 2) [m]; q (P, N, 3), J (P, N, 2, 3), ok (P, N).

        Element-wise array operations over a leading design axis: the same numbers as `solve` per design.
        """
        l1 = self.l1
        per = []
        for p in params:  # the design's scalars, as one design's solve computes them
            l2_i, tz_i, z_i = float(p.get("l2", 0.165)), float(p.get("theta_z", 0.0)), float(p.get("z_ph", 0.0539))
            if l2_i <= 0 or l1 <= 0:
                raise InvalidInput(f"l2: link lengths must be positive, got l1={l1}, l2={l2_i}")
            per.append((l2_i, np.cos(tz_i), np.sin(tz_i), z_i))
        l2, cz, sz, z = (np.array(v, dtype=float)[:, None] for v in zip(*per, strict=True))
        q_min, q_max, _, _ = self._limits()
        t = np.asarray(targets, dtype=float)
        xb = cz * t[..., 0] + sz * t[..., 1]  # world -> HI base frame (inverse yaw)
        yb = -sz * t[..., 0] + cz * t[..., 1]
        th1 = np.arctan2(yb, xb)
        th2, th3, ok = _plane_ik(l1, l2, np.hypot(xb, yb), z)
        q = np.stack([th1, th2, th3], -1)
        ok &= (th1 >= q_min[0] - _TOL) & (th1 <= q_max[0] + _TOL)
        s1, c1, s2, c2, s3, c3 = np.sin(th1), np.cos(th1), np.sin(th2), np.cos(th2), np.sin(th3), np.cos(th3)
        a = l1 * c2 + l2 * s3
        J = np.empty(t.shape[:-1] + (2, 3))
        # eq. 4.25b rows x (j0), y (j1), rotated by θz (eq. 4.26)
        for i, (j0, j1) in enumerate(((-s1 * a, c1 * a), (-l1 * c1 * s2, -l1 * s1 * s2), (l2 * c1 * c3, l2 * c3 * s1))):
            J[..., 0, i] = cz * j0 - sz * j1
            J[..., 1, i] = sz * j0 + cz * j1
        return Solution(q, J, ok, q_min, q_max)


_LIMITS_CACHE: dict[str, tuple] = {}


_TOL = 1e-9  # joint-limit tolerance of the IK [rad]


def _plane_ik(l1: float, l2: float | np.ndarray, r: float | np.ndarray, z: float | np.ndarray,
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(θ2, θ3, ok) reaching (r, z) on the HI's vertical plane, within the θ2, θ3 and parallelogram limits.

    The elbow branch is unique: the parallelogram limit keeps θ2 − θ3 + 90° in [35°, 145°]. Broadcasts.
    """
    q_min, q_max, lo, hi = _phantom3_limits()
    cd = (r**2 + z**2 - l1**2 - l2**2) / (2 * l1 * l2)
    delta = np.arccos(np.clip(cd, -1.0, 1.0))  # α − β = θ2 − θ3 + 90° in [0, π]
    th2 = np.arctan2(z, r) - np.arctan2(-l2 * np.sin(delta), l1 + l2 * np.cos(delta))
    th3 = th2 - delta + np.pi / 2
    ok = ((np.abs(cd) <= 1.0) & (th2 >= q_min[1] - _TOL) & (th2 <= q_max[1] + _TOL) & (th3 >= q_min[2] - _TOL)
          & (th3 <= q_max[2] + _TOL) & (th2 - th3 >= lo - _TOL) & (th2 - th3 <= hi + _TOL))
    return th2, th3, ok


@functools.lru_cache(maxsize=4096)
def _radial_range(l1: float, l2: float, z: float) -> tuple[float, float]:
    """`Phantom3Master.radial_range`: the edge crossings of the level curve, then which gaps between them are reached."""
    q_min, q_max, lo, hi = _phantom3_limits()
    th2: list[float] = []
    th3: list[float] = []
    for b2 in q_min[1], q_max[1]:  # θ2 at a limit: c3 = (l1 s2 − z) / l2
        c3 = (l1 * np.sin(b2) - z) / l2
        if abs(c3) <= 1:
            th2 += [b2, b2]
            th3 += [np.arccos(c3), -np.arccos(c3)]
    for b3 in q_min[2], q_max[2]:  # θ3 at a limit: s2 = (z + l2 c3) / l1
        s2 = (z + l2 * np.cos(b3)) / l1
        if abs(s2) <= 1:
            th2 += [np.arcsin(s2), np.pi - np.arcsin(s2)]
            th3 += [b3, b3]
    for d in lo, hi:  # θ3 = θ2 − d: (l1 − l2 sin d) s2 − l2 cos d c2 = R sin(θ2 + φ) = z
        a, b = l1 - l2 * np.sin(d), -l2 * np.cos(d)
        R, phi = np.hypot(a, b), np.arctan2(b, a)
        if abs(z) <= R:
            for t in np.arcsin(z / R) - phi, np.pi - np.arcsin(z / R) - phi:
                th2.append(t)
                th3.append(t - d)
    t2 = (np.asarray(th2) + np.pi) % (2 * np.pi) - np.pi
    t3 = (np.asarray(th3) + np.pi) % (2 * np.pi) - np.pi
    on = ((t2 >= q_min[1] - _TOL) & (t2 <= q_max[1] + _TOL) & (t3 >= q_min[2] - _TOL) & (t3 <= q_max[2] + _TOL)
          & (t2 - t3 >= lo - _TOL) & (t2 - t3 <= hi + _TOL))
    # the reached r form intervals whose ends are these crossings (or r = 0): keep the gaps whose middle is reached
    ends = np.unique(np.concatenate([[0.0], (l1 * np.cos(t2) + l2 * np.sin(t3))[on]]))
    ends = ends[ends >= 0]
    mid = 0.5 * (ends[:-1] + ends[1:])
    reached = _plane_ik(l1, l2, mid, z)[2]
    if not reached.any():
        return (0.0, 0.0)
    return (float(ends[:-1][reached].min()), float(ends[1:][reached].max()))


def _phantom3_limits() -> tuple[np.ndarray, np.ndarray, float, float]:
    if "phantom3" not in _LIMITS_CACHE:
        dev = device("phantom3")
        L = dev.linear_limits
        if L is None:
            raise InvalidInput("phantom3: the parallelogram's linear joint limit is missing from its device.toml")
        _LIMITS_CACHE["phantom3"] = (dev.q_min, dev.q_max, float(L.lower[0]), float(L.upper[0]))
    return _LIMITS_CACHE["phantom3"]


def slave_solution(name: str, points: np.ndarray, q0) -> Solution:
    """IK of the slave at the workspace samples (N, 2) [m] in its base frame, warm-started along the samples."""
    return _solve_device(device(name), np.asarray(points, dtype=float), np.asarray(q0, dtype=float))
