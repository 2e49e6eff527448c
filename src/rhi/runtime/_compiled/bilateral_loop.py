"""Many ticks of `rhi.runtime.bilateral.simulate_bilateral` in one compiled call, for the runs it computes exactly.

`BilateralLoop.build` accepts a run of the plain `Master` and `Slave` whose parts the kernels know: a
`NullSpaceController` whose whole tick runs compiled (`KernelTick.whole_ok`) reading no sensors but the force and
the F/T sensor, a hand that `rhi.sim._compiled.handle.hand_supported` accepts, a tissue `Wall`, two task
dimensions of the master and the slave and slave chains the compiled kinematics handle. `ticks` then runs a
block of ticks per call, each as the Python loop: the master's sensors, terms (`chain_terms`), booking and the
TDPA's `damp`, its packet, the controller's whole tick (the controller's own kernel through a
`rhi.jit.KernelRef`), the slave's sensors, terms, the TDPA's `correct`, its packet and PD torque, then a control
period of each plant (`hand_period` for the master, `_tissue_period` for the slave with the tissue's work
metered as `rhi.runtime.bilateral._Metered`) and the log row. The channel is the run's schedule
(`rhi.runtime.channel.schedule`): which packet each side sees at each tick, from the seed, up front.

A tick the kernels do not decide (a non-finite input, torque or force, the whole tick's FALLBACK or SINGULAR, a
stopped controller) ends the call *before* that tick with every state as it was; the caller runs it in Python on
the same state and channel and resumes. A plant fault ends it *after* the tick's row, as the Python loop does.
Imported by `rhi.runtime.bilateral`, not with ``import rhi`` (Numba).
"""

from __future__ import annotations

import math

import numpy as np

from rhi.control._compiled import whole as _whole
from rhi.devices._compiled.chain import chain_terms
from rhi.devices._compiled.terms import dot, finite
from rhi.jit import jit
from rhi.runtime._compiled.tdpa import P_GAIN, P_IN, P_OUT, book, correct, damp
from rhi.sim._compiled.handle import PERIOD_NONFINITE, PERIOD_OK, PERIOD_UNSTABLE, hand_period
from rhi.sim._compiled.io import sensors
from rhi.sim.mjc import step1, step2

#: How a call of `ticks` ended: every tick ran; the next tick is the Python loop's; the master's or the slave's
#: plant faulted at the last tick (its period's status in lay[L_STATUS], the failed step in lay[L_STEP]).
DONE, PYTHON, FAULT_M, FAULT_S = 0, 1, 2, 3
#: Slots of the float state `st`: both sessions' time [s], the hand's work [J], the tissue's metered work [J], the
#: flags (metered force held, master force held, x_s0 and x_m0 known, controller stopped), the controller's logged
#: values as `rhi.sim._compiled.fast_loop` keeps them; then each port's energies (`P_*`) at PM and PS.
(S_TM, S_TS, S_WORK, S_WENV, S_MET, S_HELD, S_XS0, S_XM0, S_STOPPED, S_V, S_OMEGA, S_ALPHA, S_BETA, S_CLIP, S_TLAST,
 S_TICKS, S_PC, S_DISS, S_EOBS, S_APC) = range(20)
PM, PS, N_ST = 20, 25, 30
#: Rows of the (N_V, m) vectors `vec`: the master's held position and force, the force sent to the renderer, the
#: force received, the slave's x_s0, set-point, x_m0, contact force, drift, the metered step's position and force,
#: the hand's force.
V_HX, V_HF, V_FORCE, V_RECV, V_XS0, V_XD, V_XM0, V_FE, V_DRIFT, V_MX, V_MF, V_FHAND = range(12)
N_V = 12
#: Slots of the int vector `lay`: ticks run, outcome, period status, failed step; whether the law reads the F/T.
L_DONE, L_OUT, L_STATUS, L_STEP, L_FT = range(5)
#: The log row's columns (`BilateralLog`'s, then q of both sides before the period, for the TMI) and their widths.
COLUMNS = (("t", 0), ("x_m", 1), ("x_s", 1), ("x_d", 1), ("drift", 1), ("F_m", 1), ("F_e", 1), ("F_hand", 1),
           ("W_hand", 0), ("W_env", 0), ("E_M_in", 0), ("E_M_out", 0), ("E_S_in", 0), ("E_S_out", 0), ("beta", 0),
           ("alpha", 0))



@jit
def _lambda_min(L, m):
    """The smallest eigenvalue of the symmetric (m, m) Λ stored row-major in L (m ≤ 2; its lower triangle)."""
    if m == 1:
        return L[0]
    h = 0.5 * (L[0] - L[3])
    return 0.5 * (L[0] + L[3]) - math.sqrt(h * h + L[2] * L[2])


