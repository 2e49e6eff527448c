"""Plugins by entry points: a lab's package adds a link (URL scheme), an objective (TOML type) and a device (name).

The package is installed the way pip leaves one: its module and a ``.dist-info`` with ``entry_points.txt``
in a folder on the path, which `importlib.metadata` reads (this process: sys.path; a child: PYTHONPATH).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from conftest import arm3_urdf, child_env

import rhi
from rhi import plugins
from rhi.cli import main
from rhi.errors import InvalidInput, UnknownDevice
from rhi.plugins import PluginError
from rhi.runtime.config import load_config
from rhi.sim import Log

PLUGIN = '''"""A lab's rhi plugin: its arm, a centring objective and a counting link over the simulated device."""

import numpy as np

import rhi

ARM = """@ARM@"""


def lab_arm(l1=0.3):
    return rhi.device_from_urdf(ARM.replace("L1", repr(float(l1))), ee_frame="tip", task="xy", name="labarm")


class Centering:
    """nu(q) = 1/2 w |q - center|^2."""

    def __init__(self, device, center, weight=1.0):
        self.center, self.weight = np.asarray(center, dtype=float), float(weight)
        if self.center.shape != (device.n,):
            raise ValueError(f"center: expected {device.n} values, got {center!r}")

    def value(self, device, q):
        d = np.asarray(q) - self.center
        return 0.5 * self.weight * float(d @ d)

    def gradient(self, device, q):
        return self.weight * (np.asarray(q) - self.center)


class FrameNearBase:
    """nu(q) = 1/2 w |p_frame(q)|^2, the frame looked up by name when it runs (as plugins do)."""

    def __init__(self, device, frame, weight=1.0):
        self.frame, self.weight = frame, float(weight)

    def value(self, device, q):
        import pinocchio as pin

        data = device.model.createData()  # this arm has no locked joints: its model's q is the motors' q
        pin.framesForwardKinematics(device.model, data, np.asarray(q, dtype=float))
        p = data.oMf[device.model.getFrameId(self.frame)].translation
        return 0.5 * self.weight * float(p @ p)

    def gradient(self, device, q):
        return np.array([(self.value(device, q + h) - self.value(device, q - h)) / 2e-6 for h in 1e-6 * np.eye(len(q))])


class CountingLink:
    def __init__(self, link):
        self._link, self.stats = link, {"reads": 0, "writes": 0}

    def __getattr__(self, name):
        return getattr(self._link, name)

    def open(self):
        self._link.open()

    def read(self):
        self.stats["reads"] += 1
        return self._link.read()

    def write(self, tau, *, enable):
        self.stats["writes"] += 1
        self._link.write(tau, enable=enable)

    def close(self):
        self._link.close()


def open_link(url, *, rate, config, realtime):
    if url != "lab://sim":
        raise rhi.errors.InvalidInput(f"expected lab://sim, got {url!r}")
    return CountingLink(config.sim_link(rate=rate))
