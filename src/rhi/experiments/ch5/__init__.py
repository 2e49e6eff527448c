"""Chapter 5: null-space control of the redundant HI for teleoperation manipulability (thesis §5.3–5.4.1).

Set-up (thesis §5.4): master rhi4 with d = [0.254, 0.1405, 0.21, 0.181] m and the §5.4
joint limits; slave `rehab_slave` (l = [0.34, 0.375] m, eq. 5.12b); both in one planar
frame (the thesis starts both end-effectors at the same (X, Y), so H = I, no scaling).
Unilateral teleoperation (Fig. 5.2): the slave PD-tracks the master's position
(`rhi.sim.Teleoperation`); the master is an impedance-type device,
F_m = −B^d ẋ + C_x ẋ + G_x with B^d = diag(0.3, 0.3) N s/m (eq. 5.6 with M_x^d = M_x,
`rhi.control.ImpedanceControl`; G_x = 0 in the horizontal plane),
τ = Jᵀ F_m + (I − Jᵀ J#ᵀ)(τ_N − k_D q̇) (eq. 5.9) with τ_N = −α ∂ν/∂q (eq. 5.10).

Plant (MuJoCo): the thesis's simulation leaves, after model-based compensation, only the
uncertainty 𝓕 = J#ᵀ Γ q̇ with Γ = diag(0.01) (eq. 5.13) acting on the user; our plant has
exactly this joint viscous friction Γ and no Coulomb friction (``friction="thesis"``), and
no friction compensation in the controller (what eq. 5.6's F_x leaves uncompensated).
``friction="device"`` uses the rhi4 estimates of models/rhi4/device.toml instead
(uncompensated viscous + Coulomb friction, as in the thesis's experiments, eq. 5.16).

Choices the thesis leaves open (each is ours, fixed before comparing with the thesis):

- **Objective ν (eq. 5.11)** ``TMIMatching``: the JBLD between the slave ME
  ˢM = J_s J_sᵀ and the HI ME ᵐM = J^q J^qᵀ built from the joint-limit-penalised Jacobian
  J^q (eqs. 4.19–4.20), as §5.3 says ("by using the index penalized Jacobian, we will
  prevent the HI from approaching limits"). The slave's ME is not penalised (eq. 5.11
  names it "the ME of the slave robot"; its limits are estimates). The linear
  (parallelogram) limits are not penalised (eq. 4.20 is per joint).
- **k_q = 10** in eq. 4.20 (the thesis gives no value). The stated purpose is a guard
  that keeps the HI off its limits "in addition to enhancing the teleoperation
  manipulability": with k_q = 10, P_i ≥ 0.97 on the central 80 % of every range and
  falls to 0 only near a limit. ch. 4 uses k_q = 1 for its design indices; with k_q = 1,
  P_i ≥ 0.9 only on the central 40 % of a range, the penalty dominates ν and the controller
  barely moves (see `fixed_point`'s variants table: the result depends strongly on k_q).
- **Gains**: α = 1 N m per unit of ν, null-space damping k_D = 0.05 N m s/rad (the
  thesis gives neither; the fixed-point controller settles in a few seconds with them).
- **Yoshikawa scenario (eq. 5.14)**: τ_N = −α ∂ν/∂q with ν = −log μ(J^q)
  (`rhi.control.Manipulability(log=True, k_q=K_Q)`): the same joint-limit guard J^q (same k_q) as scenario 1, which
  §4.3.2 also substitutes into the manipulability (eq. 4.7), so that scenarios 1 and 2 differ
  only in what they optimise; and log μ instead of μ (same maximiser; −log μ is a log-det like
  ν, so one α serves both; the literal α ∂μ/∂q is the same direction scaled by μ ≈ 0.1). The
  literal eq. 5.14 (plain J) is a `fixed_point` variant: it drives q3 into its −55° limit
  within 1.5 s, where the limit turns null-space torque into end-effector force.
- **Simulated user**: a hand holding the handle (fixed point: K = 3000 N/m, B = 40 N s/m)
  or tracking the reference at constant speed (W: K = 300 N/m, B = 10 N s/m, `rhi.sim.Hand`),
  the "internal PD controller" of §5.4.1.
- **W trajectory** (Figs 5.4–5.5, only drawn in the thesis): the letter W, four strokes,
  centred at (0.50, 0.00) m, 0.16 m wide (x) and 0.25 m high (y): path length 1.01 m,
  50.6 s at 2 cm/s (Table 5.1's experimental completion times are 49–62 s). It lies in
  the 2-DoF Rehab's workspace (the narrowest of the three, checked by IK along the path)
  and spans the Rehab's crescent across y ∈ [−0.125, 0.125] m (criteria 1 and 2 of §5.4.1).
  Criterion 3, strokes along the slave ME's major axis, cannot hold along a whole W with our
  slave model: across the crescent that axis turns from radial (inner side) to tangential
  (outer side) and the ME is nearly round in between. We report the alignment (mean |cos|
  between the path and the major axis, weighted by the anisotropy): ≈ 0.62, about what
  random directions give (0.64); a W rotated by 90° does no better (0.57).
- **Start**: each scenario starts from IK at the W's first point (seeded from the §5.4
  configuration), holds there for `settle` seconds so the null-space controller converges,
  then follows the W. Effort and mean TME area are taken over the motion only.
- **"Area" of the TME**: we read the thesis's mean "area" 0.1034 as the TMI λ = σ₁σ₂
  (eq. 4.17): it and the implied 0.122 of scenario 1 have the size of λ for these robots
  (λ ≤ l₁l₂ = 0.1275; ours 0.09–0.12), while π σ₁σ₂ would be 0.27–0.39. We report λ of
  the plain (unpenalised) Jacobians, the ellipses Fig. 5.3 draws; percentages do not
  depend on the factor π.
"""


from rhi.experiments.ch5.fixed import fixed_point
from rhi.experiments.ch5.tracking import w_trajectory, w_trajectory_plan
from rhi.experiments.ch5.workspace import workspaces

__all__ = ["fixed_point", "w_trajectory", "w_trajectory_plan", "workspaces"]
