"""Chapter 7: actuator saturation compensation.

The static Fig. 7.1 example and Fig. 7.5 map (`rhi.experiments.ch7.capability`) and the
§7.5 palpation of a stiff wall on the simulated rhi4 (`rhi.experiments.ch7.contact`).
"""

from rhi.experiments.ch7.capability import deficiency_map, example_3dof
from rhi.experiments.ch7.contact import palpation

__all__ = ["deficiency_map", "example_3dof", "palpation"]
