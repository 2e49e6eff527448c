"""Simulated experiments of §3.5–3.6 and §6.4: system identification and virtual psychophysics.

Everything here runs on the MuJoCo plant (`rhi.sim.Plant`) generated from the device
descriptions, so the numbers are *measurements* of the simulated hardware, analysed with
the thesis's procedures (`rhi.analysis.sysid`, `rhi.analysis.psychophysics`,
`rhi.analysis.stats`), never copies of the thesis's values.

System identification (Tables 3.2 and 6.1; `sysid_table_3_2`, `sysid_table_6_1`)
---------------------------------------------------------------------------------
Protocol (§3.5, §6.4): the plant starts at rest ``before`` metres ahead of the point of
interest (1 cm in ch. 3, 5 cm in ch. 6), a constant external force of 0.5–1.5 N along
u = [0, 1] pushes the handle (ten trials; magnitudes drawn uniformly from a seeded
generator), the position along u comes from forward kinematics of the *encoder* angles
(``device.fk(log.q)``), the force from the handle's F/T sensor, and
``M_x ẍ + Φ ẋ + c = F`` (eqs. 3.24, 6.22, plus a constant ``c``) is fitted by
`rhi.analysis.sysid.identify` (Savitzky–Golay second-order differentiator, zero-phase
5th-order Butterworth, least squares) on the samples whose position lies within
``± window`` of the point.

What the motors do during a trial (the thesis does not say; our choice):

- ``controller="off"`` (Table 3.2's default): the motors exert no torque; the
  identified dynamics are the device's own. For a free chain pushed from rest by F u the
  joint acceleration is M⁻¹JᵀuF, so ``uᵀẍ = F/Λ`` with Λ = (uᵀJM⁻¹Jᵀu)⁻¹ *exactly* eq.
  3.13, for the redundant RHI too (its null space is free and follows the dynamically
  consistent motion). Hence the model prediction we put beside the identified M_x.
- ``controller="nullspace"`` (Table 6.1's default): the null-space controller that
  set the configuration keeps running (primary force zero, no compensation terms, the
  FME-matching objective with β = 20, K_d = 0.1 and the joint-limit barrier of
  `rhi.experiments.ch6`, dynamically consistent projector). Null-space torques satisfy
  J M⁻¹ Nᵀ τ = 0, so they do not change uᵀẍ: the identified M_x still estimates Λ of
  eq. 3.13, while Φ includes the null-space damping's effect on the joint velocities.

Model predictions beside the identification, at the configuration the plant actually
has at the point of interest (mean over the trials):

- Λ = (uᵀ J M⁻¹ Jᵀ u)⁻¹ (eq. 3.13);
- Φ_model = Λ uᵀ J M⁻¹ D q̇ / (uᵀ J q̇): the viscous joint friction D of
  ``device.toml [plant]`` reflected along u for the joint velocity q̇ the plant has
  there (the instantaneous reflection; the quasi-static one of `rhi.experiments.ch6.
  reflected_damping` applies only at steady state, which these 20–100 ms records never
  reach);
- c_model = Λ uᵀ J M⁻¹ (τ_c ⊙ sign q̇): the joints' Coulomb friction (``frictionloss``)
  reflected along u.

What eqs. 3.24/6.22 omit: the Coriolis and centrifugal force F_vp = Λ uᵀ(J M⁻¹ C q̇ − J̇ q̇)
(`velocity_product_force`). From rest under a constant force the handle reaches the point
with v² ∝ F, so F_vp ≈ k F in every trial and the fit reads it as inertia: M_x ≈ Λ/(1 − k).
k is −2 to −4 % after the 1 cm run-up of ch. 3 and −15 % for the M_Stiff^des configuration
after the 5 cm run-up of ch. 6 (1–2 m/s at the point); each case reports k and Λ/(1 − k).
Fitting eq. 3.24 without a constant also folds the Coulomb friction into M_x and Φ (the
thesis's fit does the same); the fit with a constant c is reported beside it.

Why the thesis's numbers differ from ours: Table 3.2 was identified on the hardware,
whose inertias the thesis does not publish (ours are the documented estimates of
``models/rhi4/README.md``), so we compare each identified M_x with the eq. 3.13 value of
*our* model (the loop formula ↔ physics) and report the thesis's beside it. The thesis's
own Table 3.2 exceeds its Table 3.1 by 7–30 % (the F/T sensor and handle it added, and
the Coulomb friction its eq. 3.24 does not model); the simulated plant has a 1 g handle
and constant Coulomb friction fitted by ``c``.

Virtual psychophysics (Table 3.3, Figs 3.9–3.10; `psychophysics`)
------------------------------------------------------------------
Physics: for each device, each of the nine stimulus stiffnesses K (50 N/m ± 0, 5, 15,
25, 35 %) and each palpation duration T of a small grid, one simulation: the plant starts
at (0.49, −0.22) m (the RHI at the thesis's optimised configuration projected onto the
point, the NHIs by IK); the controller renders the virtual spring K (a one-sided wall
at the start point along u) plus the virtual fixture (§3.5: 1000 N/m, 5 N s/m across u)
through ``ForceRendering`` (the RHI also runs the ch. 3 VME-matching null-space
controller of `rhi.experiments.ch3_control`); a physical stop 8 cm ahead (§3.5) bounds
the motion; the simulated hand (`MinimumJerkPalpation`) pushes in along u from the start
to 1 cm past the stop with a minimum-jerk reference of duration T and returns.

Perception: the observer estimates the stiffness from what reaches the hand during the
loading phase before the stop, K̂ = Σ F d / Σ d² (least squares through the origin of the
force the hand exerts along u against its displacement d; a spring has no force at zero
displacement, so any offset the device adds — Coulomb and viscous friction, inertia
during acceleration — is attributed to the spring). The device's distortion of K̂ depends
on the palpation speed, which varies from probe to probe.

Trials: the §3.5 protocol (`rhi.analysis.psychophysics.protocol`); on every trial the two
probes of the pair each draw a palpation duration from the grid (independently, uniform),
and the subject perceives K̃ = K̂ (1 + w_s ε), ε ~ N(0, 1) (Weber's law: noise
proportional to the magnitude), and answers "comparison stiffer" when K̃_comparison >
K̃_reference (with lapse probability ``lapse``, a coin flip). Each subject s has an
intrinsic Weber fraction w_s drawn once from N(``weber_mean``, ``weber_sd``) (clipped to
≥ 0.02), the same on every device: the devices differ only through the physics. The
default intrinsic WF, 0.08 ± 0.02, is the *lower* end of the range the thesis cites for
stiffness discrimination (0.08–0.30, [54], [73], [141]): a sensitive observer, so that
device effects are not drowned. It is an input of the model, not fitted to Table 3.3;
with the 2AFC comparison of two noisy percepts the measured WF of a transparent device is
about √2 · 0.674 · w ≈ 0.95 w.

Simulating every one of the 2700 probes would take hours, hence the lookup: one
simulation per (device, K, T), trials drawn from them (documented in the result).
Analysis: psignifit fits per subject and device, PSE, LT, UT, JND (eq. 3.26), WF (eq.
3.25), one-way ANOVA on WF (as the thesis: F(2, 27)), the repeated-measures ANOVA the
within-subject design calls for, and paired t-tests with Holm–Bonferroni (§3.6) and FDR.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from rhi import thesis as T
from rhi.analysis import psychophysics as pp
from rhi.analysis.sysid import Record, SysidResult, identify
from rhi.control import WeightedSum
from rhi.device import Device, device
from rhi.errors import InvalidInput
from rhi.experiments.result import Result, Row, Table
from rhi.metrics import effective_inertia, max_force

Progress = Callable[[int, int], None]

#: Direction of motion of §3.5 and §6.4.
U = (0.0, 1.0)
#: Table 3.2: identified Λ [kg] along u at the two points of Table 3.1.
THESIS_TABLE_3_2 = T.TABLE_3_2
#: Table 6.1: (M_x [kg], Φ [N s/m], F_max [N]) at [0.5, 0.1] m.
THESIS_TABLE_6_1 = T.TABLE_6_1
#: Table 3.3: (mean, std) of WF, JND [N/m], PSE [N/m] per device.
THESIS_TABLE_3_3 = T.TABLE_3_3
#: §3.6: one-way ANOVA on WF, F(2, 27) = 7.36, P = 0.0032.
THESIS_ANOVA = T.ANOVA_3_6
#: §3.6: Holm-adjusted paired t-tests on WF.
THESIS_PAIRED = T.PAIRED_3_6
#: Constant external force range of the identification [N] and trials per case.
FORCE_RANGE = (0.5, 1.5)
TRIALS = 10
#: Point of interest and start of the ch. 6 identification [m].
X_CH6 = (0.5, 0.1)
BEFORE_CH6 = 0.05
BEFORE_CH3 = 0.01
#: Half-width of the position window around the point of interest [m].
WINDOW = 0.003
#: ch. 6: the handle passes [0.5, 0.1] m at up to 2 m/s after 5 cm of a 1.5 N push on a 0.04 kg
#: inertia, 1.5 mm per 1 kHz sample, so the window is wider [m].
WINDOW_CH6 = 0.01
#: Psychophysics: start point (§3.5), stop distance [m], fixture gains.
START = (0.49, -0.22)
STOP_DISTANCE = 0.08
FIXTURE_STIFFNESS, FIXTURE_DAMPING = 1000.0, 5.0
#: Palpation durations (in-stroke, minimum jerk) [s] of the lookup grid.
DURATIONS = (0.6, 0.9, 1.3, 2.0)
DEVICE_NAMES = {"RHI": "rhi4", "PHANToM": "phantom", "Rehab": "rehab"}


# =============================================================================== sysid
@dataclasses.dataclass(frozen=True)
class SysidCase:
    """One identified case: the fit and the model's prediction at the same configuration.

    Attributes:
        label: e.g. "RHI at (0.49, -0.22)".
        fit: `SysidResult` of the pooled trials, eq. 3.24/6.22 as the thesis fits it (M_x, Φ).
        fit_c: the same with a constant force c (Coulomb friction) fitted too.
        vp_share: k = mean F_vp / mean F over the fitted samples (signed; how much eq. 3.24
            omits). From rest under a constant force the handle reaches the point with v² ∝ F,
            so F_vp ≈ k F in every trial: indistinguishable from inertia, it makes eq. 3.24
            identify M_x ≈ Λ/(1 − k) instead of Λ (`lam_vp`).
        lam_model: Λ of eq. 3.13 at the configuration the plant has at the point (trial mean) [kg].
        lam_nominal: Λ of eq. 3.13 at the nominal configuration of the point [kg].
        phi_model: viscous joint friction reflected along u at the point (trial mean) [N s/m].
        c_model: Coulomb joint friction reflected along u at the point (trial mean) [N].
        q_point: (trials, n) configuration at the point per trial [rad].
        forces: (trials,) applied force magnitudes [N].
        records: the trials (position along u from FK of the encoders, F/T force along u).
    """

    label: str
    fit: SysidResult
    fit_c: SysidResult
    vp_share: float
    lam_model: float
    lam_nominal: float
    phi_model: float
    c_model: float
    q_point: np.ndarray
    forces: np.ndarray
    records: list[Record]

    @property
    def lam_vp(self) -> float:
        """Λ/(1 − k): what eq. 3.24 should identify given the velocity-product share k [kg]."""
        return self.lam_model / (1.0 - self.vp_share)

    @property
    def lam_error(self) -> float:
        """(identified − model)/model of Λ."""
        return self.fit.mass / self.lam_model - 1.0


class _ZeroTorque:
    """The motors off: τ = 0 (the device's own dynamics)."""

    def __init__(self, n: int) -> None:
        self.n = n

    def step(self, t, q, dq, sensors) -> np.ndarray:
        return np.zeros(self.n)


def reflected_friction(dev: Device, q: np.ndarray, dq: np.ndarray, u, damping: np.ndarray,
                       frictionloss: np.ndarray) -> tuple[float, float, float]:
    """(Λ [kg], Φ [N s/m], c [N]) felt along u at (q, q̇) by a chain with joint friction.

    From M q̈ = Jᵀ u F − D q̇ − τ_c sign(q̇) (motors off or acting in the null space only):
    uᵀẍ = (F − Φ uᵀẋ − c)/Λ with Λ = (uᵀJM⁻¹Jᵀu)⁻¹ (eq. 3.13),
    Φ = Λ uᵀJM⁻¹Dq̇ / uᵀJq̇ and c = Λ uᵀJM⁻¹(τ_c ⊙ sign q̇) (the J̇q̇ and Coriolis terms,
    quadratic in the velocity, are left out as eq. 3.24 leaves them out).

    Args:
        dev: device; q, dq: (n,) configuration [rad] and velocity [rad/s] (uᵀJq̇ ≠ 0);
        u: (m,) direction; damping: (n,) D [N m s/rad]; frictionloss: (n,) τ_c [N m].
    """
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    J, M = dev.jacobian(q), dev.mass_matrix(q)
    lam = float(effective_inertia(J, M, u))
    row = np.linalg.solve(M, J.T @ u)  # M⁻¹Jᵀu (M symmetric): uᵀJM⁻¹ = rowᵀ
    v = float(u @ J @ dq)
    if abs(v) < 1e-9:
        raise InvalidInput("dq: no motion along u; the reflected viscous friction is undefined")
    phi = lam * float(row @ (damping * dq)) / v
    c = lam * float(row @ (frictionloss * np.sign(dq)))
    return lam, phi, c


def push_trials(
    dev: Device,
    q_start: np.ndarray,
    point,
    *,
    forces: Sequence[float],
    u=U,
    after: float = 0.01,
    tail: float = 0.04,
    controller: Callable[[], object] | None = None,
    max_duration: float = 3.0,
    label: str = "",
    progress: Progress | None = None,
) -> tuple[list[Record], list[tuple[np.ndarray, np.ndarray]]]:
    """The identification trials of §3.5/§6.4 on the MuJoCo plant.

    Each trial resets the plant at rest at ``q_start``, pushes the handle with a constant
    force along u (`rhi.sim.PushForce`) and records until the handle is ``after`` metres
    past the point and ``tail`` seconds have passed since (room for the differentiator's
    and the filter's edges beyond the samples that are fitted). Position: FK of the encoder
    angles projected on u; force: the F/T sensor projected on u.

    Args:
        dev: the device (model and plant).
        q_start: (n,) start configuration at rest [rad].
        point: (m,) point of interest [m].
        forces: magnitudes [N], one trial each.
        u: (m,) direction of the force.
        after: how far past the point to record at least [m].
        tail: how long to record at least after passing ``point + after`` [s].
        controller: factory of a fresh controller per trial (None: motors off).
        max_duration: give up if the point is not passed within this time [s].
        label: prefix of the record labels.
        progress: callback(done, total) in trials.

    Returns:
        ``(records, states)``: the trials, and per trial the encoder readings ``(q, dq)``,
        each (N, n) [rad], [rad/s], aligned with the record's samples.

    Raises:
        InvalidInput: the handle does not pass the point within ``max_duration``.
    """
    from rhi.sim import Plant, PushForce, simulate

    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    p_goal = float(np.asarray(point, dtype=float) @ u)
    recs, states = [], []
    for i, F in enumerate(forces):
        plant = Plant(dev)
        plant.reset(np.asarray(q_start, dtype=float))
        ctrl = controller() if controller is not None else _ZeroTorque(dev.n)
        push = PushForce(u, float(F))
        logs, t_pass = [], None
        while True:
            log = simulate(plant, ctrl, duration=0.01, hand=push)
            logs.append(log)
            if log.fault is not None:
                raise InvalidInput(f"controller: stopped during trial {i} of {label or dev.name}: {log.fault}")
            if t_pass is None and float(dev.fk(log.q[-1]) @ u) >= p_goal + after:
                t_pass = float(log.t[-1])
            if t_pass is not None and float(log.t[-1]) >= t_pass + tail:
                break
            if plant.time > max_duration:
                raise InvalidInput(f"forces: trial {i} ({F:.3g} N) of {label or dev.name} did not reach the point "
                                   f"within {max_duration} s")
        t = np.concatenate([g.t for g in logs])
        q = np.concatenate([g.q for g in logs])
        dq = np.concatenate([g.dq for g in logs])
        ft = np.concatenate([g.ft for g in logs])
        x = dev.fk(q) @ u
        f = ft[:, : len(u)] @ u
        recs.append(Record(t, x, f, f"{label} trial {i + 1} ({F:.3f} N)"))
        states.append((q, dq))
        if progress is not None:
            progress(i + 1, len(forces))
    return recs, states


def velocity_product_force(dev: Device, q: np.ndarray, dq: np.ndarray, u) -> np.ndarray:
    """Force along u the velocity-product terms add to eq. 3.24: (N,) [N].

    With M q̈ + C(q, q̇) q̇ = Jᵀ u F − τ_f (motors off or in the null space only),
    F = Λ uᵀẍ + Λ uᵀJM⁻¹τ_f + F_vp with F_vp = Λ uᵀ(J M⁻¹ C q̇ − J̇ q̇): the Coriolis and
    centrifugal terms that eqs. 3.24 and 6.22 leave out. Negligible at low speed; at the
    1–2 m/s the handle reaches after a 5 cm push of a light configuration they are not.

    Args:
        dev: device; q, dq: (N, n) encoder readings [rad], [rad/s]; u: (m,) direction.
    """
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    J, M, dJ, C = dev.jacobian(q), dev.mass_matrix(q), dev.jacobian_derivative(q), dev.coriolis(q, dq)
    lam = effective_inertia(J, M, u)
    Jdot_dq = np.einsum("...ijk,...j,...k->...i", dJ, dq, dq)
    row = np.linalg.solve(M, np.einsum("...ij,i->...j", J, u)[..., None])[..., 0]  # M⁻¹Jᵀu
    return lam * (np.einsum("...j,...jk,...k->...", row, C, dq) - Jdot_dq @ u)


def identify_case(
    dev: Device,
    q_start: np.ndarray,
    q_nominal: np.ndarray,
    point,
    *,
    label: str,
    forces: np.ndarray,
    u=U,
    window: float = WINDOW,
    controller: Callable[[], object] | None = None,
    cutoff_hz: float = 20.0,
    progress: Progress | None = None,
) -> SysidCase:
    """Run `push_trials` and identify ``M_x ẍ + Φ ẋ + c = F`` on the samples within ±window of the point.

    Args:
        dev, q_start, point, forces, u, controller, progress: see `push_trials`.
        q_nominal: (n,) configuration the experiment intends at the point (eq. 3.13 there too) [rad].
        label: case name.
        window: half-width of the position window [m].
        cutoff_hz: Butterworth cut-off [Hz] (`rhi.analysis.sysid.identify`).
    """
    from rhi.sim import device_friction

    recs, states = push_trials(dev, q_start, point, forces=forces, u=u, after=window,
                               controller=controller, label=label, progress=progress)
    uu = np.asarray(u, dtype=float) / np.linalg.norm(u)
    p = float(np.asarray(point, dtype=float) @ uu)
    rng = (p - window, p + window)
    fit = identify(recs, cutoff_hz=cutoff_hz, offset=False, position_range=rng)
    fit_c = identify(recs, cutoff_hz=cutoff_hz, offset=True, position_range=rng)
    vp = [velocity_product_force(dev, q, dq, uu) for q, dq in states]
    k_pt = [int(np.argmin(np.abs(r.position - p))) for r in recs]
    qp = np.array([q[k] for (q, _), k in zip(states, k_pt)])
    dqp = np.array([dq[k] for (_, dq), k in zip(states, k_pt)])
    inwin = np.concatenate([f[(r.position >= rng[0]) & (r.position <= rng[1])] for r, f in zip(recs, vp)])
    f_in = np.concatenate([r.force[(r.position >= rng[0]) & (r.position <= rng[1])] for r in recs])
    vp_share = float(np.mean(inwin) / np.mean(f_in)) if inwin.size else float("nan")
    fr = device_friction(dev)
    pred = np.array([reflected_friction(dev, q, dq, uu, fr.damping, fr.frictionloss) for q, dq in zip(qp, dqp)])
    lam_nom = float(effective_inertia(dev.jacobian(q_nominal), dev.mass_matrix(q_nominal), uu))
    return SysidCase(label, fit, fit_c, vp_share, float(pred[:, 0].mean()), lam_nom,
                     float(pred[:, 1].mean()), float(pred[:, 2].mean()), qp, np.asarray(forces, dtype=float), recs)


def trial_forces(trials: int = TRIALS, seed: int = 0) -> np.ndarray:
    """Seeded constant-force magnitudes, uniform in 0.5–1.5 N (§3.5, §6.4): (trials,) [N]."""
    if int(trials) != trials or trials < 2:
        raise InvalidInput(f"trials: need an integer >= 2 (the cluster-robust CIs need several), got {trials!r}")
    return np.random.default_rng(seed).uniform(*FORCE_RANGE, size=int(trials))


def _case_arrays(case: SysidCase, key: str) -> dict[str, np.ndarray]:
    """Arrays of one case for the figures: the first trial's signals, the fits and the model."""
    r = case.records[0]
    f, g = case.fit, case.fit_c
    return {
        f"{key}_t": r.time, f"{key}_x": r.position, f"{key}_F": r.force,
        f"{key}_fit": np.array([f.mass, f.damping]),
        f"{key}_ci": np.array([f.mass_ci, f.damping_ci]),
        f"{key}_fit_c": np.array([g.mass, g.damping, float(g.offset)]),
        f"{key}_model": np.array([case.lam_model, case.phi_model, case.c_model]),
        f"{key}_lam_vp": np.array(case.lam_vp),
        f"{key}_forces": case.forces, f"{key}_q_point": case.q_point,
    }


def _fit_rows(case: SysidCase, where: str, thesis_m: float | None, thesis_phi: float | None,
              m_note: str) -> list[Row]:
    f, g = case.fit, case.fit_c
    ci = lambda c: f"95 % CI [{c[0]:.4g}, {c[1]:.4g}]"  # noqa: E731
    return [
        Row(f"M_x identified (eq. 3.24: M_x ẍ + Φ ẋ = F), {where}", thesis_m, f.mass, "kg",
            f"{ci(f.mass_ci)}; {m_note}"),
        Row(f"Λ eq. 3.13 at the plant's configuration at the point, {where}", thesis_m, case.lam_model, "kg",
            f"identified − model: {100 * case.lam_error:+.1f} %"),
        Row(f"Λ eq. 3.13 at the nominal configuration, {where}", thesis_m, case.lam_nominal, "kg"),
        Row(f"Φ identified (eq. 3.24), {where}", thesis_phi, f.damping, "N s/m",
            f"{ci(f.damping_ci)}; absorbs the Coulomb friction, as the thesis's fit does"),
        Row(f"M_x identified with a constant c (M_x ẍ + Φ ẋ + c = F), {where}", thesis_m, g.mass, "kg",
            ci(g.mass_ci)),
        Row(f"Φ identified with a constant c, {where}", thesis_phi, g.damping, "N s/m",
            f"{ci(g.damping_ci)}; c and Φ ẋ are nearly collinear over a short window"),
        Row(f"Φ model (viscous joint damping reflected along u), {where}", thesis_phi, case.phi_model, "N s/m"),
        Row(f"c identified, {where}", None, float(g.offset), "N",
            f"{ci(g.offset_ci)}; model (Coulomb joint friction reflected along u): {case.c_model:.4f} N"),
        Row(f"velocity-product (Coriolis, centrifugal) force / push force k in the window, {where}", None,
            case.vp_share, "", "what eqs. 3.24/6.22 omit (signed)"),
        Row(f"Λ/(1 − k): eq. 3.13 with the omitted velocity-product force, {where}", thesis_m, case.lam_vp, "kg",
            f"identified − this: {100 * (f.mass / case.lam_vp - 1):+.1f} %"),
        Row(f"fit R² (eq. 3.24), {where}", None, f.r_squared, "", f"{f.n_samples} samples, {f.n_trials} trials, "
            f"residual RMS {f.residual_rms:.3g} N"),
    ]


def sysid_table_3_2(
    trials: int = TRIALS,
    *,
    seed: int = 0,
    configuration: str = "thesis",
    window: float = WINDOW,
    cutoff_hz: float = 20.0,
    progress: Progress | None = None,
) -> Result:
    """Table 3.2: Λ along u = [0, 1] identified on the simulated RHI, PHANToM and Rehab at the Table 3.1 points.

    Motors off (`push_trials` with no controller: the devices' own dynamics), start 1 cm
    before each point, constant force 0.5–1.5 N along u, `trials` trials per case.

    Args:
        trials: trials per device and point (thesis: 10).
        seed: seed of the force magnitudes (the same magnitudes for every case).
        configuration: the RHI's configuration at the point: "thesis" (the optimised
            configuration printed in §3.5) or "optimum" (our optimum of eq. 3.22,
            `rhi.control.configuration.optimal_configuration`); the start is its nearest
            point on the self-motion manifold of the start point (IK without null-space motion).
        window: half-width of the position window around the point [m].
        cutoff_hz: low-pass cut-off [Hz].
        progress: callback(done, total) in trials.
    """
    from rhi.control import VMEMatching
    from rhi.control.configuration import optimal_configuration
    from rhi.experiments.ch3 import BETA, POINTS, THESIS_Q

    if configuration not in ("thesis", "optimum"):
        raise InvalidInput(f"configuration: expected 'thesis' or 'optimum', got {configuration!r}")
    forces = trial_forces(trials, seed)
    u = np.array(U)
    total = 6 * len(forces)
    done = [0]
    rows, arrays, cases = [], {"forces": forces}, {}
    ordering_ok = []
    for i, x in enumerate(POINTS):
        x = np.array(x)
        where = f"({x[0]}, {x[1]})"
        lam_here = {}
        for name, dname in DEVICE_NAMES.items():
            dev = device(dname)
            if name == "RHI":
                q_nom = np.array(THESIS_Q[i])
                q_nom = dev.ik(x, q_nom, k_null=0.0)
                if configuration == "optimum":
                    q_nom = optimal_configuration(dev, x, VMEMatching(tuple(U), BETA), q_nom)
            else:
                q_nom = dev.ik(x, np.full(dev.n, 0.3))
            q_start = dev.ik(x - BEFORE_CH3 * u, q_nom, k_null=0.0)
            cb = None
            if progress is not None:
                base = done[0]
                cb = lambda k, n, base=base: progress(base + k, total)  # noqa: E731
            case = identify_case(dev, q_start, q_nom, x, label=f"{name} at {where}", forces=forces, u=u,
                                 window=window, cutoff_hz=cutoff_hz, progress=cb)
            done[0] += len(forces)
            cases[(name, i)] = case
            lam_here[name] = case.fit.mass
            rows += _fit_rows(case, f"{name} at {where}", THESIS_TABLE_3_2[name][i], None,
                              "thesis: hardware identification (Table 3.2)")
            arrays.update(_case_arrays(case, f"{name}_{i}"))
        ordering_ok.append(lam_here["RHI"] <= lam_here["PHANToM"] < lam_here["Rehab"])
    errs = np.array([c.lam_error for c in cases.values()])
    errs_vp = np.array([c.fit.mass / c.lam_vp - 1.0 for c in cases.values()])
    summary = [
        Row("largest |identified − eq. 3.13| / eq. 3.13 over the six cases", None, float(np.max(np.abs(errs))), "",
            "the loop between the formula and the physics"),
        Row("largest |identified − Λ/(1 − k)| / (Λ/(1 − k)) over the six cases", None,
            float(np.max(np.abs(errs_vp))), "", "eq. 3.13 with the velocity-product force eq. 3.24 omits"),
        Row("cases with identified Λ ordered RHI ≤ PHANToM < Rehab (of 2 points)", T.TABLE_3_2_ORDER, float(sum(ordering_ok)), ""),
    ]
    for i in range(2):
        for a, b in (("RHI", "PHANToM"), ("RHI", "Rehab")):
            th = T.TABLE_3_2_RATIO[a, b, i]
            summary.append(Row(f"ratio Λ_{a}/Λ_{b} identified at point {i + 1}", th,
                               cases[(a, i)].fit.mass / cases[(b, i)].fit.mass, ""))
    arrays["lambda_identified"] = np.array([[cases[(n, i)].fit.mass for n in DEVICE_NAMES] for i in range(2)])
    arrays["lambda_ci"] = np.array([[cases[(n, i)].fit.mass_ci for n in DEVICE_NAMES] for i in range(2)])
    arrays["lambda_model"] = np.array([[cases[(n, i)].lam_model for n in DEVICE_NAMES] for i in range(2)])
    arrays["lambda_thesis"] = np.array([[THESIS_TABLE_3_2[n][i] for n in DEVICE_NAMES] for i in range(2)])
    return Result(
        "perception.sysid_table_3_2",
        "Table 3.2: effective apparent inertia Λ along u = [0, 1] identified on the simulated devices",
        [Table("Table 3.2: identified Λ (and Φ, c) beside the thesis and beside eq. 3.13", rows),
         Table("Identification vs model and ordering", summary)],
        arrays,
        [
            f"MuJoCo plant, motors off, {len(forces)} trials per case with seeded constant forces "
            f"{np.round(forces, 3).tolist()} N along u from 1 cm before the point; position from FK of the "
            "encoders, force from the F/T sensor; Savitzky–Golay derivatives, zero-phase 5th-order Butterworth "
            f"({cutoff_hz:g} Hz), least squares on the samples within ±{1000 * window:g} mm of the point, "
            "cluster-robust CIs (one cluster per trial).",
            "We fit M_x ẍ + Φ ẋ + c = F: the constant c absorbs the Coulomb friction of the moving joints "
            "(eq. 3.24 has none; the thesis starts 1 cm early to get past static friction).",
            "Thesis values are hardware identifications; their inertial model is not published, ours is estimated "
            "(models/rhi4/README.md), so the check is identified vs eq. 3.13 of our model and the ordering.",
            f"RHI configuration: {configuration!r} (see the docstring).",
        ],
    )


def ch6_configurations(starts: int = 3) -> dict[str, np.ndarray]:
    """The rhi4 configurations at [0.5, 0.1] m set by FME matching to M_Free^des and M_Stiff^des.

    `rhi.experiments.ch6.best_match` of the ch. 6 controller's null-space cost (FME matching,
    β = 20, plus the joint-limit barrier), exactly as `rhi.experiments.ch6.palpation` starts.

    Returns:
        {"free": (4,), "stiff": (4,)} [rad].
    """
    from rhi.experiments import ch6

    dev = device("rhi4")
    _, _, Mf, Ms = ch6.desired_fmes(dev, np.array(U), ch6.Q_HOME)
    out = {}
    for case, Md in (("free", Mf), ("stiff", Ms)):
        obj = WeightedSum(ch6.controller_terms(Md, dev.torque_max))
        out[case] = ch6.best_match(dev, np.array(X_CH6), obj, starts=starts)
    return out


def _ch6_controller(dev: Device, desired: np.ndarray, projector: str = "dynamic") -> Callable[[], object]:
    """Factory of the ch. 6 null-space controller with a zero primary force (sysid: nothing rendered).

    projector: "dynamic" (J#, eq. 5.9 as the thesis writes it) or "pseudoinverse" (J⁺).
    """
    from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
    from rhi.experiments import ch6

    def make():
        cfg = ControllerConfig(primary=ForceRendering(damping=0.0, coriolis=False, gravity=False, passivity=None),
                               objectives=ch6.controller_terms(desired, dev.torque_max), damping=ch6.K_D,
                               saturation="scaling", projector=projector)
        return NullSpaceController(dev, cfg)

    return make


def sysid_table_6_1(
    trials: int = TRIALS,
    *,
    seed: int = 0,
    controller: str = "nullspace",
    window: float = WINDOW_CH6,
    starts: int = 3,
    cutoff_hz: float = 20.0,
    projectors: tuple[str, ...] = ("dynamic", "pseudoinverse"),
    progress: Progress | None = None,
) -> Result:
    """Table 6.1: M_x, Φ and F_max along u at [0.5, 0.1] m for the FME-matched configurations of rhi4.

    The configurations at the point are `ch6_configurations`; each trial starts at rest at
    [0.5, 0.05] m at the FME-matched configuration of that start point (the null-space
    controller has converged there while the handle was placed), a constant force of
    0.5–1.5 N pushes along u, and the samples within ±window of [0.5, 0.1] m are fitted.
    F_max: `rhi.metrics.max_force` (LP with null-space torques, dynamic J#) and force
    scaling at the configuration of the point, signed like Table 6.1 (negative: along −u).

    Args:
        trials: trials per case (thesis: 10).
        seed: seed of the force magnitudes.
        controller: "nullspace" (the ch. 6 controller keeps matching the FME; zero primary
            force) or "off" (motors off).
        window: half-width of the position window [m].
        starts: starts of the FME matching (`rhi.experiments.ch6.best_match`).
        cutoff_hz: low-pass cut-off [Hz].
        projectors: null-space projectors of the controller and of the F_max LP, each run in turn:
            "dynamic" (J#, the thesis's text) and/or "pseudoinverse" (J⁺). The first gives the
            array keys ``free_*``/``stiff_*``, the others ``free_pinv_*``/``stiff_pinv_*``. With
            ``controller="off"`` the projector only changes the F_max LP.
        progress: callback(done, total) in trials.
    """
    from rhi.experiments import ch6
    from rhi.metrics import max_force_scaling

    if controller not in ("nullspace", "off"):
        raise InvalidInput(f"controller: expected 'nullspace' or 'off', got {controller!r}")
    if not projectors or len(set(projectors)) != len(projectors) or any(
            p not in ("dynamic", "pseudoinverse") for p in projectors):
        raise InvalidInput(f"projectors: expected distinct 'dynamic'/'pseudoinverse' entries, got {projectors!r}")
    dev = device("rhi4")
    u, x = np.array(U), np.array(X_CH6)
    x_start = x - BEFORE_CH6 * u
    forces = trial_forces(trials, seed)
    _, _, Mf, Ms = ch6.desired_fmes(dev, u, ch6.Q_HOME)
    desired = {"free": Mf, "stiff": Ms}
    q_point = ch6_configurations(starts)
    lo, hi = dev.torque_limits
    rows, arrays, rows_cmp = [], {"forces": forces, "u": u, "x": x}, []
    tf, ts = THESIS_TABLE_6_1["free"], THESIS_TABLE_6_1["stiff"]
    total = len(projectors) * 2 * len(forces)
    for j, proj in enumerate(projectors):
        tag = "J#" if proj == "dynamic" else "J⁺"
        cases = {}
        for k, case in enumerate(ch6.CASES):
            obj = WeightedSum(ch6.controller_terms(desired[case], hi))
            q_start = ch6.match_fme(dev, x_start, obj, q_point[case])
            factory = _ch6_controller(dev, desired[case], proj) if controller == "nullspace" else None
            done = (2 * j + k) * len(forces)
            cb = None if progress is None else (lambda i, n, done=done: progress(done + i, total))
            lab = ("M_Free^des" if case == "free" else "M_Stiff^des") + f" ({tag})"
            res = identify_case(dev, q_start, q_point[case], x, label=lab, forces=forces, u=u, window=window,
                                controller=factory, cutoff_hz=cutoff_hz, progress=cb)
            cases[case] = res
            mx, phi, fmax = THESIS_TABLE_6_1[case]
            rows += _fit_rows(res, lab, mx, phi, "thesis: hardware identification (Table 6.1)")
            J, M = dev.jacobian(q_point[case]), dev.mass_matrix(q_point[case])
            f_lp = float(max_force(J, u, torque_min=lo, torque_max=hi, projector=proj,
                                   M=M if proj == "dynamic" else None))
            f_sc = float(max_force_scaling(J, u, torque_min=lo, torque_max=hi))
            rows += [
                Row(f"F_max along u, {lab}: rhi.metrics.max_force (LP, null-space torques)", fmax, -f_lp, "N",
                    "static capability at the FME-matched configuration; thesis: measured peak"),
                Row(f"F_max along u, {lab}: force scaling (the ch. 6 controller)", fmax, -f_sc, "N"),
            ]
            key = case if j == 0 else f"{case}_pinv" if proj == "pseudoinverse" else f"{case}_dyn"
            arrays.update(_case_arrays(res, key))
            arrays[f"q_nominal_{key}"] = q_point[case]
            arrays[f"q_start_{key}"] = q_start
        cf, cs = cases["free"], cases["stiff"]
        rows_cmp += [
            Row(f"M_x ratio Stiff/Free, identified ({tag})", T.MX_RATIO_6_1, cs.fit.mass / cf.fit.mass, ""),
            Row(f"Φ ratio Stiff/Free, identified ({tag})", T.PHI_RATIO_6_1, cs.fit.damping / cf.fit.damping, ""),
            Row(f"identified − eq. 3.13, M_Free^des ({tag})", None, cf.lam_error, ""),
            Row(f"identified − eq. 3.13, M_Stiff^des ({tag})", None, cs.lam_error, ""),
            Row(f"identified / (Λ/(1 − k)) − 1, M_Free^des ({tag})", None, cf.fit.mass / cf.lam_vp - 1.0, ""),
            Row(f"identified / (Λ/(1 − k)) − 1, M_Stiff^des ({tag})", None, cs.fit.mass / cs.lam_vp - 1.0, ""),
        ]
        if j == 0:
            first = (cf, cs)
    cf, cs = first
    return Result(
        "perception.sysid_table_6_1",
        "Table 6.1: M_x, Φ and F_max along u = [0, 1] at [0.5, 0.1] m identified on the simulated rhi4",
        [Table("Table 6.1 beside the simulated identification", rows),
         Table("M_Stiff^des vs M_Free^des", rows_cmp)],
        arrays,
        [
            f"MuJoCo rhi4 plant, controller {controller!r}, {len(forces)} trials per case, forces "
            f"{np.round(forces, 3).tolist()} N along u from [0.5, 0.05] m; fit on ±{1000 * window:g} mm around "
            "[0.5, 0.1] m (eq. 6.22 plus a constant c for Coulomb friction).",
            "Configurations: FME matching to M_Free^des / M_Stiff^des within the §5.4 joint limits "
            "(rhi.experiments.ch6.best_match); the thesis does not report its configurations.",
            "The thesis's M_x and Φ are hardware identifications; the plant's inertias and joint friction are "
            "estimates (models/rhi4/README.md, device.toml [plant]).",
            f"After a 5 cm push the handle passes the point at 1–2 m/s; the Coriolis and centrifugal force that "
            f"eq. 6.22 omits is k = {cf.vp_share:+.3f} (free) and {cs.vp_share:+.3f} (stiff) of the push force, and "
            "because it scales with the force (v² ∝ F from rest) the fit reads it as inertia: M_x ≈ Λ/(1 − k) "
            f"= {cf.lam_vp:.4f} and {cs.lam_vp:.4f} kg vs identified {cf.fit.mass:.4f} and {cs.fit.mass:.4f} kg.",
        ],
    )


# ======================================================================= psychophysics
@dataclasses.dataclass(frozen=True)
class MinimumJerkPalpation:
    """A hand probing a virtual tissue: a minimum-jerk stroke along u, then a hold.

    The reference moves from ``start`` to ``start + depth u`` along the minimum-jerk profile
    s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ (τ = t/duration; peak speed 1.875 depth/duration), the
    smooth reaching motion of human arms (Flash & Hogan 1985), and stays there; the hand
    is a Cartesian impedance to it, F_h = K_h (x_r − x) + B_h (ẋ_r − ẋ), saturated at
    ``max_force``. With ``depth`` beyond the physical stop, the stroke ends on the stop.

    Attributes:
        start: (m,) start point [m].
        direction: (m,) u.
        depth: stroke length [m].
        duration: stroke duration [s].
        stiffness, damping: K_h [N/m], B_h [N s/m] (a relaxed grasp).
        max_force: saturation of |F_h| [N].
    """

    start: np.ndarray
    direction: np.ndarray
    depth: float
    duration: float
    stiffness: float = 300.0
    damping: float = 10.0
    max_force: float = 20.0

    def __post_init__(self) -> None:
        from rhi._validate import as_array, unit_vector

        p = as_array("start", self.start, ndim_min=1)
        object.__setattr__(self, "start", p)
        object.__setattr__(self, "direction", unit_vector("direction", self.direction, p.shape[-1]))
        for name in ("depth", "duration", "stiffness", "max_force"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InvalidInput(f"{name}: must be finite and > 0, got {v!r}")
        if not (math.isfinite(self.damping) and self.damping >= 0):
            raise InvalidInput(f"damping: must be finite and >= 0, got {self.damping!r}")

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Reference position (m,) [m] and velocity (m,) [m/s] at time t [s]."""
        tau = min(max(t / self.duration, 0.0), 1.0)
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
        ds = 30.0 * tau**2 * (1.0 - tau) ** 2 / self.duration
        return self.start + self.depth * s * self.direction, self.depth * ds * self.direction

    def force(self, t: float, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """F_h: (m,) [N] on the handle at position x (m,) [m], velocity ẋ (m,) [m/s]."""
        xr, vr = self.reference(t)
        F = self.stiffness * (xr - x) + self.damping * (vr - xdot)
        nf = math.sqrt(float(F @ F))  # = np.linalg.norm(F), without its overhead (called at every plant step)
        if nf > self.max_force:
            F = F * (self.max_force / nf)
        return F


def perceived_stiffness(d: np.ndarray, F: np.ndarray) -> float:
    """K̂ = Σ F d / Σ d²: the stiffness a spring through the origin would need to explain (d, F) [N/m].

    Args:
        d: (N,) displacement into the tissue along u [m] (loading phase, before the stop).
        F: (N,) force the hand exerts along u [N].

    Raises:
        InvalidInput: fewer than 3 samples or no displacement.
    """
    d = np.asarray(d, dtype=float)
    F = np.asarray(F, dtype=float)
    if d.shape != F.shape or d.ndim != 1 or d.size < 3 or not np.any(d != 0):
        raise InvalidInput(f"d/F: need two equal 1-D arrays of >= 3 samples with displacement, "
                           f"got {d.shape}, {F.shape}")
    return float(F @ d / (d @ d))


def _palpation_controller(name: str, dev: Device):
    """The rendering controller: ForceRendering (eq. 7.2 with B^d = 0); the RHI also runs the ch. 3 VME matching."""
    from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
    from rhi.experiments import ch3_control

    if name == "RHI":
        return ch3_control.controller(dev)
    cfg = ControllerConfig(primary=ForceRendering(damping=0.0, passivity=None), objectives=(), damping=0.0,
                           saturation="none")
    return NullSpaceController(dev, cfg)


def _start_configuration(name: str, dev: Device, x0: np.ndarray) -> np.ndarray:
    from rhi.experiments import ch3_control

    if name == "RHI":
        return ch3_control.start_configuration(dev, x0, "thesis")
    return dev.ik(x0, np.full(dev.n, 0.3))


def palpate(
    name: str,
    stiffness: float,
    duration: float,
    *,
    start=START,
    u=U,
    stop_distance: float = STOP_DISTANCE,
    overshoot: float = 0.01,
    hold: float = 0.2,
    hand_stiffness: float = 300.0,
    hand_damping: float = 10.0,
    margin: float = 0.003,
) -> dict[str, np.ndarray | float]:
    """One palpation of a virtual spring through a simulated device (§3.5 set-up).

    The plant starts at rest at `start`; the controller renders a one-sided spring of
    `stiffness` from `start` along u plus the virtual fixture across u; a physical stop
    sits `stop_distance` ahead; a `MinimumJerkPalpation` hand strokes to
    `stop_distance + overshoot` in `duration` seconds and holds for `hold`.

    Args:
        name: "RHI", "PHANToM" or "Rehab".
        stiffness: K of the virtual spring [N/m].
        duration: stroke duration [s].
        start, u: start point (m,) [m] and direction.
        stop_distance: distance of the physical stop [m] (§3.5: 8 cm).
        overshoot: how far past the stop the hand's reference goes [m].
        hold: hold time at the end [s].
        hand_stiffness, hand_damping: the hand's impedance [N/m], [N s/m].
        margin: loading samples closer than this to the stop are left out [m].

    Returns:
        dict with "k_hat" (perceived stiffness, `perceived_stiffness` of the loading phase)
        [N/m], "d" [m] and "F" [N] of the loading phase, "peak_speed" [m/s] and "t", "x",
        "F_hand" of the whole run.
    """
    from rhi.sim import Fixture, Plant, Wall, compose, simulate, stop

    if name not in DEVICE_NAMES:
        raise InvalidInput(f"name: expected one of {list(DEVICE_NAMES)}, got {name!r}")
    if not (math.isfinite(stiffness) and stiffness > 0):
        raise InvalidInput(f"stiffness: must be a positive stiffness in N/m, got {stiffness!r}")
    dev = device(DEVICE_NAMES[name])
    x0 = np.asarray(start, dtype=float)
    uu = np.asarray(u, dtype=float) / np.linalg.norm(u)
    plant = Plant(dev)
    plant.reset(_start_configuration(name, dev, x0))
    hand = MinimumJerkPalpation(x0, uu, stop_distance + overshoot, duration, hand_stiffness, hand_damping)
    virtual = compose(Wall(x0, uu, stiffness), Fixture(x0, uu, FIXTURE_STIFFNESS, FIXTURE_DAMPING))
    log = simulate(plant, _palpation_controller(name, dev), duration=duration + hold, hand=hand, virtual=virtual,
                   physical=stop(x0 + stop_distance * uu, uu))
    if log.fault is not None:
        raise InvalidInput(f"name: the controller of {name} stopped while palpating: {log.fault}")
    d = (log.x - x0) @ uu
    F = log.F_hand @ uu
    k_end = int(np.argmax(d >= stop_distance - margin)) if np.any(d >= stop_distance - margin) else len(d)
    load = np.zeros(len(d), dtype=bool)
    load[:k_end] = True
    load &= d > 0
    return {"k_hat": perceived_stiffness(d[load], F[load]), "d": d[load], "F": F[load],
            "peak_speed": float(np.max(log.xdot @ uu)), "t": log.t, "x": d, "F_hand": F}


def stimulus_table(
    devices: Sequence[str] = tuple(DEVICE_NAMES),
    *,
    reference: float = pp.REFERENCE_STIFFNESS,
    comparison_percent: Sequence[float] = pp.COMPARISON_PERCENT,
    durations: Sequence[float] = DURATIONS,
    progress: Progress | None = None,
) -> dict[str, np.ndarray]:
    """K̂ of every (device, stiffness, stroke duration): the lookup the simulated trials draw from.

    Returns:
        {device: (len(comparison_percent), len(durations)) perceived stiffness [N/m]}, plus
        "stiffness" (k,) [N/m], "durations" (s,) [s] and "{device}_speed" (k, s) peak speeds [m/s].
    """
    from rhi.design.executors import parallel_map

    K = reference * (1.0 + np.asarray(comparison_percent, dtype=float) / 100.0)
    T = np.asarray(durations, dtype=float)
    out: dict[str, np.ndarray] = {"stiffness": K, "durations": T}
    items = [(name, float(k), float(dur)) for name in devices for k in K for dur in T]
    # independent, deterministic simulations: the default executor runs them in parallel
    res = iter(parallel_map(_palpation_measures, items, progress=progress))
    for name in devices:
        kh = np.empty((K.size, T.size))
        sp = np.empty((K.size, T.size))
        for i in range(K.size):
            for j in range(T.size):
                kh[i, j], sp[i, j] = next(res)
        out[name], out[f"{name}_speed"] = kh, sp
    return out


def _palpation_measures(item: tuple[str, float, float]) -> tuple[float, float]:
    """(K̂ [N/m], peak speed [m/s]) of `palpate(name, stiffness, duration)` for item = (name, stiffness, duration)."""
    r = palpate(*item)
    return r["k_hat"], r["peak_speed"]


def simulate_study(
    table: dict[str, np.ndarray],
    *,
    subjects: int = 10,
    devices: Sequence[str] = tuple(DEVICE_NAMES),
    repetitions: int = pp.REPETITIONS,
    comparison_percent: Sequence[float] = pp.COMPARISON_PERCENT,
    reference: float = pp.REFERENCE_STIFFNESS,
    weber_mean: float = 0.08,
    weber_sd: float = 0.02,
    lapse: float = 0.0,
    seed: int = 0,
) -> tuple[pp.Responses, np.ndarray]:
    """Simulated 2AFC responses of §3.5 from the stimulus lookup (see the module docstring).

    Args:
        table: `stimulus_table` output covering `devices` and `comparison_percent`.
        subjects: number of simulated subjects.
        devices: device names.
        repetitions, comparison_percent, reference: the protocol (`rhi.analysis.psychophysics.protocol`).
        weber_mean, weber_sd: distribution of the subjects' intrinsic Weber fractions w_s.
        lapse: probability of a random answer.
        seed: seed of the protocol order, the subjects, the stroke durations and the noise.

    Returns:
        ``(responses, weber)``: the `Responses` and (subjects,) intrinsic Weber fractions.
    """
    if not (weber_mean > 0 and weber_sd >= 0):
        raise InvalidInput(f"weber_mean/weber_sd: need a positive mean and non-negative s.d., "
                           f"got {weber_mean}, {weber_sd}")
    if not (0.0 <= lapse < 1.0):
        raise InvalidInput(f"lapse: must lie in [0, 1), got {lapse!r}")
    pct = [float(p) for p in comparison_percent]
    K = reference * (1.0 + np.asarray(pct) / 100.0)
    if len(table["stiffness"]) != len(K) or not np.allclose(table["stiffness"], K):
        raise InvalidInput("table: its stiffnesses do not match comparison_percent and reference")
    if 0.0 not in pct:
        raise InvalidInput("comparison_percent: must include 0 (the reference itself is probed)")
    for d in devices:
        if d not in table:
            raise InvalidInput(f"table: no entry for device {d!r}")
    trials = pp.protocol(subjects, devices, reference=reference, comparison_percent=pct,
                         repetitions=repetitions, seed=seed)
    rng = np.random.default_rng([int(seed), 1])
    weber = np.maximum(rng.normal(weber_mean, weber_sd, size=int(subjects)), 0.02)
    names = sorted({t.subject for t in trials})
    w_of = dict(zip(names, weber))
    i_ref = pct.index(0.0)
    n_dur = table["durations"].size
    resp = np.empty(len(trials), dtype=np.int8)
    for k, t in enumerate(trials):
        kh = table[t.device]
        i_cmp = pct.index(t.comparison_percent)
        j_ref, j_cmp = rng.integers(n_dur, size=2)
        w = w_of[t.subject]
        e = rng.standard_normal(2)
        k_ref = kh[i_ref, j_ref] * (1.0 + w * e[0])
        k_cmp = kh[i_cmp, j_cmp] * (1.0 + w * e[1])
        answer = k_cmp > k_ref
        if rng.random() < lapse:
            answer = rng.random() < 0.5
        resp[k] = int(answer)
    return pp.Responses.from_trials(trials, resp), weber


def _fit_group(group: tuple) -> pp.PsychometricFit:
    """`fit_psychometric` of one (comparisons, responses, subject, device, overdispersion, min_trials) group."""
    x, r, subject, dev, overdispersion, min_trials = group
    return pp.fit_psychometric(x, r, subject=subject, device=dev, overdispersion=overdispersion, min_trials=min_trials)


def _summary_of(analysis, measure: str) -> dict[str, tuple[float, float, float]]:
    return {s.name: (s.mean, s.std, s.median) for s in analysis.summary[measure]}


def psychophysics(
    *,
    subjects: int = 10,
    repetitions: int = pp.REPETITIONS,
    comparison_percent: Sequence[float] = pp.COMPARISON_PERCENT,
    durations: Sequence[float] = DURATIONS,
    weber_mean: float = 0.08,
    weber_sd: float = 0.02,
    lapse: float = 0.0,
    seed: int = 0,
    overdispersion: bool = True,
    table: dict[str, np.ndarray] | None = None,
    progress: Progress | None = None,
) -> Result:
    """Table 3.3, Figs 3.9–3.10: the §3.5 stiffness-discrimination study with simulated subjects and devices.

    See the module docstring for the physics (one simulation per device, stiffness and
    stroke duration), the observer (K̂ through the origin, Weber noise w_s, the same w_s on
    every device) and the analysis (psignifit per subject and device, eqs. 3.25–3.26,
    one-way and repeated-measures ANOVA on WF, paired t-tests with Holm and with FDR).

    Args:
        subjects: simulated subjects (thesis: 10).
        repetitions: presentations per comparison and device (thesis: 10).
        comparison_percent: comparisons [% of 50 N/m] (thesis: 0, ±5, ±15, ±25, ±35).
        durations: stroke durations of the lookup grid [s].
        weber_mean, weber_sd: the subjects' intrinsic Weber fractions (model input, not fitted).
        lapse: lapse rate of the simulated answers.
        seed: seed of everything random.
        overdispersion: psignifit's η (False: about twice as fast).
        table: a precomputed `stimulus_table` (skips the simulations).
        progress: callback(done, total) over simulations, then fits.
    """
    from rhi.analysis.stats import paired_t_tests

    devs = tuple(DEVICE_NAMES)
    n_sim = len(devs) * len(comparison_percent) * len(durations)
    n_fit = subjects * len(devs)
    total = (0 if table is not None else n_sim) + n_fit
    if table is None:
        cb = None if progress is None else (lambda k, n: progress(k, total))
        table = stimulus_table(devs, comparison_percent=comparison_percent, durations=durations, progress=cb)
    responses, weber = simulate_study(table, subjects=subjects, devices=devs, repetitions=repetitions,
                                      comparison_percent=comparison_percent, weber_mean=weber_mean,
                                      weber_sd=weber_sd, lapse=lapse, seed=seed)
    from rhi.design.executors import parallel_map

    groups = [(responses.comparison[idx], responses.response[idx], s, d, overdispersion, min(20, len(idx)))
              for (s, d), idx in responses.groups().items()]
    cb = None if progress is None else (lambda k, n: progress(total - n_fit + k, total))
    fits = parallel_map(_fit_group, groups, progress=cb)  # independent fits, in parallel on the default executor
    analysis = pp.analyse_fits(fits, measure="wf", devices=devs, correction="holm")
    fdr = paired_t_tests(analysis.values, correction="fdr_bh")

    rows = []
    units = {"wf": "", "jnd": "N/m", "pse": "N/m"}
    labels = {"wf": "WF", "jnd": "JND", "pse": "PSE"}
    for m in ("wf", "jnd", "pse"):
        summ = _summary_of(analysis, m)
        for d in devs:
            mean, std, _ = summ[d]
            th_mean, th_std = THESIS_TABLE_3_3[m][d]
            rows.append(Row(f"{labels[m]} mean, {d}", th_mean, mean, units[m]))
            rows.append(Row(f"{labels[m]} std, {d}", th_std, std, units[m]))
    stats_rows = [
        Row(f"one-way ANOVA on WF: F({analysis.anova.df_between:g}, {analysis.anova.df_within:g})", THESIS_ANOVA[0],
            analysis.anova.statistic, "", "thesis: F(2, 27) = 7.36"),
        Row("one-way ANOVA on WF: p", THESIS_ANOVA[1], analysis.anova.p_value, ""),
        Row(f"repeated-measures ANOVA on WF: F({analysis.anova_rm.df_between:g}, {analysis.anova_rm.df_within:g})",
            None, analysis.anova_rm.statistic, "", f"p = {analysis.anova_rm.p_value:.3g} (the within-subject design)"),
    ]
    for t, tf in zip(analysis.paired, fdr):
        th = THESIS_PAIRED.get((t.a, t.b), THESIS_PAIRED.get((t.b, t.a)))
        stats_rows.append(Row(f"paired t-test on WF {t.a} vs {t.b}: Holm-adjusted p", th, t.p_adjusted, "",
                              f"t({t.df}) = {t.statistic:.2f}, mean difference {t.mean_difference:+.4f}; "
                              f"FDR-adjusted p = {tf.p_adjusted:.3g}"))
    ref_i = [float(p) for p in comparison_percent].index(0.0)
    phys_rows = []
    for d in devs:
        kh = table[d][ref_i]
        phys_rows.append(Row(f"K̂ of the 50 N/m reference through {d}: mean over stroke durations", None,
                             float(np.mean(kh)), "N/m",
                             f"range {kh.min():.2f}–{kh.max():.2f} N/m over durations "
                             f"{np.round(table['durations'], 2).tolist()} s "
                             f"(peak speeds {np.round(table[f'{d}_speed'][ref_i], 2).tolist()} m/s)"))
        slope = np.polyfit(table["stiffness"], table[d].mean(axis=1), 1)[0]
        phys_rows.append(Row(f"dK̂/dK through {d} (1: transparent)", None, float(slope), ""))
    phys_rows.append(Row("subjects' intrinsic Weber fraction w_s: mean (model input)", None, float(np.mean(weber)), "",
                         f"drawn from N({weber_mean}, {weber_sd}); measured WF of a transparent device ≈ 0.95 w"))

    # Figures: Fig. 3.9 (subject #3, or the last if fewer), Fig. 3.10 (WF and JND per subject and device).
    subj_names = analysis.subjects
    s3 = subj_names[min(2, len(subj_names) - 1)]
    grid = np.linspace(table["stiffness"].min(), table["stiffness"].max(), 201)
    arrays: dict[str, np.ndarray] = {"stiffness_grid": grid, "stiffness": table["stiffness"],
                                     "durations": table["durations"], "weber": weber,
                                     "fig39_subject": np.array(subj_names.index(s3) + 1)}
    for f in fits:
        if f.subject == s3:
            arrays[f"fig39_data_{f.device}"] = f.data
            arrays[f"fig39_curve_{f.device}"] = f.curve(grid)
    arrays["fig39_ideal"] = (grid > pp.REFERENCE_STIFFNESS).astype(float) + 0.5 * (grid == pp.REFERENCE_STIFFNESS)
    for m in ("wf", "jnd", "pse"):
        _, vals = pp.by_device(fits, m, devices=devs)
        arrays[m] = np.array([vals[d] for d in devs])  # (devices RHI, PHANToM, Rehab; subjects S01, ...)
    for d in devs:
        arrays[f"khat_{d}"] = table[d]
        arrays[f"speed_{d}"] = table[f"{d}_speed"]
    order = np.argsort(arrays["wf"].mean(axis=1))
    notes = [
        f"Simulated study: {subjects} subjects × {len(devs)} devices × {len(comparison_percent)} comparisons × "
        f"{repetitions} repetitions; each probe draws one of {len(durations)} stroke durations "
        f"{list(durations)} s and uses the K̂ of that (device, stiffness, duration) simulation "
        f"({n_sim} MuJoCo runs, one per combination, instead of one per probe).",
        f"Observer: K̂ = ΣFd/Σd² over the loading phase; Weber noise w_s ~ N({weber_mean}, {weber_sd}) "
        "per subject, "
        "the same on every device; these are model inputs from the literature range the thesis cites (0.08–0.30), "
        "not fitted to Table 3.3.",
        f"Devices ordered by mean WF: {[devs[i] for i in order]} (thesis: RHI < PHANToM < Rehab).",
        "psignifit 4 (the thesis used 2.5.6), equal-asymptote cumulative Gaussian, thresholds on the lapse-free "
        "sigmoid; the thesis's ANOVA is the between-subjects one (F(2, 27)); the repeated-measures one fits the "
        "design.",
    ]
    return Result(
        "perception.psychophysics",
        "Table 3.3 / Figs 3.9–3.10: stiffness discrimination through the simulated RHI, PHANToM and Rehab",
        [Table("Table 3.3: mean and std of WF, JND, PSE per device", rows),
         Table("§3.6 statistics on WF", stats_rows),
         Table("What the devices do to the perceived stiffness (simulation)", phys_rows)],
        arrays,
        notes,
    )
