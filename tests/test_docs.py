"""The documentation site builds without a warning (`mkdocs build --strict`: pages, links, API reference)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import child_env

ROOT = Path(__file__).resolve().parents[1]


def test_mkdocs_build_strict(tmp_path: Path) -> None:
    pytest.importorskip("mkdocstrings", reason="the docs extra is not installed (./run installs it)")
    env = child_env()
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-6000:]
    api = (tmp_path / "site" / "api" / "metrics" / "index.html").read_text()
    assert "effective_manipulability" in api and "thesis eq. 3.6" in api  # the reference comes from the docstrings
    assert (tmp_path / "site" / "protocol" / "index.html").exists()


def _resolves(name: str) -> bool:
    """Whether a dotted name is an importable module, or an attribute path inside one."""
    import importlib

    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        try:
            for attr in parts[k:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False


def test_names_in_the_docs_exist() -> None:
    """Every `rhi.…` name in the pages, CONTRIBUTING.md and the README is a module or an attribute of one."""
    import re

    pages = [*sorted((ROOT / "docs").glob("*.md")), ROOT / "CONTRIBUTING.md", ROOT / "README.md"]
    named = {(p.name, n) for p in pages for n in re.findall(r"`(rhi(?:\.\w+)+)", p.read_text())}
    missing = sorted((page, n) for page, n in named if "__main__" not in n and not _resolves(n))
    assert not missing, f"names in the docs that do not exist: {missing}"
    assert len(named) > 50  # the pages do name the code


def test_contributing_points_to_what_exists() -> None:
    """CONTRIBUTING.md's paths exist, each `name` it places in or of a file is defined there, its tests exist."""
    import re

    text = (ROOT / "CONTRIBUTING.md").read_text()
    paths = set(re.findall(r"`((?:src|tests|benchmarks|examples)/[\w./<>-]+)`", text))
    missing = sorted(p for p in paths if "<" not in p and not (ROOT / p).exists())
    assert not missing, f"CONTRIBUTING.md names files that do not exist: {missing}"
    placed = re.findall(r"`(\w+)`\s+(?:in|of)\s+`((?:src|tests|benchmarks)/[\w./-]+\.py)`", text)
    absent = sorted((name, path) for name, path in placed
                    if not re.search(rf"^\s*(?:def |class )?{name}\b\s*[:=(]", (ROOT / path).read_text(), re.M))
    assert not absent, f"CONTRIBUTING.md places names where they are not: {absent}"
    tests = set(re.findall(r"`(test_\w+)`", text))
    source = "\n".join(p.read_text() for p in (ROOT / "tests").glob("test_*.py"))
    assert not {t for t in tests if f"def {t}(" not in source}, "CONTRIBUTING.md names tests that do not exist"
    assert len(paths) > 15 and len(placed) >= 4 and len(tests) >= 5  # the guide does point to the code
