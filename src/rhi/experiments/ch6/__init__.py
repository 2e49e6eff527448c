"""Chapter 6: dynamic reconfiguration of a redundant haptic interface for soft and hard contacts.

Thesis §6.3–6.4: the 3-DoF example (Figs 6.3–6.4), palpation of a 1000 N/m spring with
the configuration set by FME matching to M_Free^des vs M_Stiff^des (Fig. 6.9, Table 6.1),
the ASO of the two-DoF example (Fig. 6.6), the F_max ratio map (Fig. 6.10) and the ASO-driven transition between the desired FMEs
with and without the cosine blend (Fig. 6.11).

Set-up and the choices the thesis leaves open (each fixed before comparing with the thesis):

- **Desired FMEs** (eqs. 6.11–6.13): 𝒦 = μ λ_max(M̂₀), ζ = λ_min(M̂₀)/μ with μ = 5 from the
  torque-weighted FME at the home configuration (rhi4: q = 0 gives 𝒦 = 123.0, ζ = 3.34;
  the 3-DoF example: its initial configuration, 𝒦 = 5 × 5.79, ζ = 2.58/5). M_Free^des has
  its minor axis ζ along the motion u, M_Stiff^des its major axis 𝒦 along the contact force.
- **Configuration reached by FME matching** (`match_fme`): where the controller's null-space
  flow (eqs. 6.3–6.6 with the handle held) settles from a start configuration, sliding along
  the joint limits it meets (`rhi.control.configuration.null_space_descent`; SLSQP alone could
  jump to a minimum in another basin, which the controller never reaches). For the
  3-DoF example the start is the thesis's initial configuration (the null-space controller
  converges from there with the end-effector held). On rhi4 the start is the IK solution
  from the home configuration q = 0 plus `starts − 1` seeded configurations, and the best
  match is kept, so every grid point of the map is computed independently.
- **Joint limits on rhi4** (§5.4 limits, `models/rhi4`): every unconstrained FME-matching
  optimum at X₀ lies outside them (M_Free^des: q4 > 80°; M_Stiff^des: q4 < −20° and
  q1 − q2 < −55°), so the matching is constrained. The thesis's controller (eq. 6.6) knows no
  limits; driven against the plant's limit stops its null-space torque no longer stays in
  the null space (the stop's reaction force is not in it) and pushes the handle with up to
  ~12 N in free space. The simulated controller therefore adds a joint-limit barrier to the
  null-space cost (`BARRIER`, a quadratic `rhi.control.JointLimitBarrier`: ½ Σ max(0, δ − d)² over the distances d to every box
  and linear limit, δ = 0.1 rad, gain 100 N m/rad), and the static optimum minimises the
  same sum ν_FME + (100/β) ν_lim, so simulation and statics describe one configuration.
- **Palpation** (§6.4, eq. 6.21, K_e = 1000 N/m from X₀ = [0.5, 0.1] m along u = [0, 1]):
  the MuJoCo plant (motor friction of `models/rhi4/device.toml [plant]`) starts at the
  FME-matched configuration; a hand holds X₀ while the null-space controller (β = 20,
  K_d = 0.1, dynamically consistent J#) keeps the match, then pushes in along u at constant
  speed. (Started from the IK configuration instead, the controller settles within 0.01 rad
  of the static optimum in about 1 s.) The primary law is the spring alone (eq. 6.21: no
  damping, no Coriolis/gravity terms); saturation is handled by simple force scaling
  (§6.3.1: "a scaling factor α ... as soon as one of the RHI's actuators is saturated"),
  not by ASCM (chapter 7). The rendered force is read on the
  handle's F/T sensor, as in Fig. 6.9.
- **Transition** (eqs. 6.14–6.19, ε₁ = 0.7, ε₂ = 0.95, ρ = 0.003, S = 50): the same palpation
  with `FMESchedule`, pushing in, holding, and releasing. "Without the method" is eq. 6.15
  as written: one threshold ε = ε₁ and an instantaneous switch of M_des (ρ = 0).

Why our numbers differ from the thesis's:

- Kinematics, torque limits and 𝒦, ζ are the thesis's, so FME shapes and static F_max
  depend only on which configuration the matching reaches. The thesis does not report its
  configurations; ours respect the §5.4 joint limits, which bind at X₀ for both FMEs.
- Table 6.1's F_max was measured on the hardware (with its friction, compliance, sensor
  filtering and a human hand); ours is a simulated hand on a plant whose inertias and
  friction are partly estimates (`models/rhi4/README.md`).
- Table 6.1's M_x and Φ come from a system-identification experiment on the hardware; we
  report our model's effective inertia Λ = (uᵀ J M⁻¹ Jᵀ u)⁻¹ (eq. 3.13) and the quasi-static
  viscous friction our plant reflects along u at the same configurations, beside them.
- Fig. 6.11: the thesis's β = 20 makes the null-space torque saturate the actuators during
  a reconfiguration. `transition` runs the §6.4 law as written, each joint clipped at its
  programmed limit (the literal reading; with it the method lowers the handle disturbance), and
  chapter 7's Algorithm 2 (τ_S scaled into the box) beside it (see `transition`).
- Fig. 6.10: the thesis shows the map without its configurations or numbers; where the
  joint limits leave little self-motion the two matched configurations nearly coincide and
  the ratio is close to 1 (our minimum is slightly below 1).
"""

from rhi.experiments.ch6.capability import fmax_ratio_map
from rhi.experiments.ch6.contact import palpation
from rhi.experiments.ch6.example import example_3dof
from rhi.experiments.ch6.identification import sysid_table_6_1
from rhi.experiments.ch6.observer import aso_example
from rhi.experiments.ch6.switching import transition

__all__ = ["aso_example", "example_3dof", "fmax_ratio_map", "palpation", "sysid_table_6_1", "transition"]
