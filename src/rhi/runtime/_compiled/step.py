"""The step of one `rhi.runtime.run` tick in one compiled call (`rhi.runtime.step.FastStep`).

Between a reading and its command: the handle's kinematics and virtual force
(`rhi.sim._compiled.handle.handle_state`), the safety layer's checks (`rhi.runtime.safety.Safety.check`),
the controller's whole tick (its kernel of `rhi.control._compiled.whole.whole_for`, by the address of a
`rhi.jit.KernelRef`)
and the safety filter's box (`Safety.filter`). It decides only the ticks on which the safety layer does
nothing: where a rule would trip, the controller's kernel does not decide, or the torque needs clamping,
it returns the last stage it finished (`NONE`, `CHECKED`, `STEPPED`) with the state of the stages after
it untouched, and the caller runs the rest in Python, the reference.
"""

from __future__ import annotations

import math

from rhi.control._compiled import whole as _whole
from rhi.jit import jit
from rhi.sim._compiled.handle import handle_state

#: How far `step` went: nothing (the safety state untouched), the reading checked (the safety state
#: advanced), the controller's tick too (its state advanced), the whole step (τ inside the filter's box).
NONE, CHECKED, STEPPED, DONE = 0, 1, 2, 3
#: The whole tick's status where it decided (`rhi.control.tick.KernelTick.settle`).
OK = _whole.OK
#: Slots of the vector `sv`, the safety state (`Safety`'s per-tick attributes) then the limits and the output: the
#: last sequence number, the ticks it repeated, the newest arrival [s], the last device time [s], the frozen rule's
#: repeats of the joints and their start [s], the F/T repeats; whether each of _last_seq, _last_new, _last_t,
#: _joints, _ft, _ft_q0 is set; then the last joints (q then q̇, 2 n), the last F/T (6) and the positions at its
#: last change (n); from `limits(n)` on the limits, from `output(n)` on the filter's largest τ_i / limit_i.
S_SEQ, S_SAME, S_NEW, S_T, S_JSAME, S_JT0, S_FTSAME, S_HSEQ, S_HNEW, S_HT, S_HJ, S_HFT, S_HFTQ0 = range(13)
N_S = 13
#: Slots of the limits (from `limits(n)` in sv): `SafetyConfig`'s stale_ticks, frozen_ticks, frozen_motion, silence,
#: max_age, max_handle_speed, `rhi.runtime.safety.FT_EXEMPT` and the bad status bits; then q_lo, q_hi, max |q̇|,
#: torque min and max ((n,) each).
L_STALE, L_FROZEN, L_MOTION, L_SILENCE, L_AGE, L_SPEED, L_EXEMPT, L_BAD = range(8)
N_L = 8


@jit
def limits(n):
    """Where the limits start in sv, for n motors."""
    return N_S + 3 * n + 6


@jit
def output(n):
    """Where the output starts in sv (its length: `output(n) + 1`), for n motors."""
    return limits(n) + N_L + 5 * n


#: A handle speed within this relative distance of its limit is left to the reference (`math.hypot`'s rounding).
SPEED_MARGIN = 1e-12


