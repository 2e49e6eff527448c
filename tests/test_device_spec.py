"""`rhi.devices.spec`: the one reader of device.toml, and the plant data a locked device keeps."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import rhi
from rhi.devices.mobile_base import wheel_geometry
from rhi.devices.spec import available_devices, bundled_spec, read_spec
from rhi.errors import ModelError, UnknownDevice
from rhi.sim import device_friction

SRC = Path(rhi.__file__).parent


def test_locked_rhi4_and_phantom_get_the_same_plant_friction():
    """models/phantom is rhi4 with q1 = q2 = 0: both ways of making it carry the [plant] friction of q3, q4."""
    locked = rhi.device("rhi4").lock(q1=0, q2=0)
    phantom = rhi.device("phantom")
    assert locked.joint_names == phantom.joint_names == ["q3", "q4"]
    np.testing.assert_array_equal(locked.damping, [0.01, 0.01])  # models/rhi4/device.toml [plant]
    np.testing.assert_array_equal(locked.frictionloss, [0.005, 0.005])
    for a, b in zip(device_friction(locked).__dict__.values(), device_friction(phantom).__dict__.values()):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(locked.armature, phantom.armature)
    assert phantom.spec is not None and phantom.spec.name == "rhi4"  # the description it was built from


def test_locking_the_base_of_wmm_keeps_the_arm_limits_of_gen3():
    arm = rhi.device("wmm").lock(x_b=0, y_b=0, theta_b=0)
    gen3 = rhi.device("gen3")
    np.testing.assert_array_equal(arm.velocity_max, gen3.velocity_max)
    np.testing.assert_array_equal(arm.acceleration_max, gen3.acceleration_max)
    assert wheel_geometry(arm) == wheel_geometry("wmm")  # the base description stays with the device
    with pytest.raises(ModelError, match="mobile_base"):
        wheel_geometry(gen3)


def test_every_bundled_spec_reads_and_units_are_si():
    for name in available_devices():
        spec = bundled_spec(name)
        assert spec.name == name
    rhi4 = bundled_spec("rhi4")
    np.testing.assert_allclose(rhi4.q_max, np.deg2rad([90, 145, 115, 80]))  # unit = "deg"
    np.testing.assert_allclose(rhi4.linear_limits.upper, np.deg2rad([55, 55]))
    assert rhi4.parameter_bounds == {"d2": (0.05, 0.5)}
    assert bundled_spec("phantom").lock == {"q1": 0.0, "q2": 0.0}
    with pytest.raises(UnknownDevice, match="nope"):
        bundled_spec("nope")


def test_malformed_device_toml_raises_model_error(tmp_path):
    (tmp_path / "device.toml").write_text("name = [")
    with pytest.raises(ModelError, match="cannot read device.toml"):
        read_spec(tmp_path)
    (tmp_path / "device.toml").write_text('name = "x"\nurdf = "x.urdf"\n')  # no ee_frame
    with pytest.raises(ModelError, match="ee_frame"):
        read_spec(tmp_path)


def test_only_the_spec_module_reads_device_toml():
    readers = [p.relative_to(SRC).as_posix() for p in SRC.rglob("*.py")
               if re.search(r"""["']device\.toml["']""", p.read_text(encoding="utf-8"))]
    assert readers == ["devices/spec.py"]
