"""The documentation site builds without a warning (`mkdocs build --strict`: pages, links, API reference)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    pytest.importorskip("mkdocstrings", reason="the docs extra is not installed (./run installs it)")
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-6000:]
    api = (tmp_path / "site" / "api" / "metrics" / "index.html").read_text()
    assert "effective_manipulability" in api and "thesis eq. 3.6" in api  # the reference comes from the docstrings
    assert (tmp_path / "site" / "protocol" / "index.html").exists()
