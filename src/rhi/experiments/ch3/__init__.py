"""Chapter 3: intrinsic and null-space advantages of the 4-DoF RHI.

Table 3.1 and Figs 3.6–3.8 (`rhi.experiments.ch3.measures`), the prismatic example of eqs. 3.16–3.19
(`rhi.experiments.ch3.prismatic`), the null-space VME-matching
controller on the simulated rhi4 (`rhi.experiments.ch3.nullspace`), the identification of
Table 3.2 (`rhi.experiments.ch3.identification`) and the virtual psychophysics of Table 3.3
(`rhi.experiments.ch3.discrimination`).
"""

from rhi.experiments.ch3.discrimination import psychophysics
from rhi.experiments.ch3.identification import sysid_table_3_2
from rhi.experiments.ch3.measures import ratio_maps, table_3_1
from rhi.experiments.ch3.nullspace import nullspace_configurations
from rhi.experiments.ch3.prismatic import apparent_inertia_example

__all__ = ["apparent_inertia_example", "nullspace_configurations", "psychophysics", "ratio_maps", "sysid_table_3_2", "table_3_1"]
