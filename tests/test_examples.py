"""Every script in examples/ runs and prints the values its docstring says it should."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import child_env

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))
EXPECTED = re.compile(r"^\s+(\w+) = (\S+) \+- (\S+)$")
PRINTED = re.compile(r"^(\w+) = (\S+)$")


def expected(path: Path) -> dict[str, tuple[float, float]]:
    """{name: (value, tolerance)} from the ``Expected output`` block of the example's docstring."""
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    assert "Expected output" in doc, f"{path.name}: no 'Expected output' block in its docstring"
    block = doc.split("Expected output", 1)[1]
    return {m[1]: (float(m[2]), float(m[3])) for m in map(EXPECTED.match, block.splitlines()) if m}


def test_there_are_examples() -> None:
    assert len(EXAMPLES) >= 5
    for path in EXAMPLES:
        assert len(expected(path)) >= 2, path.name


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example(path: Path, tmp_path: Path) -> None:
    want = expected(path)
    env = {**child_env(), "MPLBACKEND": "Agg"}
    out = subprocess.run([sys.executable, str(path)], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    if out.stdout.startswith("skipped: "):  # render_device without any OpenGL backend (CI installs OSMesa)
        pytest.skip(out.stdout.strip())
    got = {m[1]: float(m[2]) for m in map(PRINTED.match, out.stdout.splitlines()) if m}
    assert got.keys() == want.keys(), out.stdout
    for name, (value, tol) in want.items():
        assert abs(got[name] - value) <= tol, f"{path.name}: {name} = {got[name]}, expected {value} ± {tol}"
