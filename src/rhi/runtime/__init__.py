"""The runtime: a controller on a device at a fixed rate, behind a safety layer.

`run(link, controller, ...)` paces ticks on the monotonic clock; links are the simulated device
(`SimLink`) and a device process over UDP (`UDPLink`, served by `rhi device-server`, protocol in
docs/protocol.md); `Safety` latches every fault to zero torque with a reason in the log.
"""

from rhi.errors import LinkError
from rhi.runtime.link import DeviceLink, Reading, Status
from rhi.runtime.loop import RunResult, run
from rhi.runtime.safety import Safety, SafetyConfig
from rhi.runtime.simlink import SimLink
from rhi.sim.log import Log
from rhi.sim.telemetry import Telemetry

__all__ = ["DeviceLink", "LinkError", "Log", "Reading", "RunResult", "Safety", "SafetyConfig", "SimLink", "Status",
           "Telemetry", "run"]