@jit
def step(t, seq, status, age, arrival, now, v, ft_at, sv, kin, kout, fused, wargs, whole):
    """One tick's step; returns `NONE`, `CHECKED`, `STEPPED` or `DONE` (module docstring).

    The controller's arrays are left as the kernel left them where it returns `CHECKED` after the whole
    tick did not decide: the caller reloads them from the controller's state (as `KernelTick.settle` does).

    Args:
        t: the reading's device time [s].
        seq: its sequence number.
        status: its status flags.
        age: its round-trip age [s] (NaN: not measured).
        arrival: its arrival [s] (NaN: a local link's).
        now: the host's time of the check [s] (NaN: no silence check).
        v: (2 n + k,) the reading's one float array: q [rad], q̇ [rad/s], then every sensor.
        ft_at: where the F/T reading (6) starts in v (-1: none).
        sv: the safety state (S_* slots, advanced where the reading passes), the limits (L_* slots from
            `limits(n)`) and the output (from `output(n)`: the filter's largest τ_i / limit_i where `DONE`).
        kin: `handle_state`'s (ints, joints, fc).
        kout: (4, m) x, ẋ, the virtual force (zero unless `fused`: the virtual environment is in fc) and the
            force the controller reads [N].
        fused: the virtual environment is in fc.
        wargs: the whole tick's arguments after (t, q, dq, force), ending in (…, τ, held, result).
        whole: the whole tick (a `rhi.jit.KernelRef`: a pointer to its kernel).
    """
    tau, res = wargs[-3], wargs[-1]
    n = tau.shape[0]
    q, dq = v[:n], v[n:2 * n]
    lim = sv[limits(n):]
    if status & int(lim[L_BAD]) != 0 or not math.isfinite(t):
        return NONE
    for x in v:
        if not math.isfinite(x):
            return NONE
    # the safety layer's per-tick state, advanced in locals and kept only where no rule trips
    same, last_new, last_t = sv[S_SAME], sv[S_NEW], sv[S_T]
    has_new, has_t = sv[S_HNEW] != 0.0, sv[S_HT] != 0.0
    has_now = not math.isnan(now)
    new = sv[S_HSEQ] == 0.0 or seq > sv[S_SEQ]
    jsame, jt0, ftsame = sv[S_JSAME], sv[S_JT0], sv[S_FTSAME]
    jmoved = ftmoved = False
    if new:
        has_arr = not math.isnan(arrival)
        if has_now and has_arr and has_new and arrival - last_new > lim[L_SILENCE]:
            return NONE
        if has_t and not t > last_t:
            return NONE
        same = 0.0
        if has_arr or has_now:
            last_new, has_new = arrival if has_arr else now, True
        else:
            has_new = False
        last_t, has_t = t, True
        o = N_S
        jmoved = sv[S_HJ] == 0.0
        for i in range(n):
            if q[i] != sv[o + i] or dq[i] != sv[o + n + i]:
                jmoved = True
        if jmoved:
            jsame, jt0 = 0.0, t
        else:
            jsame += 1.0
        o = N_S + 2 * n
        ftmoved = sv[S_HFT] != (1.0 if ft_at >= 0 else 0.0)
        if ft_at >= 0 and not ftmoved:
            for i in range(6):
                if v[ft_at + i] != sv[o + i]:
                    ftmoved = True
        ftsame = 0.0 if ftmoved else ftsame + 1.0
        if jsame >= lim[L_FROZEN]:
            top = 0.0
            for i in range(n):
                top = max(top, abs(dq[i]))
            if top * (t - jt0) > lim[L_MOTION]:
                return NONE
        if ftsame >= lim[L_FROZEN] and ft_at >= 0:  # (the F/T unchanged: its positions are those in sv)
            moved = sv[S_HFTQ0] == 0.0
            for i in range(n):
                if q[i] != sv[N_S + 2 * n + 6 + i]:
                    moved = True
            top = 0.0
            for i in range(6):
                top = max(top, abs(v[ft_at + i]))
            if moved and top >= lim[L_EXEMPT]:
                return NONE
    elif seq < sv[S_SEQ]:
        return NONE
    else:
        same += 1.0
        if same >= lim[L_STALE]:
            return NONE
    if has_now and has_new and now - last_new > lim[L_SILENCE]:
        return NONE
    if age > lim[L_AGE]:
        return NONE
    o = N_L
    ss = 0.0
    for i in range(n):
        x, w, vmax = q[i], dq[i], lim[o + 2 * n + i]
        if not (lim[o + i] <= x <= lim[o + n + i] and -vmax <= w <= vmax):
            return NONE
        ss += x * x + w * w
    if not ss < 1e300:  # `run` renders the handle where q·q + q̇·q̇ is finite: far from an overflow only
        return NONE
    m = kout.shape[1]
    if fused:
        handle_state(kin[0], kin[1], kin[2], q, dq, kout[:3])
    else:
        handle_state(kin[0], kin[1], kin[2], q, dq, kout[:2])
        kout[2, :] = 0.0
    speed = 0.0
    for i in range(m):
        speed += kout[1, i] * kout[1, i]
    if not math.sqrt(speed) * (1.0 + SPEED_MARGIN) <= lim[L_SPEED]:
        return NONE
    # the reading passed every check: the safety state advances
    sv[S_SAME], sv[S_NEW], sv[S_T] = same, last_new, last_t
    sv[S_HNEW], sv[S_HT] = 1.0 if has_new else 0.0, 1.0 if has_t else 0.0
    if new:
        sv[S_SEQ], sv[S_HSEQ] = seq, 1.0
        sv[S_JSAME], sv[S_JT0], sv[S_FTSAME] = jsame, jt0, ftsame
        if jmoved:
            sv[S_HJ] = 1.0
            for i in range(n):
                sv[N_S + i], sv[N_S + n + i] = q[i], dq[i]
        if ftmoved:
            sv[S_HFT], sv[S_HFTQ0] = 1.0 if ft_at >= 0 else 0.0, 1.0
            for i in range(6 if ft_at >= 0 else 0):
                sv[N_S + 2 * n + i] = v[ft_at + i]
            for i in range(n):
                sv[N_S + 2 * n + 6 + i] = q[i]
    # the controller's whole tick on a finite force
    F = kout[3]
    for i in range(m):
        F[i] = kout[2, i]
        if not math.isfinite(F[i]):
            return CHECKED
    if whole(t, q, dq, F, *wargs) != _whole.OK or res[_whole.R_DONE] == 0.0:
        return CHECKED
    for i in range(n):
        if not math.isfinite(tau[i]):
            return CHECKED
    # the filter: τ inside the box, its largest τ_i / limit_i
    o = N_L + 3 * n
    top = 0.0
    for i in range(n):
        x, lo, hi = tau[i], lim[o + i], lim[o + n + i]
        if not lo <= x <= hi:
            return STEPPED
        r = x / hi if x > 0.0 else x / lo
        if r > top:
            top = r
    sv[output(n)] = top
    return DONE
