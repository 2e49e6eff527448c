"""The `rhi` command."""

import json

from rhi.cli import main


def test_devices_and_measure(capsys):
    assert main(["devices"]) == 0
    assert "rhi4" in capsys.readouterr().out
    assert main(["measure", "rhi4", "--q", "0.125,0.022,0.298,0.175", "--u", "0,1", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert abs(res["effective_manipulability ρ (3.6)"] - 0.3752) < 5e-4  # Table 3.1, RHI at (0.49, -0.22)


def test_experiment_writes_figures_and_numbers(tmp_path, capsys):
    assert main(["experiment", "--list"]) == 0
    assert "ch7.example_3dof" in capsys.readouterr().out.split()
    assert main(["experiment", "ch7.example_3dof", "--quick", "--out", str(tmp_path), "--executor", "serial"]) == 0
    out = capsys.readouterr().out
    assert "thesis" in out and "rhi" in out
    data = json.loads((tmp_path / "results.json").read_text())
    assert any(r["name"] == "ch7.example_3dof" for r in data["results"])
    assert list((tmp_path / "figures").glob("*.png")) and list((tmp_path / "tables").glob("*.csv"))


def test_bad_input_exits_2(capsys):
    assert main(["measure", "nosuchdevice", "--q", "0"]) == 2
    assert "unknown device" in capsys.readouterr().err
    assert main(["experiment", "ch9.nothing", "--out", "/tmp/rhi-none"]) == 2
    assert "experiment" in capsys.readouterr().err
