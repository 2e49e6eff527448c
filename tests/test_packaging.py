"""Packaging: the core imports without the heavy extras, one version string, plotting keeps the backend."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from conftest import child_env

import rhi

ROOT = Path(__file__).resolve().parents[1]
# not core dependencies
EXTRAS = ("mujoco", "psignifit", "statsmodels", "matplotlib", "viser", "ray", "pandas", "mcap", "pyarrow")
HEAVY = (*EXTRAS, "scipy", "xacro", "rich")  # `import rhi.metrics` and the measures below need none of these


def _blocker(names: tuple[str, ...]) -> str:
    """Code for a meta-path finder that refuses `names`: the child behaves as an install without them."""
    return f"""
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in {names!r}:
            raise ModuleNotFoundError(f"blocked: {{name}}", name=name)
        return None
sys.meta_path.insert(0, Block())
"""


BLOCK = _blocker(HEAVY)
NO_EXTRAS = _blocker(EXTRAS)


def _python(code: str, **env: str) -> subprocess.CompletedProcess[str]:
    environ = {**child_env(), **env}
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=environ, timeout=120)


def test_core_needs_only_numpy_and_pinocchio() -> None:
    code = BLOCK + """
import numpy as np
import rhi, rhi.metrics
dev = rhi.device("rhi4")
J, M = dev.jacobian([0.125, 0.022, 0.298, 0.175]), dev.mass_matrix([0.125, 0.022, 0.298, 0.175])
print(f"{rhi.metrics.effective_manipulability(J, [0, 1]):.4f}")
print(f"{rhi.metrics.effective_inertia(J, M, [0, 1]):.4f}")
heavy = sorted({m.split('.')[0] for m in sys.modules} & set(""" + repr(HEAVY) + """))
print("heavy:", heavy)
"""
    out = _python(code)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split("\n")
    assert lines[0] == "0.3752"  # the README value (thesis Table 3.1: 0.371; test_rhi4 holds the rounding)
    assert float(lines[1]) > 0
    assert lines[2] == "heavy: []"


def test_blocker_blocks() -> None:
    """The finder above does refuse a heavy module (else the test before could not fail)."""
    out = _python(BLOCK + "import rhi.sim")
    assert out.returncode != 0 and "blocked: mujoco" in out.stderr


def test_cli_names_the_missing_extra() -> None:
    code = NO_EXTRAS + "from rhi.cli import main; sys.exit(main(['render', 'rhi4', '--out', 'x.png']))"
    out = _python(code)
    assert out.returncode == 2, out.stderr
    assert "rhi[sim]" in out.stderr or "rhi[plots]" in out.stderr, out.stderr


def test_measure_command_without_extras() -> None:
    code = NO_EXTRAS + "from rhi.cli import main; sys.exit(main(['measure', 'rhi4', '--q', '0.125,0.022,0.298,0.175', '--json']))"
    out = _python(code)
    assert out.returncode == 0, out.stderr
    values = json.loads(out.stdout)
    assert values["device"] == "rhi4" and values["undefined (singular J)"] == []
    assert values["max_force (LP, dynamic projector) [N]"] == pytest.approx(5.9573, abs=1e-4)


def test_one_version_string() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "version" not in project and "version" in project["dynamic"]
    assert tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["dynamic"]["version"] == {
        "attr": "rhi.__version__"
    }
    out = _python("from rhi.cli import main; main(['--version'])")
    assert out.stdout.strip() == f"rhi {rhi.__version__}"
    assert f"## [{rhi.__version__}]" in (ROOT / "CHANGELOG.md").read_text()


def test_python_dash_m_rhi() -> None:
    out = subprocess.run([sys.executable, "-m", "rhi", "devices"], capture_output=True, text=True, timeout=120,
                         env=child_env())
    assert out.returncode == 0, out.stderr
    assert "rhi4" in out.stdout


@pytest.mark.parametrize("backend", ["pdf", "svg"])
def test_plotting_keeps_the_users_backend(backend: str) -> None:
    code = f"""
import io
import matplotlib
matplotlib.use({backend!r})
import numpy as np
import rhi.plots, rhi.report
from rhi.plots.draw import force_torque_panels
t = np.linspace(0, 1, 50)
arrays = {{"t": t, "Fe": np.c_[t, 0 * t], "tau_a": np.c_[t, -t, 2 * t], "force_a": np.c_[t, t]}}
fig = force_torque_panels(arrays, {{"a": "case a"}}, "demo")
fig.savefig(io.BytesIO(), format="png")
print(len(fig.axes), matplotlib.get_backend())
"""
    out = _python(code, MPLBACKEND="")
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["1", backend]


def test_license_and_citation() -> None:
    assert (ROOT / "LICENSE").read_text().startswith("BSD 3-Clause License")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["license"] == {"text": "BSD-3-Clause"}
    cff = (ROOT / "CITATION.cff").read_text()
    assert "license: BSD-3-Clause" in cff and "Torabiparizi" in cff
