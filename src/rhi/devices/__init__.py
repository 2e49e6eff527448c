"""The device layer: the `Device` model object, its kinematics and dynamics terms, loaders and measures.

`rhi.devices.model` holds `Device` and `device` (re-exported as ``rhi.Device`` and ``rhi.device``);
`rhi.devices.spec` is the one reader of a bundled device's ``device.toml``; `rhi.devices.terms` and
`rhi.devices.ik` the per-state terms and the inverse kinematics; `rhi.devices.batch` batched kinematics;
`rhi.devices.loaders` devices from URDF, MJCF or description packages; `rhi.devices.measures` every measure
of a device at once; `rhi.devices.mobile_base` the mobile base. The compiled kernels behind `Device.terms`
and the batch are private (`rhi.devices._compiled`).

The package is ``devices``, not ``device``: ``rhi.device`` is the function ``rhi.device("rhi4")``, and a
package of that name would be shadowed by it (``import rhi.device.x as y`` and ``mock.patch("rhi.device.x")``
would reach the function).
"""

from rhi.devices.loaders import description_path, device_from_description, device_from_mjcf, device_from_urdf
from rhi.devices.measures import all_measures
from rhi.devices.model import Device, available_devices, device

__all__ = [
    "Device",
    "all_measures",
    "available_devices",
    "description_path",
    "device",
    "device_from_description",
    "device_from_mjcf",
    "device_from_urdf",
]
