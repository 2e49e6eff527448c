"""The notes of `rhi.experiments.beyond.passivity`'s report: where the energy comes from and what each case costs."""

from __future__ import annotations

from rhi.experiments.beyond.wall_measures import STOP_MARGIN


def notes(res: dict, stiff_res: dict, *, labels: dict[str, str], window: float) -> list[str]:
    """The notes after the set-up's, from the cases' numbers (`res` at the wall, `stiff_res` at the stiff wall).

    Args:
        res: {case: numbers} at the palpation wall.
        stiff_res: {case: numbers} at the stiff wall.
        labels: {case: its label in the tables}.
        window: the moving-average window that separates chatter from the palpation motion [s].
    """
    notes: list[str] = []
    if "objectives" in res:
        m = res["objectives"]
        notes.append(
            f"Where the energy comes from (no PC, objectives on): the motors did {m['motors']:.3f} J of work on the "
            f"mechanism, {m['task']:.3f} J of it at the handle and {m['null']:.3f} J in the null space; the sampled "
            f"wall generated {m['wall_zoh']:.4f} J (sample-and-hold: the wall alone is nearly passive at 1 kHz "
            f"against the plant's friction), the damping B^d dissipated {m['damping']:.4f} J and the plant's joint "
            f"friction {m['friction']:.3f} J. The source is the null-space torque of the allocation under "
            f"saturation: while ASCM holds joints at their torque limits ({100 * m['held']:.0f} % of the ticks) its "
            "null-space torque is balanced by nothing (the hand holds only the handle), so it accelerates the "
            f"self-motion steadily (joint speeds up to {m['qdot_max']:.1f} rad/s) until a joint runs past its range "
            f"into the plant's stop ({100 * m['beyond_range']:.1f} % of the ticks). The motors' work on the "
            "self-motion is lost in friction and stop impacts, and the part that reaches the hand comes through the "
            "stops' reaction and the velocity coupling of the fast self-motion with the handle (the dynamically "
            "consistent projector removes the instantaneous handle force of a null-space torque, neither of these). "
            "Sample-and-hold (the wall's generated energy above), B^d and friction (dissipative) do not make the "
            "device active" + (f"; with simple force scaling, which puts no allocation torque into the null space, "
                               f"W = {res['scaling']['W']:.3g} J (lowest {res['scaling']['W_min']:.2g} J)."
                               if "scaling" in res else "."))
    if "bare" in res and "objectives" in res:
        notes.append(
            f"Null-space objectives: W = {res['objectives']['W']:.3f} J with them and {res['bare']['W']:.3f} J "
            f"without (ASCM alone); their own null-space work adds "
            f"{res['objectives']['null'] - res['bare']['null']:.3f} J to the motors' null-space work.")
    if "objectives_pc" in res:
        m, m0 = res["objectives_pc"], res.get("objectives")
        notes.append(
            f"With the passivity controller at the motor port: W = {m['W']:.4g} J (target ≥ −1 mJ; lowest during "
            f"the run {m['W_min']:.2g} J), lowest E_obs {m['E_obs_min']:.2g} J; the motors' net work is "
            f"{m['motors']:.2g} J. "
            + (f"Force: RMS error {m['force_rms_error']:.2f} N with it vs {m0['force_rms_error']:.2f} N without, "
               f"mean {m['force_mean_error']:.2f} N vs {m0['force_mean_error']:.2f} N, peak {m['force_peak']:.1f} N "
               f"vs {m0['force_peak']:.1f} N. The PC counts every joule the motors put into the mechanism, the "
               "objectives' null-space work included, as active: while that budget is spent it damps the motion "
               f"({100 * m['pc_active']:.0f} % of the ticks) and scales the law down "
               f"({100 * m['pc_scaled']:.0f} % of the ticks), which weakens the wall; it also removes the "
               "stop impacts' force spikes of the run without it." if m0 else ""))
    if "objectives" in res and "objectives_damper" in res:
        m0, m = res["objectives"], res["objectives_damper"]
        notes.append(
            f"Transparency beside passivity (the goal: passive and the peak within 10 % of no PC's): the largest "
            f"force of the run without a PC, {m0['force_peak']:.1f} N at {m0['peak_time']:.2f} s, is "
            + ("a joint-stop impact (a joint past its range limit within "
               f"{STOP_MARGIN * 1e3:g} ms), not the rendered wall; " if m0["peak_at_stop"] else "the rendered wall; ")
            + f"away from the stops the wall peaks at {m0['force_peak_wall']:.2f} N without a PC and "
            f"{m['force_peak_wall']:.2f} N with the series damper (H&R's PC at the motor port, the law never scaled), "
            f"whose hand's work never falls below {m['W_min'] * 1e3:.3f} mJ (W = {m['W']:.3g} J). Each contact's "
            f"largest force (median over the contacts): {m0['contact_peak']:.2f} N without a PC, "
            f"{m['contact_peak']:.2f} N with the series damper, which keeps the self-motion out of the stops "
            f"(fastest joint {m['qdot_max']:.1f} vs {m0['qdot_max']:.1f} rad/s) and the configuration in which the "
            f"wall is rendered; RMS force error {m['force_rms_error']:.2f} N vs {m0['force_rms_error']:.2f} N.")
    for c in ("objectives_damper", "objectives_bounding"):
        if c in res and "objectives" in res:
            m, m0 = res[c], res["objectives"]
            notes.append(
                f"{labels[c][0].upper()}{labels[c][1:]}: W = {m['W']:.4g} J (lowest {m['W_min']:.2g} J); force RMS error "
                f"{m['force_rms_error']:.2f} N vs {m0['force_rms_error']:.2f} N without a PC, mean "
                f"{m['force_mean_error']:.2f} N vs {m0['force_mean_error']:.2f} N; the PC acted on "
                f"{100 * m['pc_active']:.0f} % of the ticks and scaled the law on {100 * m['pc_scaled']:.0f} %.")
    for c in ("objectives_tank", "objectives_tank_damper"):
        if c in res and "objectives" in res and res[c]["sources"] and res["objectives"]["sources"]:
            m, m0 = res[c], res["objectives"]
            notes.append(
                f"{labels[c][0].upper()}{labels[c][1:]}: the objectives did {m['objective_work']:.3g} J of work "
                f"(without the tank {m0['objective_work']:.3g} J) and the null-space side {m['null_work']:.3g} J net "
                f"({m0['null_work']:.3g} J); the allocation's null-space torque did {m['sources']['allocation']:.3g} J "
                f"and its damper {m['sources']['tank damper']:.3g} J (acting on {100 * m['tank_damped']:.0f} % of the "
                f"ticks; ASCM left no redundancy on {100 * m['held_full']:.0f} %); both accounts together ended at "
                f"{m['tank_end']:.3g} J. Hand's work W = {m['W']:.3g} J "
                f"(lowest {m['W_min']:.2g} J); peak force {m['force_peak']:.1f} N vs {m0['force_peak']:.1f} N without "
                f"a PC, RMS force error {m['force_rms_error']:.2f} N vs {m0['force_rms_error']:.2f} N.")
    if "passive" in res and "objectives" in res:
        m, m0 = res["passive"], res["objectives"]
        e = res.get("passive_empty")
        alloc = (f" The allocation's null-space torque did {m['sources']['allocation']:.3g} J (without the gate "
                 f"{m0['sources']['allocation']:.3g} J)." if m["sources"] and m0["sources"] else "")
        bar = (f" The barrier's held torque generated {m0['barrier']['gradient']:.3g} J on the no-PC run's trajectory "
               f"(the gradient sampled and held) and would have generated {m0['barrier']['sampled']:.2g} J in the "
               f"sampled-exact form; in the passive case {m['barrier']['sampled']:.2g} J."
               if m0["barrier"] and m["barrier"] else "")
        notes.append(
            f"The passive null space, no PC ({labels['passive']}): W = {m['W']:.3g} J, lowest {m['W_min'] * 1e3:.2f} "
            f"mJ; the wall's largest force away from the stops {m['force_peak_wall']:.2f} N vs "
            f"{m0['force_peak_wall']:.2f} N without it, per contact {m['contact_peak']:.2f} N vs "
            f"{m0['contact_peak']:.2f} N, RMS force error {m['force_rms_error']:.2f} N vs {m0['force_rms_error']:.2f} N; "
            f"fastest joint {m['qdot_max']:.1f} vs {m0['qdot_max']:.1f} rad/s." + alloc + bar
            + (f" With the tank empty at the start the redistribution cannot start the self-motion (its first "
               f"interval's work is the kinetic energy it gives): W = {e['W']:.3g} J, lowest {e['W_min'] * 1e3:.2f} mJ, "
               f"the wall's largest force {e['force_peak_wall']:.2f} N." if e else ""))
    if "objectives_pc_handle" in res:
        m = res["objectives_pc_handle"]
        notes.append(
            f"At the handle port (H&R's virtual-environment port, J#ᵀτ against ẋ) the observer sees only "
            f"{m['task']:.3f} J and the hand still receives W = {m['W']:.3f} J: the energy comes through the null "
            "space, which only the motor port observes.")
    if stiff_res:
        a, b = stiff_res.get("objectives"), stiff_res.get("objectives_pc")
        if a and b:
            notes.append(
                f"Stiff wall: handle-velocity chatter above {1 / window:g} Hz {a['chatter_velocity'] * 1e3:.1f}"
                f" mm/s without the PC, {b['chatter_velocity'] * 1e3:.1f} mm/s with it; W {a['W']:.3f} J vs "
                f"{b['W']:.3f} J.")
    faults = [f"{c}: {m['fault']}" for c, m in {**res, **stiff_res}.items() if m["fault"]]
    if faults:
        notes.append("Controller faults: " + "; ".join(faults))
    return notes
