"""The system-identification protocol of §3.5 and §6.4 on the MuJoCo plant (Tables 3.2 and 6.1).

Everything runs on the MuJoCo plant (`rhi.sim.Plant`) generated from the device
descriptions, so the numbers are *measurements* of the simulated hardware, analysed with
the thesis's procedure (`rhi.analysis.sysid`), never copies of the thesis's values.

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
  `rhi.experiments.ch6.setup`, dynamically consistent projector). Null-space torques satisfy
  J M⁻¹ Nᵀ τ = 0, so they do not change uᵀẍ: the identified M_x still estimates Λ of
  eq. 3.13, while Φ includes the null-space damping's effect on the joint velocities.

Model predictions beside the identification, at the configuration the plant actually
has at the point of interest (mean over the trials):

- Λ = (uᵀ J M⁻¹ Jᵀ u)⁻¹ (eq. 3.13);
- Φ_model = Λ uᵀ J M⁻¹ D q̇ / (uᵀ J q̇): the viscous joint friction D of
  ``device.toml [plant]`` reflected along u for the joint velocity q̇ the plant has
  there (the instantaneous reflection; the quasi-static one of `rhi.experiments.ch6.setup.
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
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from rhi.analysis.sysid import Record, SysidResult, identify
from rhi.control import ZeroTorque
from rhi.devices.model import Device
from rhi.errors import InvalidInput
from rhi.experiments.result import Row
from rhi.experiments.setups import Progress
from rhi.metrics import effective_inertia
from rhi.sim import Plant, PushForce, device_friction, simulate
from rhi.sim.loop import Controller

#: Direction of motion of §3.5 and §6.4.
U = (0.0, 1.0)
#: Constant external force range of the identification [N] and trials per case.
FORCE_RANGE = (0.5, 1.5)
TRIALS = 10
#: Half-width of the position window around the point of interest [m].
WINDOW = 0.003


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
    def c_identified(self) -> float:
        """The constant force c of `fit_c` [N].

        Raises:
            InvalidInput: `fit_c` was fitted without c (`rhi.analysis.sysid.identify` with offset=False).
        """
        if self.fit_c.offset is None:
            raise InvalidInput(f"fit_c: fitted without the constant force c (identify(..., offset=True)), {self.label}")
        return self.fit_c.offset

    @property
    def lam_error(self) -> float:
        """(identified − model)/model of Λ."""
        return self.fit.mass / self.lam_model - 1.0


def reflected_friction(dev: Device, q: np.ndarray, dq: np.ndarray, u, damping: np.ndarray,
                       frictionloss: np.ndarray) -> tuple[float, float, float]:
    """(Λ [kg], Φ [N s/m], c [N]) felt along u at (q, q̇) by a chain with joint friction.

    From M q̈ = Jᵀ u F − D q̇ − τ_c sign(q̇) (motors off or acting in the null space only):
    uᵀẍ = (F − Φ uᵀẋ − c)/Λ with Λ = (uᵀJM⁻¹Jᵀu)⁻¹ (eq. 3.13),
    Φ = Λ uᵀJM⁻¹Dq̇ / uᵀJq̇ and c = Λ uᵀJM⁻¹(τ_c ⊙ sign q̇) (the J̇q̇ and Coriolis terms,
    quadratic in the velocity, are left out as eq. 3.24 leaves them out).

    Args:
        dev: device.
        q: (n,) configuration [rad].
        dq: (n,) velocity [rad/s] (uᵀJq̇ ≠ 0).
        u: (m,) direction.
        damping: (n,) viscous joint friction D [N m s/rad].
        frictionloss: (n,) Coulomb joint friction τ_c [N m].
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
    forces: Sequence[float] | np.ndarray,
    u=U,
    after: float = 0.01,
    tail: float = 0.04,
    controller: Callable[[], Controller] | None = None,
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
    u = np.asarray(u, dtype=float) / np.linalg.norm(u)
    p_goal = float(np.asarray(point, dtype=float) @ u)
    recs, states = [], []
    for i, F in enumerate(forces):
        plant = Plant(dev)
        plant.reset(np.asarray(q_start, dtype=float))
        ctrl = controller() if controller is not None else ZeroTorque(dev.n)
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
        dev: device.
        q: (N, n) encoder angles [rad].
        dq: (N, n) encoder velocities [rad/s].
        u: (m,) direction.
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
    controller: Callable[[], Controller] | None = None,
    cutoff_hz: float = 20.0,
    progress: Progress | None = None,
) -> SysidCase:
    """Run `push_trials` and identify ``M_x ẍ + Φ ẋ + c = F`` on the samples within ±window of the point.

    Args:
        dev: the device (model and plant).
        q_start: (n,) start configuration at rest [rad].
        point: (m,) point of interest [m].
        forces: magnitudes [N], one trial each.
        u: (m,) direction of the force.
        controller: factory of a fresh controller per trial (None: motors off).
        progress: callback(done, total) in trials.
        q_nominal: (n,) configuration the experiment intends at the point (eq. 3.13 there too) [rad].
        label: case name.
        window: half-width of the position window [m].
        cutoff_hz: Butterworth cut-off [Hz] (`rhi.analysis.sysid.identify`).
    """
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


def case_arrays(case: SysidCase, key: str) -> dict[str, np.ndarray]:
    """Arrays of one case for the figures: the first trial's signals, the fits and the model."""
    r = case.records[0]
    f, g = case.fit, case.fit_c
    return {
        f"{key}_t": r.time, f"{key}_x": r.position, f"{key}_F": r.force,
        f"{key}_fit": np.array([f.mass, f.damping]),
        f"{key}_ci": np.array([f.mass_ci, f.damping_ci]),
        f"{key}_fit_c": np.array([g.mass, g.damping, case.c_identified]),
        f"{key}_model": np.array([case.lam_model, case.phi_model, case.c_model]),
        f"{key}_lam_vp": np.array(case.lam_vp),
        f"{key}_forces": case.forces, f"{key}_q_point": case.q_point,
    }


def fit_rows(case: SysidCase, where: str, thesis_m: float | None, thesis_phi: float | None,
             m_note: str) -> list[Row]:
    """The rows of one case: identified M_x, Φ, c beside eq. 3.13, the reflected friction and k (`SysidCase`)."""
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
        Row(f"c identified, {where}", None, case.c_identified, "N",
            f"{ci(g.offset_ci)}; model (Coulomb joint friction reflected along u): {case.c_model:.4f} N"),
        Row(f"velocity-product (Coriolis, centrifugal) force / push force k in the window, {where}", None,
            case.vp_share, "", "what eqs. 3.24/6.22 omit (signed)"),
        Row(f"Λ/(1 − k): eq. 3.13 with the omitted velocity-product force, {where}", thesis_m, case.lam_vp, "kg",
            f"identified − this: {100 * (f.mass / case.lam_vp - 1):+.1f} %"),
        Row(f"fit R² (eq. 3.24), {where}", None, f.r_squared, "", f"{f.n_samples} samples, {f.n_trials} trials, "
            f"residual RMS {f.residual_rms:.3g} N"),
    ]
