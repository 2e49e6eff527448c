"""The package at a git revision, extracted (`git archive`) for a benchmark's baseline run in the same session."""

from __future__ import annotations

import contextlib
import io
import subprocess
import tarfile
import tempfile
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def source_at(rev: str) -> Iterator[Path]:
    """The `src` folder of the package at git revision `rev`, in a temporary folder while the block runs.

    Raises:
        LookupError: no such revision, or no git checkout.
    """
    try:
        tar = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "src"], capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError) as exc:
        raise LookupError(f"no git revision {rev}: {exc}") from None
    with tempfile.TemporaryDirectory() as tmp:
        tarfile.open(fileobj=io.BytesIO(tar)).extractall(tmp, filter="data")
        yield Path(tmp) / "src"
