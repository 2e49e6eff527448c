"""Compiled kernels of the simulation loop: the handle's kinematics and the hand's force per physics step.

`handle_state` is what a haptic rendering loop computes before its controller runs (the virtual
environment's input): forward kinematics of a tree of one-DoF revolute/prismatic joints packed by
`rhi.devices.batch.pack`, the end-effector point p and its velocity ṗ = Σ_j J_j θ̇_j over the
joints j supporting the frame, with the linear Jacobian column J_j = ω_j × (p − o_j) for a
revolute joint and ω_j for a prismatic one (ω_j = R_j a_j the joint's world axis, o_j its
origin); each joint's frame by `rhi.devices._compiled.chain.joint_frame` (Pinocchio's conventions), without the
inertias, the Jacobian's angular rows or the dynamics; with the virtual environment's force (walls,
fixtures and their sums). `hand_step` is `rhi.sim.Hand.force` (`rhi.sim.MinimumJerkPalpation.force`,
`rhi.sim.PushForce.force`) plus a physical `rhi.sim.Wall.force` at one physics step, read from MuJoCo's
sensors and written to the handle's applied force in the same call; `hand_period` runs a control period's
physics steps with it (with the hand of each step's time for a `rhi.sim.HandSequence`), MuJoCo's step
included (`rhi.sim.mjc`).
Imported by `rhi.sim.loop`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.devices._compiled.chain import joint_frame
from rhi.devices.batch import AXIS_COLUMN as _AX
from rhi.jit import jit, stack_empty
from rhi.sim.environment import Compose, Fixture, Wall
from rhi.sim.hand import Hand, HandSequence, MinimumJerkPalpation, PushForce
from rhi.sim.mjc import step1, step2

#: `hand_period`'s outcomes: the period ran; a step's force was not finite; MuJoCo flagged a step as diverged.
PERIOD_OK, PERIOD_NONFINITE, PERIOD_UNSTABLE = 0, 1, 2


@jit
def handle_state(ints, joints, fc, q, dq, out):
    """Write the end-effector position and velocity on the task rows at motor state (q, q̇) into `out`.

    Args:
        ints: (2 nθ + 1 + m,) int64: `pack`'s integer constants, then the task rows (world axes).
        joints: (nθ, 29) `pack`'s per-joint constants.
        fc: (12 + nθ + nθ n,) the frame placement (`pack`'s consts[:12]), the actuation offset b
            (nθ,) [rad or m] and the actuation map A (nθ, n) row-major: θ = A q + b.
        q: (n,) motor positions [rad].
        dq: (n,) motor velocities [rad/s].
        out: (2, m) output: the end-effector position [m], then its velocity [m/s]; or (3, m): then also the
            force of a virtual environment on the handle [N] (`_env_force`), its `env_constants` at the end
            of `fc`.
    """
    nt, n, m = joints.shape[0], q.shape[0], out.shape[1]
    oR, o = stack_empty((nt, 3, 3), np.float64), stack_empty((nt, 3), np.float64)  # local: on the stack
    RP, T = stack_empty((3, 3), np.float64), stack_empty((3, 3), np.float64)
    for j in range(nt):
        th = fc[12 + j]
        for k in range(n):
            th += fc[12 + nt + j * n + k] * q[k]
        joint_frame(ints, joints, j, th, oR, o, RP, T)
    f = ints[2 * nt]
    pt = stack_empty(3, np.float64)
    for r in range(3):
        pt[r] = fc[9 + r]
        if f >= 0:
            pt[r] = o[f, r] + oR[f, r, 0] * fc[9] + oR[f, r, 1] * fc[10] + oR[f, r, 2] * fc[11]
    v = stack_empty(3, np.float64)
    v[:] = 0.0
    j = f
    while j >= 0:  # the joints supporting the frame, from its own joint to the root
        dth = 0.0
        for k in range(n):
            dth += fc[12 + nt + j * n + k] * dq[k]
        R = oR[j]
        a0, a1, a2 = joints[j, _AX], joints[j, _AX + 1], joints[j, _AX + 2]
        w0 = R[0, 0] * a0 + R[0, 1] * a1 + R[0, 2] * a2
        w1 = R[1, 0] * a0 + R[1, 1] * a1 + R[1, 2] * a2
        w2 = R[2, 0] * a0 + R[2, 1] * a1 + R[2, 2] * a2
        if ints[nt + j]:  # ω × (p − o_j)
            d0, d1, d2 = pt[0] - o[j, 0], pt[1] - o[j, 1], pt[2] - o[j, 2]
            v[0] += (w1 * d2 - w2 * d1) * dth
            v[1] += (w2 * d0 - w0 * d2) * dth
            v[2] += (w0 * d1 - w1 * d0) * dth
        else:
            v[0] += w0 * dth
            v[1] += w1 * dth
            v[2] += w2 * dth
        j = ints[j]
    for i in range(m):
        r = ints[2 * nt + 1 + i]
        out[0, i] = pt[r]
        out[1, i] = v[r]
    if out.shape[0] == 3:
        _env_force(out[0], out[1], fc, 12 + nt + nt * n, out[2])


def wall_constants(wall) -> list[float]:
    """A `rhi.sim.Wall`'s constants for the kernels: its point (m,) [m], normal (m,), K_e [N/m], B_e [N s/m]."""
    return [*wall.point.tolist(), *wall.normal.tolist(), wall.stiffness, wall.damping]


def env_constants(env, m: int) -> list[float] | None:
    """A virtual environment's constants for `handle_state` (`_env_force`), or None where it has other parts.

    A `Wall`, a `Fixture` or a `Compose` of them, for a handle of m task rows. Layout: the number of
    parts, then each part's kind (0: wall, 1: fixture) and constants: a wall's `wall_constants`; a
    fixture's point (m,) [m], projector I − u uᵀ (m, m) row-major, K [N/m] and B [N s/m].
    """
    parts = env.parts if type(env) is Compose else (env,)
    c: list[float] = [float(len(parts))]
    for p in parts:
        if type(p) is Wall and p.point.shape == (m,):
            c += [0.0, *wall_constants(p)]
        elif type(p) is Fixture and p.point.shape == (m,):
            c += [1.0, *p.point.tolist(), *p._P.ravel().tolist(), p.stiffness, p.damping]
        else:
            return None
    return c


@jit
def _env_force(x, v, c, o, F):
    """Write the force (m,) [N] of the environment whose `env_constants` start at c[o] on the handle at x, ẋ into F.

    The parts' forces summed in order, each as its `force` computes it: a wall's −push n (`_wall_push`), a
    fixture's −(K (x − point) + B ẋ) (I − u uᵀ).
    """
    m = x.shape[0]
    for j in range(m):
        F[j] = 0.0
    count, o = int(c[o]), o + 1
    for _ in range(count):
        if c[o] == 0.0:
            push = _wall_push(x, v, c, o + 1)
            for j in range(m):
                F[j] += -push * c[o + 1 + m + j]
            o += 1 + 2 * m + 2
        else:
            K, B = c[o + 1 + m + m * m], c[o + 2 + m + m * m]
            for j in range(m):
                f = 0.0
                for i in range(m):
                    f += -(K * (x[i] - c[o + 1 + i]) + B * v[i]) * c[o + 1 + m + i * m + j]
                F[j] += f
            o += 3 + m + m * m


@jit
def _wall_push(x, v, c, o):
    """How hard a wall pushes the handle at x (m,) [m] moving at v (m,) [m/s]: max(K_e d + B_e ḋ, 0) [N].

    d = nᵀ(x − point) while positive, else 0 (`rhi.sim.Wall.force`: the force is −push n); the wall's
    `wall_constants` start at c[o].
    """
    m = x.shape[0]
    depth = 0.0
    for j in range(m):
        depth += (x[j] - c[o + j]) * c[o + m + j]
    if depth <= 0:
        return 0.0
    rate = 0.0
    for j in range(m):
        rate += v[j] * c[o + m + j]
    return max(c[o + 2 * m] * depth + c[o + 2 * m + 1] * rate, 0.0)


def hand_constants(hand, wall, m: int) -> np.ndarray:
    """The flat constants of `hand_period` for a `hand_supported` hand (or None) and a physical `Wall` (or None).

    Every hand as a sequence of P hands (P = 1 but for a `HandSequence`): P, the switch times (P − 1,) [s], the
    offsets (P,) of the hands' blocks, then the blocks, each one hand's `hand_step` constants (the wall repeated
    in each). No hand: a hand that never pushes (a one-point path with stiffness and damping 0), for a handle
    of m task rows.
    """
    hands, switch = (hand.hands, hand.switch) if type(hand) is HandSequence else ((hand,), ())
    blocks = [_hand_block(h, wall, m) for h in hands]
    P = len(blocks)
    offsets = 2 * P + np.cumsum([0] + [len(b) for b in blocks[:-1]])
    return np.concatenate([[P, *switch], offsets, *blocks]).astype(float)


def _hand_block(hand, wall, m: int) -> np.ndarray:
    """`hand_step`'s constants for a `Hand`, `MinimumJerkPalpation`, `PushForce` or None and a `Wall` (or None).

    Layout: k, m, start [s], speed [m/s], K_h [N/m], B_h [N s/m], max |F_h| [N] (inf: none), then the
    wall flag (1/0), its point (m,) [m], normal (m,), K_e [N/m] and B_e [N s/m] (zeros without a wall),
    then for a `Hand` the path's arc lengths (k,) [m], its points (k, m) [m] and segment directions
    (k − 1, m); for a `MinimumJerkPalpation` k = 0, the stroke's duration [s] in place of the speed, then
    its depth [m], start (m,) [m] and direction (m,); for a `PushForce` k = −1 and its force (m,) [N].
    """
    if hand is None:
        return np.array([1, m, 0.0, 0.0, 0.0, 0.0, np.inf, *physical_constants(wall, m), 0.0, *([0.0] * m)])
    if type(hand) is PushForce:
        head = [-1, m, hand.start, 0.0, 0.0, 0.0, np.inf]
        return np.array([*head, *physical_constants(wall, m), *(hand.magnitude * hand.direction).tolist()])
    if type(hand) is MinimumJerkPalpation:
        m = hand.start.shape[0]
        head = [0, m, 0.0, hand.duration, hand.stiffness, hand.damping, hand.max_force]
        return np.array([*head, *physical_constants(wall, m), hand.depth, *hand.start.tolist(), *hand.direction.tolist()],
                        dtype=float)
    path = hand.path
    P = np.asarray(path.points, dtype=float)
    k, m = P.shape
    head = [k, m, path.start, path.speed, hand.stiffness, hand.damping,
            np.inf if hand.max_force is None else hand.max_force]
    return np.concatenate([head, physical_constants(wall, m), path._s, P.ravel(), np.ravel(path._u)]).astype(float)


def physical_constants(wall, m: int) -> list[float]:
    """The physical wall's part of `hand_constants`: its flag and `wall_constants` (zeros without one)."""
    return [1.0, *wall_constants(wall)] if wall is not None else [0.0] * (2 * m + 3)


def hand_supported(hand, wall, m: int) -> bool:
    """Whether `hand_constants` describes `hand` and the physical `wall` (or None) for a handle of m task rows.

    A `Hand`, a `MinimumJerkPalpation`, a `PushForce` or a `HandSequence` of them.
    """
    if type(hand) is HandSequence:
        return all(type(h) is not HandSequence and hand_supported(h, wall, m) for h in hand.hands)
    if type(hand) is Hand:
        dim = hand.path.points.shape[1]
    elif type(hand) is MinimumJerkPalpation:
        dim = hand.start.shape[0]
    elif type(hand) is PushForce:
        dim = hand.direction.shape[0]
    else:
        return False
    return dim == m and (wall is None or (type(wall) is Wall and wall.point.shape == (m,)))


@jit
def hand_step(t, sd, idx, c, F, xfrc, acc):
    """The hand's force (and a physical wall's) on the handle for one physics step, from MuJoCo's sensors.

    First adds the user's work of the previous step, acc[1] · F_h·ẋ (F the previous step's hand
    force, ẋ the handle velocity now, acc[1] the timestep) to acc[0] when acc[2] is nonzero; then
    F_h = K_h (x_r − x) + B_h (ẋ_r − ẋ) at the reference x_r, ẋ_r of the path (or the stroke) at time t
    (saturated at max |F_h|), as `rhi.sim.Hand.force` (`MinimumJerkPalpation.force`), or a push's constant
    force from its start (`PushForce.force`), plus the wall's
    −max(K_e d + B_e ḋ, 0) n while d = nᵀ(x − point) > 0, as `rhi.sim.Wall.force`.

    Args:
        t: time [s].
        sd: MuJoCo's sensordata.
        idx: (3 m,) int64: the handle position's and velocity's sensordata indices, then the task rows
            of the applied force.
        c: one hand's constants (a block of `hand_constants`).
        F: (m,) in: the previous hand force [N]; out: the hand force F_h [N].
        xfrc: (6,) the handle body's applied force and torque: the total force written on the task rows [N].
        acc: (3,) work so far [J], timestep [s], whether to add the previous step's work.

    Returns:
        |F_total|² [N²] (not finite: a non-finite force, written to xfrc all the same).
    """
    k, m = int(c[0]), int(c[1])
    if acc[2] != 0.0:
        wd = 0.0
        for j in range(m):
            wd += F[j] * sd[idx[m + j]]
        acc[0] += wd * acc[1]
    start, speed, K, B, fmax = c[2], c[3], c[4], c[5], c[6]
    o = 7 + 2 * m + 3  # the path's arc lengths, the stroke's depth or the push's force
    if k == -1:  # `PushForce.force`: its force from its start, else zero
        for j in range(m):
            F[j] = c[o + j] if t >= start else 0.0
    elif k == 0:  # `MinimumJerkPalpation.force`: s(τ) = 10τ³ − 15τ⁴ + 6τ⁵, τ = t / duration (speed holds the duration)
        depth = c[o]
        tau = min(max(t / speed, 0.0), 1.0)
        t2, w = tau * tau, 1.0 - tau
        sj = t2 * tau * (10.0 - 15.0 * tau + 6.0 * t2)
        ds = 30.0 * t2 * (w * w) / speed
        for j in range(m):
            u = c[o + 1 + m + j]
            F[j] = K * ((c[o + 1 + j] + depth * sj * u) - sd[idx[j]]) + B * (depth * ds * u - sd[idx[m + j]])
    else:
        s, P, U = c[o:o + k], c[o + k:o + k + k * m], c[o + k + k * m:]
        i, dd, moving = 0, 0.0, False
        if k > 1 and t > start:
            d = (t - start) * speed
            if d >= s[k - 1]:
                i = k - 1
            else:
                i = np.searchsorted(s, d, side="right") - 1  # the segment holding d (zero-length ones skipped)
                dd, moving = d - s[i], True
        for j in range(m):
            u = U[i * m + j] if moving else 0.0
            v = speed * u if moving else 0.0
            F[j] = K * ((P[i * m + j] + dd * u) - sd[idx[j]]) + B * (v - sd[idx[m + j]])
    if fmax < np.inf:
        ss = 0.0
        for j in range(m):
            ss += F[j] * F[j]
        nf = math.hypot(F[0], F[1]) if m == 2 and k > 0 else math.sqrt(ss)  # as Hand.force / the stroke's
        if nf > fmax:
            r = fmax / nf
            for j in range(m):
                F[j] = F[j] * r
    push = 0.0
    if c[7] != 0.0:
        x, v = np.empty(m), np.empty(m)
        for j in range(m):
            x[j], v[j] = sd[idx[j]], sd[idx[m + j]]
        push = _wall_push(x, v, c, 8)
    n2 = 0.0
    for j in range(m):
        f = F[j] - push * c[8 + m + j] if push != 0.0 else F[j]
        xfrc[idx[2 * m + j]] = f
        n2 += f * f
    return n2


@jit
def hand_period(model, data, sub, t0, sd, idx, c, F, xfrc, acc, wn, bad, at):
    """A control period of `sub` physics steps: `hand_step`, then mj_step2 + mj_step1, then the divergence check.

    The loop of `rhi.sim.loop.Session._steps` for a `hand_supported` hand and a physical `Wall` (or none), with
    MuJoCo's step called from here (`rhi.sim.mjc`); ends with the last step's work added to acc[0].

    Args:
        model: the mjModel's address (``MjModel._address``).
        data: the mjData's address (``MjData._address``).
        sub: physics steps per control period.
        t0: time of the period's first step [s].
        sd: MuJoCo's sensordata.
        idx: `hand_step`'s indices.
        c: `hand_constants` (each step with the block of the hand of its time).
        F: (m,) in: the previous hand force [N]; out: the period's last hand force F_h [N].
        xfrc: (6,) the handle body's applied force and torque.
        acc: (3,) work so far [J], timestep [s], 0 (the first step adds no previous work); advanced.
        wn: MuJoCo's warning counters (``MjData.warning.number``).
        bad: (3,) int64: the warnings that mean divergence (bad qacc, qvel, qpos).
        at: (1,) int64, written: the step that failed, when one did.

    Returns:
        PERIOD_OK, PERIOD_NONFINITE (a non-finite force, written to xfrc and not stepped) or
        PERIOD_UNSTABLE (MuJoCo flagged the step as diverged and reset its data).
    """
    m, P = F.shape[0], int(c[0])
    for s in range(sub):
        t, b = t0 + s * acc[1], 0
        while b < P - 1 and t >= c[1 + b]:  # the block of the hand of time t
            b += 1
        n2 = hand_step(t, sd, idx, c[int(c[P + b]):], F, xfrc, acc)  # adds the previous step's work (acc[2] = 1)
        if not math.isfinite(n2):
            at[0] = s
            return PERIOD_NONFINITE
        acc[2] = 1.0
        step2(model, data)
        step1(model, data)
        if wn[bad[0]] != 0 or wn[bad[1]] != 0 or wn[bad[2]] != 0:
            at[0] = s
            return PERIOD_UNSTABLE
    wd = 0.0
    for j in range(m):  # the last step's work, at the velocity after it
        wd += F[j] * sd[idx[m + j]]
    acc[0] += wd * acc[1]
    return PERIOD_OK
