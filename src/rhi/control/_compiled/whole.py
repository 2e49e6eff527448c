"""A whole controller tick in one compiled call: device terms, primary law, steps 2–6 and the passivity layer.

The kernel of `whole_for` (one per set of `Parts` a controller has) runs, without returning to Python,
what a `NullSpaceController` tick otherwise composes from four calls:
`rhi.devices._compiled.chain.chain_terms` (every device term at (q, q̇), passed by address: `terms_ref`),
the primary law's (F_render, F_extra) for the built-in laws (`ForceRendering`,
`SpringPalpation`, `ImpedanceControl` without a desired inertia: eqs. 5.6, 6.21, 7.2, 7.20),
`rhi.control._compiled.step.tick` and `rhi.control._compiled.passivity.apply`, with the static FME-matching
objectives and joint-limit barriers of `rhi.control._compiled.objectives`. The laws'
Python `forces` and the controller's composition are the references it is tested against
(`tests/test_whole_tick.py`). The law's settings travel in one float vector (`LAW_*`
indices), the passivity layer's settings and state in another (`PC_*`).

Where steps 2–6 cannot decide accurately (`FALLBACK`: a held set of fewer than n − m joints whose
projector block is ill-conditioned) the controller finishes the tick in the reference.
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import numpy as np
from numba import typeof, types
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from rhi.control._compiled import passivity
from rhi.control._compiled.objectives import objectives
from rhi.control._compiled.step import FALLBACK, OK, SINGULAR, tick
from rhi.devices._compiled.chain import chain_terms
from rhi.devices._compiled.terms import assign, dot
from rhi.jit import KernelRef, compile_aside, jit, stack_empty

__all__ = ["FALLBACK", "OK", "SINGULAR", "Parts", "compile_ahead", "terms_ref", "whole_for"]

#: Primary laws the whole tick computes (code in law[LAW_KIND]).
FORCE, SPRING, FREE = 1, 2, 3
#: Scalar slots of the law vector; then B^d (m × m), X₀ (m), normal (m), viscous (n), Coulomb (n).
LAW_KIND, LAW_GAIN, LAW_CORIOLIS, LAW_GRAVITY, LAW_STIFFNESS, LAW_NORMAL, LAW_FRICTION, LAW_VS = range(8)
N_LAW = 8
#: Slots of the passivity vector: settings (on, motor port, mode of `passivity.apply`, α bound), then state (E_obs, a
#: previous tick, its time, α, λ and the energy the damping took out this tick).
PC_ON, PC_MOTORS, PC_CONTROL, PC_ALPHA_MAX, PC_E, PC_PREV, PC_T, PC_ALPHA, PC_SCALE, PC_DISSIPATED = range(10)
N_PC = 10
#: Slots of the result vector: α, β, V, Ω, clipped, the passivity layer ran, the FME transition state tr changed,
#: the tick ran to its end (0 where it raised: a caller through `rhi.jit.KernelRef` sees no exception).
R_ALPHA, R_BETA, R_V, R_OMEGA, R_CLIPPED, R_PC, R_TR, R_DONE = range(8)
N_RES = 8


@jit(inline=True)
def _law(law, n, m, x, xdot, dq, force, Cx, Gx, g, Jsharp, F_r, F_x):
    """The built-in primary laws: F_r (rendered, α-scaled) and F_x (never scaled), written [N].

    Scalar loops into F_r and F_x: no temporary vectors (each an allocation and reference counts).
    """
    kind = law[LAW_KIND]
    if kind == FORCE:
        gain = law[LAW_GAIN]
        for i in range(m):
            F_r[i] = force[i] if gain == 1.0 else gain * force[i]
    elif kind == SPRING:
        o = N_LAW + m * m  # X₀, then the normal
        k = law[LAW_STIFFNESS]
        if law[LAW_NORMAL] != 0.0:
            depth = 0.0
            for i in range(m):
                depth += law[o + m + i] * (x[i] - law[o + i])
            depth = max(depth, 0.0)
            for i in range(m):
                F_r[i] = -k * depth * law[o + m + i]
        else:
            for i in range(m):
                F_r[i] = -k * (x[i] - law[o + i])
    else:
        for i in range(m):
            F_r[i] = 0.0
    # task_compensation: C_x ẋ + G_x + J#ᵀ F_q(q̇), then − B^d ẋ (rhi.control.primary)
    coriolis, friction = law[LAW_CORIOLIS] != 0.0, law[LAW_FRICTION] != 0.0
    gravity = law[LAW_GRAVITY] != 0.0 and dot(g, g) != 0.0
    o = N_LAW + m * m + 2 * m  # viscous, then Coulomb
    for i in range(m):
        c = 0.0
        if coriolis:
            for j in range(m):
                c += Cx[i, j] * xdot[j]
        if gravity:
            c = c + Gx[i]
        if friction:
            f = 0.0
            for a in range(n):
                f += Jsharp[a, i] * (law[o + a] * dq[a] + law[o + n + a] * math.tanh(dq[a] / law[LAW_VS]))
            c = c + f
        bx = 0.0
        for j in range(m):
            bx += law[N_LAW + i * m + j] * xdot[j]
        F_x[i] = c - bx


class Parts(NamedTuple):
    """The parts a whole tick has (`whole_for`): `rhi.control._compiled.step.flags` and two of its own.

    Attributes:
        code: the allocation (`rhi.control._compiled.step` NONE, SCALING, ASCM, ACTIVE_SET).
        scheduled: an FME schedule.
        vme: VME-matching objectives.
        safe: the held joints' safety torque is kept.
        clipped_null: null_space="clipped".
        tank: the null-space energy tank.
        objectives: static FME-matching objectives, joint-limit barriers or Jacobian objectives
            (`rhi.control._compiled.objectives`).
        passivity: the passivity layer.
    """

    code: int
    scheduled: bool
    vme: bool
    safe: bool
    clipped_null: bool
    tank: bool
    objectives: bool
    passivity: bool


def _borrow(context, builder, ty, value):
    """`value` of Numba type `ty` with every array in it (a tuple's, recursively) given no owner; other items increfed."""
    if isinstance(ty, types.Array):
        src = make_array(ty)(context, builder, value)
        dst = make_array(ty)(context, builder)
        populate_array(dst, data=src.data, shape=src.shape, strides=src.strides, itemsize=src.itemsize, meminfo=None)
        return dst._getvalue()
    if isinstance(ty, types.BaseTuple):
        parts = ty.types  # type: ignore[attr-defined]
        items = [_borrow(context, builder, t, builder.extract_value(value, i)) for i, t in enumerate(parts)]
        return context.make_tuple(builder, ty, items)
    context.nrt.incref(builder, ty, value)  # the result is a new reference: its items that are not arrays too
    return value


@intrinsic
def _borrowed(typingctx, arr):
    """The array `arr` with no owner (meminfo NULL): every reference count of it and of its views is a null check.

    Numba counts references to an array's owner with an atomic operation per count, and a tick's code counts hundreds
    (every argument on entry and exit, every view, every call's arguments): most of its time. The kernel's
    arguments outlive its call, so within it they need no counting. Only for arrays that outlive every use. A tuple
    (e.g. of arrays) gives the tuple of its items so borrowed.
    """
    if not isinstance(arr, (types.Array, types.BaseTuple)):
        return None

    def codegen(context, builder, sig, args):
        return _borrow(context, builder, sig.args[0], args[0])

    return arr(arr), codegen


B: Any = _borrowed  # as the kernels call it (Numba's intrinsic takes the typing context first)


@functools.cache
def whole_for(parts: Parts):
    """The whole tick compiled for one set of `parts`: Numba types and compiles only the branches they use.

    A cold start compiles only what one controller runs (e.g. ASCM without the active set, the tank and the
    passivity layer); each set is compiled once and cached on disk under a name of its own (the flags are
    constants of the closure, part of Numba's cache key). The settings must agree with `parts`; the status is that of
    `rhi.control._compiled.step.tick` (OK, FALLBACK, SINGULAR).

    Args:
        parts: the parts the kernel has.

    Returns:
        The kernel ``kernel(t, q, dq, force, ints, joints, consts, A, b, rows, armature, supports, identity, terms,
        ascm_at, ready, at, law, lo, hi, prm, tr, sch, vme_D, vme_gain, obj, pc, pc_pos, pc_eff, tank, tank_q, tank_e, x, buf,
        F_r, F_x, tau_out, sat, res) -> status``, its arguments:

            t: time [s].
            q: (n,) joint positions [rad].
            dq: (n,) joint velocities [rad/s].
            force: (m,) ``sensors["force"]`` [N] (read by `ForceRendering`).
            ints: the device's chain constants (`rhi.devices.batch.pack`).
            joints: its per-joint constants.
            consts: its frame and gravity constants.
            A: (nθ, n) actuation map.
            b: (nθ,) its offset.
            rows: (m,) int64 task rows.
            armature: (n,) rotor inertia [kg m²].
            supports: (nθ, nθ) bool, chain joint k supports joint j.
            identity: A is the identity.
            terms: `rhi.devices._compiled.chain.chain_terms` by address (`terms_ref`): the tick's code does not contain
                it, so its compile neither repeats nor waits for the one of the first `Device.terms`.
            ascm_at: `rhi.control._compiled.allocation.ascm_into` by address (`rhi.control._compiled.step.ascm_ref`):
                the controller compiles it while a child compiles the tick (`compile_ahead`).
            ready: x and buf already hold this state's terms (a `Device.terms` snapshot): not recomputed.
            at: (≥ 13,) int64 term offsets in buf (`rhi.devices.terms.layout`).
            law: the primary law's code and settings (LAW_* slots).
            lo: (n,) lower torque limits [N m].
            hi: (n,) upper torque limits [N m].
            prm: parameters of `rhi.control._compiled.step.tick` (P_* slots).
            tr: (4,) FME transition state, advanced in place.
            sch: the FME schedule of `rhi.control._compiled.step.tick` (empty: none).
            vme_D: (k, m, m) desired VMEs of the VME-matching objectives.
            vme_gain: (k,) their gradient steps.
            obj: the static FME-matching objectives, joint-limit barriers and Jacobian objectives
                (`rhi.control._compiled.objectives.pack`).
            pc: (N_PC,) the passivity layer's settings and state, advanced in place.
            pc_pos: (k,) its port position at the previous tick, written.
            pc_eff: (k,) its port effort at the previous tick, written.
            tank: (N_TANK,) the null-space energy tank (`rhi.control._compiled.tank`), advanced in place.
            tank_q: (n,) its q of the previous tick, written.
            tank_e: (2, n) its metered torques (objectives, allocation) of the previous tick, written.
            x: (m,) handle position [m], written unless ready.
            buf: the device terms (`rhi.devices.terms.layout`), written unless ready.
            F_r: (m,) the law's rendered force, written [N].
            F_x: (m,) the law's extra force, written [N].
            tau_out: (n,) the torque to send, written [N m].
            sat: (n,) bool, the held joints, written.
            res: (N_RES,) α, β, V, Ω, clipped, whether the passivity layer ran, whether tr changed, 1 (the tick
                ran to its end) (R_* slots), written.
    """
    code, scheduled, vme, safe, clipped_null, tank_on, objectives_on, passivity_on = (
        int(parts[0]), *(bool(p) for p in parts[1:]))

    def whole_parts(t, q, dq, force, ints, joints, consts, A, b, rows, armature, supports, identity, terms, ascm_at,
                    ready, at, law, lo, hi, prm, tr, sch, vme_D, vme_gain, obj, pc, pc_pos, pc_eff, tank, tank_q,
                    tank_e, x, buf, F_r, F_x, tau_out, sat, res):
        res[R_DONE] = 0.0
        # the arguments outlive the call: no reference counting of them (or their views) within it
        status = _whole(t, B(q), B(dq), B(force), (B(ints), B(joints), B(consts), B(A), B(b), B(rows), B(armature),
                                                   B(supports), identity, terms, ascm_at), ready,
                        B(at), B(law), B(lo), B(hi), B(prm), B(tr), B(sch), B(vme_D), B(vme_gain), B(obj),
                        (B(pc), B(pc_pos), B(pc_eff)), (B(tank), B(tank_q), B(tank_e)),
                        (B(x), B(buf), B(F_r), B(F_x), B(tau_out), B(sat), B(res)), code, scheduled, vme, safe,
                        clipped_null, tank_on, objectives_on, passivity_on)
        res[R_DONE] = 1.0
        return status

    # One name per set: Numba names a kernel's symbols after its qualified name, its argument types and a counter
    # of the process that compiled it, so two sets compiled by two processes (test workers, `rhi reproduce`'s)
    # could share every symbol name once both are loaded from the cache, and an address looked up by name
    # (`rhi.jit.KernelRef`, Numba's own entry points) would be the other set's code.
    whole_parts.__qualname__ += "_" + "_".join(str(int(p)) for p in parts)
    return jit(whole_parts)


def terms_ref(chain: tuple, x: np.ndarray, buf: np.ndarray) -> KernelRef:
    """`chain_terms` as the whole tick calls it (its ``terms`` argument), for a device's constants and outputs.

    Compiled (or loaded) at the first tick, not here: a whole tick can be typed and compiled (e.g. aside, in a
    child) meanwhile. Its types are those of the device's own `Device.terms` call: one compile serves both.

    Args:
        chain: the device's chain constants (ints, joints, consts, A, b, rows, armature, supports, identity).
        x: (m,) the whole tick's x.
        buf: its terms buffer.
    """
    ints, joints, consts, A, _, rows, armature, supports, identity = chain
    vec = types.float64[::1]  # θ (on the tick's stack) and q̇ (the tick's argument)
    return _terms_ref(tuple(typeof(a) for a in (ints, joints, consts)) + (vec,)
                      + tuple(typeof(a) for a in (A, rows, armature, supports, identity)) + (vec, typeof(x), typeof(buf)))


@functools.cache
def _terms_ref(args: tuple) -> KernelRef:
    return KernelRef(chain_terms, args, types.none)


_AHEAD: set[Parts] = set()  # the parts `compile_ahead` was asked for in this process


def compile_ahead(parts: Parts, args: tuple) -> None:
    """On a cold cache, compile `whole_for` (`parts`) for the types of `args` in a child process (`rhi.jit.compile_aside`).

    A controller calls it when it is made, so that its first tick's compile runs beside whatever this process
    compiles meanwhile (e.g. the first `Device.terms`: the child waits for the `chain_terms` it compiles, then loads it).

    Asked once per process and set of parts (a later controller of the same parts on another device compiles its
    own types at its first tick, as without this).

    Args:
        parts: the parts of the kernel.
        args: the kernel's arguments, as its first call will pass them (their Numba types are compiled for).
    """
    if parts in _AHEAD:
        return
    _AHEAD.add(parts)
    compile_aside(whole_for(parts), "rhi.control._compiled.whole:whole_for", (parts,), tuple(typeof(a) for a in args))


@jit(inline=True)
def _whole(t, q, dq, force, chain, ready, at, law, lo, hi, prm, tr, sch, vme_D, vme_gain, obj, pcs, tanks, outs,
           code, scheduled, vme, safe, clipped_null, tank_on, objectives_on, passivity_on):
    """The whole tick's body (inlined), with the `Parts` it has as its last eight arguments (constants: pruned).

    `chain` is (ints, ..., identity, terms, ascm_at), `pcs` (pc, pc_pos, pc_eff), `tanks` (tank, tank_q, tank_e) and `outs`
    (x, ..., res) of `whole_for`'s kernel's arguments (tuples: a call of more than 30 arguments is one Numba cannot inline).
    """
    ints, joints, consts, A, b, rows, armature, supports, identity, terms, ascm_at = chain
    pc, pc_pos, pc_eff = pcs
    tank, tank_q, tank_e = tanks
    x, buf, F_r, F_x, tau_out, sat, res = outs
    n, m = q.shape[0], rows.shape[0]
    if not ready:
        th = stack_empty(A.shape[0], np.float64)  # θ = A q + b
        for i in range(A.shape[0]):
            s = 0.0
            for j in range(n):
                s += A[i, j] * q[j]
            th[i] = s + b[i]
        terms(ints, joints, consts, th, A, rows, armature, supports, identity, dq, x, buf)
    J = buf[at[0]:at[0] + m * n].reshape((m, n))
    M = buf[at[2]:at[2] + n * n].reshape((n, n))
    g = buf[at[3]:at[3] + n]
    Minv = buf[at[4]:at[4] + n * n].reshape((n, n))
    JMinv = buf[at[5]:at[5] + m * n].reshape((m, n))
    Lam = buf[at[6]:at[6] + m * m].reshape((m, m))
    Jsharp = buf[at[7]:at[7] + n * m].reshape((n, m))
    Gx = buf[at[8]:at[8] + m]
    xdot = buf[at[9]:at[9] + m]
    Cx = buf[at[12]:at[12] + m * m].reshape((m, m))
    _law(law, n, m, x, xdot, dq, force, Cx, Gx, g, Jsharp, F_r, F_x)
    tau_s, tau_to = stack_empty(n, np.float64), stack_empty(n, np.float64)
    tau_s[:], tau_to[:] = 0.0, 0.0
    if objectives_on:
        objectives(obj, q, dq, J, buf[at[1]:at[1] + m * n * n].reshape((m, n, n)), tau_s, tau_to)
    tr0, tr1, tr2, tr3 = tr[0], tr[1], tr[2], tr[3]
    status, alpha, beta, V, omega, clipped = tick(t, buf, at, F_r, F_x, q, dq, lo, hi, prm, tr, sch, vme_D, vme_gain,
                                                  tau_s, tau_to, tank, tank_q, tank_e, tau_out, sat, ascm_at, code,
                                                  scheduled, vme, safe, clipped_null, tank_on)
    res[R_ALPHA], res[R_BETA], res[R_V], res[R_OMEGA], res[R_CLIPPED] = alpha, beta, V, omega, 1.0 if clipped else 0.0
    res[R_PC] = 0.0
    res[R_TR] = 0.0 if tr[0] == tr0 and tr[1] == tr1 and tr[2] == tr2 and tr[3] == tr3 else 1.0
    if not passivity_on:
        return status
    if status != OK or pc[PC_ON] == 0.0 or not math.isfinite(dot(tau_out, tau_out)):
        return status
    motors = pc[PC_MOTORS] != 0.0
    Mi = stack_empty((m, m), np.float64)  # the handle port's J M⁻¹ Jᵀ (`mm`'s arithmetic, on the stack)
    if motors:
        pos, v, Mp, Mi = q, dq, M, Minv
    else:
        Mi[:, :] = 0.0
        for i in range(m):
            for k in range(n):
                a = JMinv[i, k]
                for j in range(m):
                    Mi[i, j] += a * J[j, k]
        pos, v, Mp = x, xdot, Lam
    tau0 = stack_empty(n, np.float64)
    assign(tau0, tau_out)
    prev = pc[PC_PREV] != 0.0
    E, a_pc, scale, dissipated = passivity.apply(
        pc[PC_E], prev, pc_pos if prev else pos, pc_eff if prev else pos, t - pc[PC_T], pos, v, Mp, Mi, J, Jsharp,
        tau0, lo, hi, motors, int(pc[PC_CONTROL]), pc[PC_ALPHA_MAX], tau_out, pc_eff)  # eff_prev read before written
    pc[PC_E], pc[PC_ALPHA], pc[PC_SCALE], pc[PC_DISSIPATED] = E, a_pc, scale, dissipated
    pc[PC_PREV], pc[PC_T] = 1.0, t
    assign(pc_pos, pos)
    res[R_PC] = 1.0
    return status
