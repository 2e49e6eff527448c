"""Numba's disk cache for rhi's kernels, refreshed when any kernel source changes, not only the function's own file.

Numba stamps a cached function with the hash of the file that defines it. A kernel that calls
kernels of other files (`rhi.control.kernels.whole` calls `step`, `allocation`, `objectives`,
`passivity`, `rhi.terms_kernel` and `rhi.chain_kernel`, and a compiled simulation loop calls
`whole`) would then load machine code compiled from the old callees after an edit of theirs.
`install` registers cache locators for the files of the rhi package whose stamp is one hash of
every rhi module that defines compiled functions (`kernel_files`): an edit of any of them
recompiles every rhi kernel once. Functions outside the rhi package keep Numba's own locators.

Uses Numba's cache-locator classes (``numba.core.caching``); `install` runs before the kernel
modules create their decorators (`rhi.terms_kernel`, `rhi.control.kernels.jit`, `rhi.design.planar`).
"""

from __future__ import annotations

import functools
import hashlib
import re
from pathlib import Path

from numba.core import caching

_ROOT = Path(__file__).resolve().parent
#: A module defines compiled functions when a line starts with one of these decorators.
_DECORATED = re.compile(rb"^@(_?jit|njit)\b", re.M)


def kernel_files(root: Path = _ROOT) -> list[Path]:
    """The modules under `root` (default: the rhi package) that define compiled functions, sorted."""
    return sorted(p for p in root.rglob("*.py") if _DECORATED.search(p.read_bytes()))


@functools.lru_cache(maxsize=4)
def stamp(root: Path = _ROOT) -> bytes:
    """SHA-256 over the relative path and contents of every `kernel_files` module of `root` (read once per process)."""
    h = hashlib.sha256()
    for p in kernel_files(root):
        h.update(p.relative_to(root).as_posix().encode() + b"\0" + p.read_bytes() + b"\0")
    return h.digest()


def _inside(py_file: str) -> bool:
    try:
        return Path(py_file).resolve().is_relative_to(_ROOT)
    except OSError:
        return False


class _PackageStamp:
    """Mixin: the package-wide `stamp` for files of the rhi package; other files are left to Numba's locators."""

    def get_source_stamp(self):
        return stamp()

    @classmethod
    def from_function(cls, py_func, py_file):
        if not _inside(py_file):
            return None
        return super().from_function(py_func, py_file)  # type: ignore[misc]


class _UserProvided(_PackageStamp, caching.UserProvidedCacheLocator):
    pass


class _InTree(_PackageStamp, caching.InTreeCacheLocator):
    pass


class _UserWide(_PackageStamp, caching.UserWideCacheLocator):
    pass


_LOCATORS = (_UserProvided, _InTree, _UserWide)


def install() -> None:
    """Put the package-stamped locators first in Numba's list (idempotent)."""
    classes = caching.CacheImpl._locator_classes
    if classes[:len(_LOCATORS)] != list(_LOCATORS):
        classes[:] = [*_LOCATORS, *(c for c in classes if c not in _LOCATORS)]

