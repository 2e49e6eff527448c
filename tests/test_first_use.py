"""First use: help pages with a description and an example, experiment list, rhi[all], the cold-cache line, warmup."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import child_env

from rhi import cli_help, jit
from rhi.cli import main
from rhi.report.steps import experiments

ROOT = Path(__file__).resolve().parents[1]


def _parser():
    """The `rhi` parser as `main` builds it (caught at parse time through --help's exit)."""
    import argparse

    seen = {}
    real = argparse.ArgumentParser.parse_args

    def grab(self, *a, **kw):
        seen.setdefault("p", self)
        raise SystemExit(0)

    argparse.ArgumentParser.parse_args = grab
    try:
        with pytest.raises(SystemExit):
            main(["devices"])
    finally:
        argparse.ArgumentParser.parse_args = real
    return seen["p"]


def test_every_subcommand_help_has_a_description_and_an_example(capsys):
    commands = cli_help.subcommands(_parser())
    assert {"run", "measure", "log export", "warmup", "devices"} <= {c for c, _ in commands}
    for path, _ in commands:
        with pytest.raises(SystemExit) as exc:
            main([*path.split(), "--help"])
        assert exc.value.code == 0
        text = capsys.readouterr().out
        usage, _, rest = text.partition("\n\n")
        assert rest.strip() and not rest.lstrip().startswith(("positional arguments", "options")), \
            f"rhi {path} --help has no description"
        assert "example:\n  rhi " in text, f"rhi {path} --help has no example"


def test_experiment_list_has_one_line_per_experiment(capsys):
    assert main(["experiment", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[0] for ln in lines] == experiments()
    assert all(len(ln.split(maxsplit=1)) == 2 for ln in lines)  # each with its one-line description


def test_reproduce_without_extras_names_rhi_all():
    sys.path.insert(0, str(Path(__file__).parent))
    try:
        from test_packaging import NO_EXTRAS, _python
    finally:
        sys.path.pop(0)
    out = _python(NO_EXTRAS + "from rhi.cli import main; sys.exit(main(['reproduce', '--quick', '--out', 'x']))")
    assert out.returncode == 2, out.stderr
    assert "pip install 'rhi[all]'" in out.stderr and "rhi[plots]" not in out.stderr, out.stderr


def test_a_cold_cache_says_so_once(tmp_path):
    """A process compiling an rhi kernel prints the one line; one loading it from the cache prints nothing."""
    code = ("import numpy as np\nfrom rhi.design.planar import planar_indices\nr = np.random.default_rng(0)\n"
            "print(planar_indices(r.normal(size=(4, 2, 3)), r.normal(size=(4, 2, 3)), np.ones(4, bool), np.ones(4)))")
    env = {**child_env(), "NUMBA_CACHE_DIR": str(tmp_path)}
    cold = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    warm = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert cold.returncode == 0 and warm.returncode == 0, cold.stderr + warm.stderr
    assert cold.stderr.count(jit.COLD) == 1, cold.stderr
    assert jit.COLD not in warm.stderr and cold.stdout == warm.stdout


def test_warmup_runs_every_step(capsys):
    """On a pool of two processes (whatever the CPU count): every step once, reported in `STEPS` order."""
    assert main(["warmup", "--quiet", "--workers", "2"]) == 0
    out = capsys.readouterr().out.splitlines()
    from rhi.cli_warmup import STEPS

    assert [ln[:44].strip() for ln in out[:-1]] == [name for name, _ in STEPS]
    assert out[-1].startswith("kernels ready")
    assert main(["warmup", "--quiet", "--workers", "0"]) == 2
    assert "workers" in capsys.readouterr().err