@jit
def _terms(chain, q, dq, th, x, buf):
    """Every device term at (q, q̇) into x and buf (`Device.terms` by `chain_terms`, θ = A q + b)."""
    ints, joints, consts, A, b, rows, armature, supports, identity = chain
    for a in range(A.shape[0]):
        s = 0.0
        for k in range(q.shape[0]):
            s += q[k] * A[a, k]
        th[a] = s + b[a]
    chain_terms(ints, joints, consts, th, A, rows, armature, supports, identity, dq, x, buf)


@jit
def _tissue_period(model, data, sub, sd, idx, c, xfrc, st, vec, wn, bad, F, at):
    """The slave's control period with the tissue `Wall` (constants c), its work on the tip metered.

    Each physics step as `rhi.sim.loop.Session._steps` with `_Metered(Wall)`: the work up to the tip's position
    (the last step's force against the displacement since), then the wall's force at the step's x, ẋ written to
    the tip's applied force, then MuJoCo's step. Returns PERIOD_OK, PERIOD_NONFINITE or PERIOD_UNSTABLE (the
    step in at[0]).
    """
    m = F.shape[0]
    for s in range(sub):
        if st[S_MET] != 0.0:
            w = 0.0
            for i in range(m):
                w += vec[V_MF, i] * (sd[idx[i]] - vec[V_MX, i])
            st[S_WENV] = st[S_WENV] + w
        depth, rate = 0.0, 0.0
        for i in range(m):
            depth += (sd[idx[i]] - c[i]) * c[m + i]
        if depth > 0:
            for i in range(m):
                rate += sd[idx[m + i]] * c[m + i]
        push = max(c[2 * m] * depth + c[2 * m + 1] * rate, 0.0) if depth > 0 else 0.0
        for i in range(m):
            F[i] = -push * c[m + i]
            vec[V_MX, i], vec[V_MF, i] = sd[idx[i]], F[i]
        st[S_MET] = 1.0
        if not finite(F):
            at[0] = s
            return PERIOD_NONFINITE
        for i in range(m):
            xfrc[idx[2 * m + i]] = F[i]
        step2(model, data)
        step1(model, data)
        if wn[bad[0]] != 0 or wn[bad[1]] != 0 or wn[bad[2]] != 0:
            at[0] = s
            return PERIOD_UNSTABLE
    return PERIOD_OK


