"""Fig. 6.6: the actuator saturation observer V of eq. 6.14 for the thesis's two-DoF example (S = 50).

The thesis draws V over the torque box of a two-DoF robot with |T1| ≤ 0.5 N m and |T2| ≤ 2 N m and
states that V "spans the [0, 1] interval": 1 with both torques at the middle of their ranges, 0 when
one or more actuators saturate. We evaluate `rhi.control.transition.aso_volume` (the kernel the
controllers use) on a grid over and slightly beyond the box.
"""

from __future__ import annotations

import numpy as np

from rhi import thesis as T
from rhi.control.transition import aso_volume
from rhi.experiments.arguments import checked
from rhi.experiments.result import Result, Row, Table

#: Fig. 6.6: the torque bounds [N m] and the shape factor S.
LIMITS = np.array([0.5, 2.0])
S_6_6 = 50.0


@checked
def aso_example(resolution: int = 81) -> Result:
    """Fig. 6.6: V(τ1, τ2) over the torque box (and 10 % beyond it) of the thesis's two-DoF example."""
    t1 = np.linspace(-1.1, 1.1, resolution) * LIMITS[0]
    t2 = np.linspace(-1.1, 1.1, resolution) * LIMITS[1]
    V = np.array([[aso_volume(np.array([a, b]), torque_min=-LIMITS, torque_max=LIMITS, S=S_6_6) for a in t1]
                  for b in t2])
    inside = (np.abs(t1)[None, :] < LIMITS[0]) & (np.abs(t2)[:, None] < LIMITS[1])
    edge = [aso_volume(np.array(p), torque_min=-LIMITS, torque_max=LIMITS, S=S_6_6)
            for p in ((0.5, 0.0), (-0.5, 1.0), (0.2, 2.0), (0.0, -2.0))]
    v0 = aso_volume(np.zeros(2), torque_min=-LIMITS, torque_max=LIMITS, S=S_6_6)
    span = float(abs(v0 - 1.0) < 1e-12 and max(edge) == 0.0 and V.min() >= 0.0 and V.max() <= 1.0 + 1e-12
                 and bool(np.all(V[~inside] == 0.0)))
    half = aso_volume(LIMITS / 2, torque_min=-LIMITS, torque_max=LIMITS, S=S_6_6)
    rows = [
        Row("V spans [0, 1]: 1 at zero torque, 0 on and beyond the box (1 = yes)", T.ASO_SPAN_6_6, span, ""),
        Row("V at τ = 0", None, v0, ""),
        Row("max V on the box's edges", None, float(max(edge)), ""),
        Row("min V inside the box", None, float(V[inside].min()), ""),
        Row("V at half of both limits (τ = [0.25, 1] N m)", None, half, ""),
        Row("fraction of the box where V > 0.7 (ε₁ of §6.4)", None, float(np.mean(V[inside] > 0.7)), ""),
    ]
    return Result("ch6.aso_example", "Fig. 6.6: the ASO of eq. 6.14 for a two-DoF robot with S = 50",
                  [Table("Fig. 6.6 (|T1| ≤ 0.5 N m, |T2| ≤ 2 N m, S = 50)", rows)],
                  {"tau1": t1, "tau2": t2, "V": V},
                  ["V is evaluated by the controllers' own kernel (rhi.control.transition.aso_volume); the test "
                   "compares it with eq. 6.14 transcribed in NumPy."])
