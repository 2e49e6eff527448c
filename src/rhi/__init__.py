"""rhi: redundant haptic interfaces — models, measures, design, control, simulation, analysis.

Quick start::

    import rhi
    dev = rhi.device("rhi4")
    J = dev.jacobian([0.125, 0.022, 0.298, 0.175])
    rhi.metrics.effective_manipulability(J, [0, 1])   # 0.375 (thesis Table 3.1: 0.371)
"""

from rhi._gl import headless_default

headless_default()  # before anything imports MuJoCo (see rhi._gl)

from rhi import devices, errors, metrics  # noqa: E402
from rhi.devices import *  # noqa: E402, F403  (the device layer's names: rhi.device, rhi.Device, rhi.all_measures, ...)

__all__ = ["errors", "metrics"]
__all__ += devices.__all__
__version__ = "0.1.0"