@jit
def _copy(dst, src):
    """Each of the controller's ten arrays in `dst` set to its twin in `src` (its state before a tick, or back)."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8, a9 = dst
    b0, b1, b2, b3, b4, b5, b6, b7, b8, b9 = src
    a0[:], a1[:], a2[:], a3[:], a4[:], a5[:], a6[:], a7[:], a8[:], a9[:] = b0, b1, b2, b3, b4, b5, b6, b7, b8, b9


@jit
def ticks(count, k0, dt, mst, slv, chan, cfg, wargs, cs, whole, st, vec, lay, rows):
    """Run up to `count` ticks of the bilateral loop from tick k0, one log row each (see the module docstring).

    Args:
        count: ticks to run at most (<= len(rows)).
        k0: the first tick's index.
        dt: control period [s].
        mst: the master's (mj, sub, `sensors`' arguments, `hand_period`'s (sd, idx, c, F, xfrc, acc, wn, bad,
            at), ctrl, chain constants, term offsets, x, buf).
        slv: the slave's (mj, sub, `sensors`' arguments, ctrl, xfrc, sd, (3 m,) int64 position, velocity and
            force indices, the wall's constants, wn, bad, chain constants, term offsets, x, buf, (m,) int64 F/T
            rows, torque limits lo, hi, (K_p, K_d)).
        chan: (forward packets (N, m + 1), backward packets (N, m + 1), the forward and backward schedules (N,)).
        cfg: the TDPA's settings (`settings`).
        wargs: the whole tick's arguments after (t, q, dq, force), ready = True.
        cs: the controller's arrays the whole tick advances (restored where a tick is Python's).
        whole: the controller's whole tick (a `rhi.jit.KernelRef`).
        st: (N_ST,) float state (S_* slots and the ports), advanced.
        vec: (N_V, m) the state's vectors (V_* rows), advanced.
        lay: (5,) int64 layout and outcome (L_* slots).
        rows: (>= count, width) the log rows to write (`COLUMNS`, then q_m, q_s).
    """
    mj_m, sub_m, sens_m, hand, ctrl_m, chain_m, at_m, x_m, buf_m = mst
    (mj_s, sub_s, sens_s, ctrl_s, xfrc_s, sd_s, idx_s, wall, wn_s, bad_s, chain_s, at_s, x_s, buf_s, ft_rows, lo, hi,
     gains) = slv
    fwd, bwd, vis_f, vis_b = chan
    sd, idx, c, Fh, xfrc, acc, wn, bad, at = hand
    tau, res = cs[4], cs[6]
    n, m, n_s = ctrl_m.shape[0], vec.shape[1], ctrl_s.shape[0]
    read_m, read_s = np.empty(2 * n + 6), np.empty(2 * n_s + 6)
    th_m, th_s = np.empty(chain_m[3].shape[0]), np.empty(chain_s[3].shape[0])
    F, x_nom, v_nom, v, Fpd, Ft = np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty(m), np.empty(m)
    tau_s, st0, vec0 = np.empty(n_s), st.copy(), vec.copy()
    saved = (cs[0].copy(), cs[1].copy(), cs[2].copy(), cs[3].copy(), cs[4].copy(), cs[5].copy(), cs[6].copy(),
             cs[7].copy(), cs[8].copy(), cs[9].copy())
    kp, kd = gains[0], gains[1]
    lay[L_DONE], lay[L_OUT], lay[L_STATUS] = 0, DONE, PERIOD_OK
    for j in range(count):
        k = k0 + j
        if st[S_STOPPED] != 0.0:
            lay[L_OUT] = PYTHON
            return
        st0[:], vec0[:, :] = st, vec
        _copy(saved, cs)
        t = st[S_TM]
        sensors(sens_m[0], sens_m[1], sens_m[2], sens_m[3], sens_m[4], sens_m[5], read_m)
        q, dq = read_m[:n], read_m[n:2 * n]
        if not (finite(q) and finite(dq)) or (lay[L_FT] != 0 and not finite(read_m[2 * n:])):
            lay[L_OUT] = PYTHON
            return
        # `Master.step`: book the last sample, damp the slave's force, send x_m and E_in, the controller's tick
        i = vis_b[k]
        for r in range(m):
            F[r] = 0.0 if i < 0 else bwd[i, r]
            vec[V_RECV, r] = F[r]
        E_other = 0.0 if i < 0 else bwd[i, m]
        _terms(chain_m, q, dq, th_m, x_m, buf_m)
        xdot = buf_m[at_m[9]:at_m[9] + m]
        if st[S_HELD] != 0.0:
            e = 0.0
            for r in range(m):
                e += vec[V_HF, r] * (x_m[r] - vec[V_HX, r])
            book(st[PM:PM + 5], e)
        if cfg[0] != 0.0:
            damp(st[PM:PM + 5], F, xdot, _lambda_min(buf_m[at_m[6]:at_m[6] + m * m], m), E_other, dt, cfg)
        for r in range(m):
            vec[V_FORCE, r] = F[r]
            fwd[k, r] = x_m[r]
        fwd[k, m] = st[PM + P_IN]
        status = whole(t, q, dq, F, *wargs) if finite(F) else _whole.FALLBACK
        if status != _whole.OK or res[_whole.R_DONE] == 0.0 or not finite(tau):
            st[:], vec[:, :] = st0, vec0
            _copy(cs, saved)
            lay[L_OUT] = PYTHON
            return
        st[S_ALPHA], st[S_BETA] = res[_whole.R_ALPHA], res[_whole.R_BETA]
        st[S_V], st[S_OMEGA] = res[_whole.R_V], res[_whole.R_OMEGA]
        st[S_CLIP], st[S_TLAST] = res[_whole.R_CLIPPED], t
        if res[_whole.R_PC] != 0.0:
            st[S_DISS] += cs[1][_whole.PC_DISSIPATED]
            st[S_EOBS], st[S_APC] = cs[1][_whole.PC_E], cs[1][_whole.PC_ALPHA]
            st[S_PC] += 1.0
        st[S_TICKS] += 1.0
        scale = res[_whole.R_ALPHA] if math.isfinite(res[_whole.R_ALPHA]) else 1.0
        for r in range(m):
            vec[V_HX, r], vec[V_HF, r] = x_m[r], F[r] * scale
        st[S_HELD] = 1.0
        # `Slave.step`: PD toward the master's delayed position, the TDPA's correction, send F_e and E_in
        sensors(sens_s[0], sens_s[1], sens_s[2], sens_s[3], sens_s[4], sens_s[5], read_s)
        qs, dqs = read_s[:n_s], read_s[n_s:2 * n_s]
        _terms(chain_s, qs, dqs, th_s, x_s, buf_s)
        if st[S_XS0] == 0.0:
            for r in range(m):
                vec[V_XS0, r], vec[V_XD, r] = x_s[r], x_s[r]
            st[S_XS0] = 1.0
        i = vis_f[k]
        if i >= 0 and st[S_XM0] == 0.0:
            for r in range(m):
                vec[V_XM0, r] = fwd[i, r]
            st[S_XM0] = 1.0
        for r in range(m):
            x_nom[r] = vec[V_XS0, r] if i < 0 else vec[V_XS0, r] + (fwd[i, r] - vec[V_XM0, r])
            v_nom[r] = (x_nom[r] + vec[V_DRIFT, r] - vec[V_XD, r]) / dt
            Ft[r] = read_s[2 * n_s + ft_rows[r]]
            vec[V_FE, r], v[r] = Ft[r], v_nom[r]
        if cfg[0] != 0.0:
            correct(st[PS:PS + 5], v, Ft, 0.0 if i < 0 else fwd[i, m], vec[V_DRIFT], dt, cfg)
        for r in range(m):
            vec[V_DRIFT, r] = vec[V_DRIFT, r] + (v[r] - v_nom[r]) * dt
        book(st[PS:PS + 5], -dot(Ft, v) * dt)
        sxdot = buf_s[at_s[9]:at_s[9] + m]
        for r in range(m):
            vec[V_XD, r] = x_nom[r] + vec[V_DRIFT, r]
            bwd[k, r] = Ft[r]
            Fpd[r] = kp * (vec[V_XD, r] - x_s[r]) + kd * (v[r] - sxdot[r])
        bwd[k, m] = st[PS + P_IN]
        J, g = buf_s[at_s[0]:at_s[0] + m * n_s], buf_s[at_s[3]:at_s[3] + n_s]
        for a in range(n_s):
            s = 0.0
            for r in range(m):
                s += J[r * n_s + a] * Fpd[r]
            tau_s[a] = s + g[a]
        if not finite(tau_s):  # `Plant.apply` refuses it: the Python loop's tick raises
            st[:], vec[:, :] = st0, vec0
            _copy(cs, saved)
            lay[L_OUT] = PYTHON
            return
        row = rows[j]
        o = 1 + 7 * m + 8
        for a in range(n):
            row[o + a] = q[a]
        for a in range(n_s):
            row[o + n + a] = qs[a]
        # the periods: the master with the hand, then (unless it faulted) the slave with the tissue
        ctrl_m[:] = tau
        xfrc[:] = 0.0
        acc[0], acc[2] = st[S_WORK], 0.0
        status = hand_period(mj_m[0], mj_m[1], sub_m, t, sd, idx, c, Fh, xfrc, acc, wn, bad, at)
        st[S_WORK] = acc[0]
        out = DONE
        if status == PERIOD_OK:
            for r in range(m):
                vec[V_FHAND, r] = Fh[r]
            st[S_TM] = t + dt
            for a in range(n_s):
                ctrl_s[a] = min(max(tau_s[a], lo[a]), hi[a])
            xfrc_s[:] = 0.0
            status = _tissue_period(mj_s[0], mj_s[1], sub_s, sd_s, idx_s, wall, xfrc_s, st, vec, wn_s, bad_s, Ft,
                                    lay[L_STEP:L_STEP + 1])
            if status == PERIOD_OK:
                st[S_TS] = st[S_TS] + dt
            else:
                out = FAULT_S
        else:
            out, lay[L_STEP] = FAULT_M, at[0]
        row[0] = t
        for r in range(m):
            row[1 + r], row[1 + m + r] = sd[idx[r]], sd_s[idx_s[r]]
            row[1 + 2 * m + r], row[1 + 3 * m + r] = vec[V_XD, r], vec[V_DRIFT, r]
            row[1 + 4 * m + r], row[1 + 5 * m + r], row[1 + 6 * m + r] = vec[V_FORCE, r], vec[V_FE, r], vec[V_FHAND, r]
        o = 1 + 7 * m
        w = st[S_WENV]
        if st[S_MET] != 0.0:
            e = 0.0
            for r in range(m):
                e += vec[V_MF, r] * (sd_s[idx_s[r]] - vec[V_MX, r])
            w = w + e
        row[o], row[o + 1] = st[S_WORK], w
        row[o + 2], row[o + 3], row[o + 4], row[o + 5] = st[PM + P_IN], st[PM + P_OUT], st[PS + P_IN], st[PS + P_OUT]
        row[o + 6], row[o + 7] = st[PM + P_GAIN], st[PS + P_GAIN]
        lay[L_DONE] = j + 1
        if out != DONE:
            lay[L_OUT], lay[L_STATUS] = out, status
            return
