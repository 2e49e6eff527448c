"""The `rhi` command."""

import json

from conftest import child_env

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


def test_python_m_rhi_and_version():
    import subprocess
    import sys

    import rhi

    env = child_env()
    res = subprocess.run([sys.executable, "-m", "rhi", "--version"], capture_output=True, text=True, env=env, check=True)
    assert res.stdout.strip() == f"rhi {rhi.__version__}"


def test_negative_numbers_and_singular_configuration(capsys):
    assert main(["measure", "rhi4", "--q", "-0.5,0.2,0.3,0.1", "--u", "-1,0", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["q"][0] == -0.5 and res["u"] == [-1.0, 0.0] and res["singular"] is False
    assert main(["measure", "gen3", "--q", "0,0,0,0,0,0,0", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["singular"] is True and res["rank J"] < 3
    assert res["manipulability μ (4.7)"] < 1e-12 and res["apparent_inertia M_x [kg] (3.12)"] is None
    assert "max_force (LP, dynamic projector) [N]" in res["undefined (singular J)"]


def test_experiment_report_names_default_out_and_piped_progress(tmp_path, monkeypatch, capsys):
    from rhi.report.reproduce import STEPS, step_names

    for name, step in [("ch3.psychophysics", "ch3.psychophysics"), ("full_design", "ch4.full_design"),
                       ("ch4.theta_z_design", "ch4.theta_z_design"), ("ch7.palpation", "ch7.palpation"),
                       ("sysid_table_6_1", "ch6.sysid_table_6_1"), ("beyond.passivity", "beyond.passivity")]:
        assert [s.name for s in STEPS if name in step_names(s)] == [step]
    # an experiment's id is the chapter module or package that defines it and its function
    for s in STEPS:
        assert s.run.__module__.startswith(f"rhi.experiments.{s.chapter}") and s.name == f"{s.chapter}.{s.run.__name__}"
    monkeypatch.chdir(tmp_path)
    assert main(["experiment", "ch7.example_3dof", "--quick", "--executor", "serial"]) == 0
    assert (tmp_path / "out" / "ch7.example_3dof" / "results.json").is_file()
    assert not (tmp_path / "out" / "report.html").exists()
    assert "[1/1] ch7.example_3dof done in" in capsys.readouterr().out  # stdout is not a terminal here


def test_cli_bad_inputs_exit_2_naming_the_argument(capsys):
    import pytest

    cases = [
        (["measure", "rhi4", "--q", "1,2"], "q: expected shape"),
        (["measure", "rhi4", "--q", "0,0,0,0", "--u", "0,0"], "u: zero-length"),
        (["measure", "rhi4", "--q", "0,0,0,0", "--param", "d9=0.1"], "params: unknown parameter"),
        (["measure", "rhi4", "--q", "0,0,0,0", "--param", "d2=-1"], "d2: -1.0 outside"),
        (["reproduce", "--only", "ch99"], "only: unknown chapter"),
    ]
    for argv, message in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, (argv, err)
    for argv, option in [(["measure", "rhi4", "--q", "abc"], "--q"), (["measure", "rhi4", "--q", "1j,0,0,0"], "--q"),
                         (["measure", "rhi4", "--q", "0,0,0,0", "--param", "d2=abc"], "--param"),
                         (["measure", "rhi4", "--q", "nan,0,0,0"], "--q"),
                         (["reproduce", "--only", "ch3", "--workers", "0"], "--workers")]:
        with pytest.raises(SystemExit) as exc:  # argparse's own usage error
            main(argv)
        assert exc.value.code == 2 and f"argument {option}" in capsys.readouterr().err