'''
PLUGIN = PLUGIN.replace("@ARM@", arm3_urdf("labarm", l1="L1", tip_com=0.05, tip_inertia=2e-3))
ENTRY_POINTS = """[rhi.devices]
labarm = rhi_labkit:lab_arm
brokenarm = rhi_labkit_missing:arm

[rhi.objectives]
centering = rhi_labkit:Centering
near_base = rhi_labkit:FrameNearBase

[rhi.links]
lab = rhi_labkit:open_link
"""
CONFIG = """description = "the lab's arm, centred, over the lab's link"
[device]
name = "labarm"
params = {{ l1 = 0.3 }}
[controller]
damping = 0.5
[controller.primary]
law = "force_rendering"
damping = 0.01
[[controller.objectives]]
type = "centering"
center = [0.3, 0.8, 0.6]
{extra}gain = 2.0
[sim]
q0 = [0.1, 0.9, 0.4]
"""


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The plugin package in a site folder on sys.path (and PYTHONPATH for children), removed afterwards."""
    site = tmp_path_factory.mktemp("site")
    (site / "rhi_labkit.py").write_text(PLUGIN)
    info = site / "rhi_labkit-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: rhi-labkit\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    (site / "lab.toml").write_text(CONFIG.format(extra=""))
    sys.path.insert(0, str(site))
    try:
        yield site
    finally:
        sys.path.remove(str(site))
        sys.modules.pop("rhi_labkit", None)


def test_the_plugins_are_found(installed):
    assert plugins.names("rhi.devices") == ["brokenarm", "labarm"]
    assert plugins.names("rhi.objectives") == ["centering", "near_base"] and plugins.names("rhi.links") == ["lab"]
    assert plugins.provider("rhi.links", "lab") == "rhi-labkit 0.1"
    dev = rhi.device("labarm", l1=0.35)
    np.testing.assert_allclose(dev.fk([0.0, 0.0, 0.0]), [0.6, 0.0], atol=1e-12)  # l1 + 0.25 m along x
    with pytest.raises(PluginError, match=r"plugin 'brokenarm' .*rhi_labkit_missing.*ModuleNotFoundError"):
        rhi.device("brokenarm")
    with pytest.raises(InvalidInput, match=r"params: device plugin 'labarm'.*'l9'"):
        rhi.device("labarm", l9=1.0)
    with pytest.raises(UnknownDevice, match="unknown device 'nonesuch'"):
        rhi.device("nonesuch")


def test_device_objective_and_link_from_the_cli_and_a_toml(installed, tmp_path, capsys):
    assert main(["measure", "labarm", "--q", "0.3,0.8,0.6", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["device"] == "labarm"
    cfg = load_config(installed / "lab.toml")
    obj = cfg.controller_config.objectives[0].objective
    assert type(obj).__name__ == "Centering" and obj.weight == 1.0
    np.testing.assert_array_equal(obj.center, [0.3, 0.8, 0.6])
    log, summary = tmp_path / "lab.rhilog", tmp_path / "summary.json"
    assert main(["run", "labarm", "--config", str(installed / "lab.toml"), "--link", "lab://sim", "--duration", "0.3",
                 "--fast", "--log", str(log), "--summary", str(summary)]) == 0
    s = json.loads(summary.read_text())
    assert s["link_stats"]["reads"] >= 300 and s["link_stats"]["writes"] >= 300  # the plugin's link ran the loop
    run = Log.load(log)
    assert len(run) == 300 and run.fault is None
    # the centring objective moves the joints toward its center in the null space (0.300 -> 0.268 rad), the
    # handle held (no hand, no environment: the primary task only damps it)
    d = np.linalg.norm(run.q - obj.center, axis=1)
    assert np.all(np.diff(d) < 0) and d[-1] < d[0] - 0.02
    assert np.abs(run.x[-1] - run.x[0]).max() < 1e-3


def test_plugin_errors_name_the_key_and_scheme(installed, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    for extra, msg in (("colour = 1\n", "controller.objectives[0].colour: unknown key"),
                       ("center = [1.0]\n", "controller.objectives[0]: objective plugin 'centering' refused its "
                                            "parameters: center: expected 3 values")):
        text = CONFIG.format(extra=extra)
        if extra.startswith("center"):
            text = text.replace("center = [0.3, 0.8, 0.6]\n", "")
        bad.write_text(text)
        with pytest.raises(InvalidInput) as exc:
            load_config(bad)
        assert msg in str(exc.value)
    bad.write_text(CONFIG.format(extra="").replace("center = [0.3, 0.8, 0.6]\n", ""))
    with pytest.raises(InvalidInput, match=r"controller.objectives\[0\].center: missing"):
        load_config(bad)
    assert main(["run", "labarm", "--config", str(installed / "lab.toml"), "--link", "nolab://x", "--fast",
                 "--duration", "0.1", "--log", str(tmp_path / "x.rhilog")]) == 2
    assert "or a plugin scheme (lab://)" in capsys.readouterr().err
    assert main(["run", "labarm", "--config", str(installed / "lab.toml"), "--link", "lab://elsewhere", "--fast",
                 "--duration", "0.1", "--log", str(tmp_path / "y.rhilog")]) == 2
    assert "--link: expected lab://sim" in capsys.readouterr().err


def test_a_misspelt_frame_in_an_objective_is_found_when_the_file_is_read(installed, tmp_path, capsys):
    """A plugin looks its frame up only when it runs: load_config evaluates each objective at sim.q0."""
    text = CONFIG.format(extra="").replace('type = "centering"\ncenter = [0.3, 0.8, 0.6]', 'type = "near_base"\n'
                                           'frame = "FRAME"')
    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    good.write_text(text.replace("FRAME", "tip"))
    bad.write_text(text.replace("FRAME", "tipp"))
    assert load_config(good).controller_config.objectives[0].objective.frame == "tip"
    with pytest.raises(InvalidInput, match=r"^controller.objectives\[0\]: the objective fails at sim.q0"):
        load_config(bad)
    log = tmp_path / "bad.rhilog"
    assert main(["run", "labarm", "--config", str(bad), "--fast", "--duration", "0.1", "--log", str(log)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "controller.objectives[0]" in err[0] and not log.exists()  # no run started


def test_another_process_finds_the_installed_plugin(installed):
    out = subprocess.run([sys.executable, "-m", "rhi", "devices"], env=child_env(installed), capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    line = next(ln for ln in out.stdout.splitlines() if ln.startswith("labarm"))
    assert line.split()[1:3] == ["3", "xy"] and "plugin: rhi-labkit 0.1" in line
