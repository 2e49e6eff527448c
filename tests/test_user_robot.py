"""Your robot everywhere: a user URDF through `rhi measure`, `render`, `run --link sim`, `device-server` and a TOML file."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest
from conftest import arm3_urdf, child_env, free_udp_port

import rhi
from rhi.cli import main
from rhi.devices._urdf import fill_inertia
from rhi.devices.loaders import available_descriptions
from rhi.devices.source import device_from_table
from rhi.errors import InvalidInput, ModelError
from rhi.runtime.config import load_config
from rhi.sim import Log

Q = "0.3,0.8,0.6"
OPTS = ["--ee-frame", "tip", "--task", "xy", "--inertia", "fill", "--damping", "0.01"]
CONFIG = """description = "a user's 3R arm rendering a wall"
[run]
rate = 1000.0
{device}
[controller]
damping = 0.5
[controller.primary]
law = "force_rendering"
damping = 0.01
[[controller.objectives]]
type = "manipulability"
gain = 1.0
[[virtual]]
type = "wall"
point = [0.55, 0.30]
normal = [0.0, 1.0]
stiffness = 500.0
[sim]
q0 = [0.3, 0.8, 0.6]
"""
DEVICE = """[device]
urdf = "arm3.urdf"
ee_frame = "tip"
task = "xy"
inertia = "fill"
friction = { damping = 0.01 }
"""


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    folder = tmp_path_factory.mktemp("arm")
    path = folder / "arm3.urdf"
    path.write_text(arm3_urdf())  # the tip a point mass, as exported URDFs often have
    (folder / "bare.toml").write_text(CONFIG.format(device=""))
    (folder / "arm3.toml").write_text(CONFIG.format(device=DEVICE))
    return path


def test_point_mass_refused_unless_filled_with_a_warning(arm):
    with pytest.raises(ModelError, match=r"link 'tip' <inertia>: a point mass .*inertia=\"fill\""):
        rhi.device_from_urdf(arm, ee_frame="tip", task="xy")
    with pytest.warns(UserWarning, match=r"point-mass links .* tip \(0\.000105 kg m²\)"):
        dev = rhi.device_from_urdf(arm, ee_frame="tip", task="xy", inertia="fill")
    # the filled moment is a 0.2 kg solid sphere of water: r = (3 m / 4 π ρ)^(1/3), I = 2/5 m r²
    r = (3 * 0.2 / (4 * np.pi * 1000.0)) ** (1 / 3)
    assert fill_inertia(0.2) == pytest.approx(0.4 * 0.2 * r * r, rel=1e-12)
    inertia = dev.model.inertias[dev.model.getJointId("j3")].inertia
    np.testing.assert_allclose(np.diag(inertia), fill_inertia(0.2), rtol=1e-12)
    with pytest.raises(InvalidInput, match="inertia"):
        rhi.device_from_urdf(arm, ee_frame="tip", inertia="guess")


def test_measure_and_render_a_user_urdf(arm, tmp_path, capsys):
    assert main(["measure", "--urdf", str(arm), *OPTS, "--q", Q, "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dev = rhi.device_from_urdf(arm, ee_frame="tip", task="xy", inertia="fill")
    assert res["device"] == "arm3"
    np.testing.assert_allclose(res["J"], dev.jacobian([0.3, 0.8, 0.6]), rtol=1e-12)
    os.environ.setdefault("MUJOCO_GL", "osmesa")
    png = tmp_path / "arm.png"
    assert main(["render", "--urdf", str(arm), *OPTS, "--q", Q, "-o", str(png), "--width", "64", "--height", "48"]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_a_user_urdf_from_flags_and_from_a_toml(arm, tmp_path):
    log1, log2 = tmp_path / "flags.rhilog", tmp_path / "toml.rhilog"
    assert main(["run", "--urdf", str(arm), *OPTS, "--config", str(arm.parent / "bare.toml"), "--link", "sim",
                 "--duration", "0.2", "--fast", "--log", str(log1)]) == 0
    assert main(["run", "--config", str(arm.parent / "arm3.toml"), "--link", "sim", "--duration", "0.2", "--fast",
                 "--log", str(log2)]) == 0  # the device comes from the file ([device] urdf, relative path)
    a, b = Log.load(log1), Log.load(log2)
    assert len(a) == len(b) == 200 and a.fault is None and a.meta["device"] == "arm3"
    np.testing.assert_array_equal(a.tau, b.tau)  # the same robot either way
    assert np.abs(a.q[-1] - a.q[0]).max() > 0 or np.abs(a.tau).max() > 0
    # the configuration's [device] and a device on the command line: refused
    assert main(["run", "--urdf", str(arm), *OPTS, "--config", str(arm.parent / "arm3.toml"), "--link", "sim",
                 "--duration", "0.1", "--fast", "--log", str(tmp_path / "x.rhilog")]) == 2


def test_device_server_serves_a_user_urdf_to_rhi_run(arm, tmp_path):
    """`rhi device-server --urdf` in its own process, `rhi run --urdf --link udp://` against it (lock step)."""
    port = free_udp_port()
    server = subprocess.Popen([sys.executable, "-m", "rhi", "device-server", "--urdf", str(arm), *OPTS, "--config",
                               str(arm.parent / "bare.toml"), "--port",
                               str(port), "--lockstep", "--watchdog-ms", "2000", "--duration", "5"],  # a loaded machine
                              env=child_env(), stdout=subprocess.PIPE, text=True)
    try:
        assert "arm3 (simulated" in server.stdout.readline()  # listening
        log = tmp_path / "udp.rhilog"
        assert main(["run", "--urdf", str(arm), *OPTS, "--config", str(arm.parent / "bare.toml"), "--link",
                     f"udp://127.0.0.1:{port}", "--duration", "0.2", "--fast", "--log", str(log)]) == 0
    finally:
        server.terminate()
        server.wait(10)
    run = Log.load(log)
    assert len(run) == 200 and run.fault is None and np.all(np.isfinite(run.tau))


def test_device_table_and_flag_errors_name_the_key(arm, tmp_path, capsys):
    cfg = load_config(arm.parent / "arm3.toml")
    assert cfg.device.name == "arm3" and cfg.device.n == 3 and cfg.device.task_axes == "xy"
    for table, key in (({"urdf": str(arm)}, "device.ee_frame"), ({"urdf": str(arm), "mjcf": "x"}, "device"),
                       ({"name": "rhi4", "ee_frame": "x"}, "device.ee_frame"), ({"urdf": "none.urdf", "ee_frame": "a"},
                                                                                "device.urdf"),
                       ({"mjcf": str(arm), "ee_frame": "tip", "inertia": "fill"}, "device.inertia"),
                       ({"urdf": str(arm), "ee_frame": "nope", "inertia": "fill"}, "device.ee_frame"),
                       ({"urdf": str(arm), "ee_frame": "tip", "colour": 1}, "device.colour")):
        with pytest.raises(rhi.errors.RhiError, match=f"^{key}"):
            device_from_table(table)
    bad = tmp_path / "bad.toml"
    bad.write_text(CONFIG.format(device=DEVICE.replace('task = "xy"', "task = 3")))
    with pytest.raises(InvalidInput, match="device.task"):
        load_config(bad)
    assert main(["measure", "--urdf", str(arm), "--ee-frame", "nope", "--inertia", "fill", "--q", Q]) == 2
    assert "--ee-frame: no link or frame named 'nope'" in capsys.readouterr().err
    assert main(["measure", "rhi4", "--lock", "j1=0", "--q", Q]) == 2
    assert "--lock: an option of --urdf" in capsys.readouterr().err


def test_devices_lists_the_installed_descriptions(capsys):
    if "so_arm_description/urdf/so101.urdf" not in available_descriptions():
        pytest.skip("example-robot-data is not installed")
    assert main(["devices", "--descriptions"]) == 0
    names = [line.split()[0] for line in capsys.readouterr().out.splitlines()]
    assert "panda" in names and "so_arm_description/urdf/so101.urdf" in names
    # each name loads as --description (SO-101's gripper frame is a point mass: fill)
    assert main(["measure", "--description", "so_arm_description/urdf/so101.urdf", "--ee-frame", "gripper_frame_link",
                 "--inertia", "fill", "--q", "0,0.5,0.5,0.2,0", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["device"] == "so101"
