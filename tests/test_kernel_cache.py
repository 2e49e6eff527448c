"""Numba's disk cache of rhi's kernels is stamped with every kernel source (`rhi.jit`)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from rhi import jit as kernel_cache


def test_every_rhi_kernel_carries_the_package_stamp():
    """A kernel that calls other files' kernels (the whole tick) is refreshed when any of them changes."""
    from rhi.control._compiled import allocation, step, whole
    from rhi.design import planar
    from rhi.devices._compiled import chain as chain_kernel, terms as terms_kernel

    files = {p.relative_to(kernel_cache._ROOT).as_posix() for p in kernel_cache.kernel_files()}
    assert {"control/_compiled/whole.py", "control/_compiled/step.py", "control/_compiled/allocation.py",
            "devices/_compiled/terms.py", "devices/_compiled/chain.py", "design/planar.py",
            "jit.py"} <= files  # jit.py: stack_empty, an intrinsic whose code every kernel using it holds
    assert "devices/model.py" not in files  # no compiled function there
    tick = whole.whole_for(whole.Parts(0, False, False, False, False, False, False, False))
    for fn in (tick, step.tick, allocation.ascm, terms_kernel.mv, chain_kernel.chain_terms, planar._axes):
        assert fn._cache._cache_file._source_stamp == kernel_cache.stamp(), fn


def test_each_whole_tick_has_symbol_names_of_its_own():
    """Two parts sets' whole ticks never share a name whichever processes compiled them.

    Numba names a kernel's symbols after its qualified name, argument types and the compiling process's counter
    of functions: two sets compiled first in two processes (both "v1") and loaded from the cache into a third
    had one cfunc name, and the compiled loop's pointer to the second set's tick ran the first's (every tick of
    an intent run handed back to Python).
    """
    from rhi.control._compiled import whole

    sets = [whole.Parts(0, False, True, False, True, False, False, False),
            whole.Parts(2, False, False, True, True, True, False, False)]
    names = {whole.whole_for(p).py_func.__qualname__ for p in sets}
    assert len(names) == len(sets)


def test_stamp_follows_every_kernel_file(tmp_path: Path):
    src = Path(kernel_cache.__file__).parent
    for name, to in (("devices/_compiled/terms.py", "terms_kernel.py"), ("devices/model.py", "device.py")):
        shutil.copy(src / name, tmp_path / to)
    (tmp_path / "sub").mkdir()
    shutil.copy(src / "control/_compiled/whole.py", tmp_path / "sub/whole.py")
    assert [p.name for p in kernel_cache.kernel_files(tmp_path)] == ["whole.py", "terms_kernel.py"]
    before = kernel_cache.stamp(tmp_path)
    kernel_cache.stamp.cache_clear()
    (tmp_path / "device.py").write_text("x = 1\n")  # not a kernel file: same stamp
    assert kernel_cache.stamp(tmp_path) == before
    kernel_cache.stamp.cache_clear()
    with open(tmp_path / "terms_kernel.py", "a") as f:  # a callee's edit: a new stamp for every kernel
        f.write("\n# edited\n")
    assert kernel_cache.stamp(tmp_path) != before
    kernel_cache.stamp.cache_clear()


def test_processes_saving_one_index_at_once_keep_every_entry(tmp_path: Path):
    """Workers saving overloads of one function at once (xdist's, `rhi reproduce`'s): each key keeps its own data."""
    import multiprocessing

    from numba.core.caching import IndexDataCacheFile

    def cache() -> IndexDataCacheFile:
        return IndexDataCacheFile(str(tmp_path), "kernel-1.py311", kernel_cache.stamp())

    def save(worker: int, start) -> None:
        start.wait()
        for i in range(40):
            cache().save((worker, i), (worker, i, b"x" * 20000))

    ctx = multiprocessing.get_context("fork")  # the children share this process's installed save
    start = ctx.Barrier(4)
    workers = [ctx.Process(target=save, args=(w, start)) for w in range(4)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(timeout=120)
    assert [w.exitcode for w in workers] == [0] * 4
    loaded = {(w, i): cache().load((w, i)) for w in range(4) for i in range(40)}
    assert all(v is not None and v[:2] == k for k, v in loaded.items()), [k for k, v in loaded.items() if v is None or v[:2] != k]


def _compile_at_once(cache_dir: str, start, out) -> None:
    """A fresh dispatcher of `rhi.devices._compiled.terms.dot` on `cache_dir`: compile (float32) after `start`."""
    from numba import config, types

    from rhi.devices._compiled import terms

    config.CACHE_DIR = cache_dir  # read by the cache locator when the dispatcher is made
    kernel = kernel_cache.jit(terms.dot.py_func)
    vec = types.Array(types.float32, 1, "C")
    start.wait()
    kernel.compile((vec, vec))
    out.put(sum(kernel._cache_misses.values()))  # 1: compiled here; 0: loaded what another process saved


@pytest.mark.realtime
def test_processes_starting_cold_at_once_compile_each_kernel_once(tmp_path: Path):
    """Four processes on one cold cache compiling one kernel at once: one compiles it, the others load it."""
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    start, out = ctx.Barrier(4), ctx.Queue()
    workers = [ctx.Process(target=_compile_at_once, args=(str(tmp_path), start, out)) for _ in range(4)]
    for w in workers:
        w.start()
    for w in workers:
        w.join(timeout=300)
    assert [w.exitcode for w in workers] == [0] * 4
    assert sorted(out.get(timeout=10) for _ in workers) == [0, 0, 0, 1]
    assert list(tmp_path.rglob("*.claim"))  # the claim files lie beside the index


def _aside_then_load(cache_dir: str, out) -> None:
    """`compile_aside` of `rhi.devices._compiled.terms.dot` (float32) on a cold `cache_dir`, then this process's compile."""
    import os

    from numba import config, types

    from rhi.devices._compiled import terms

    config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"] = cache_dir  # this process's locator and the child's
    kernel = kernel_cache.jit(terms.dot.py_func)
    vec = types.Array(types.float32, 1, "C")
    was = kernel_cache.cached(kernel, (vec, vec))
    child = kernel_cache.compile_aside(kernel, "rhi.devices._compiled.terms:dot", None, (vec, vec))
    code = None if child is None else child.wait(timeout=300)
    again = kernel_cache.compile_aside(kernel, "rhi.devices._compiled.terms:dot", None, (vec, vec))
    now = kernel_cache.cached(kernel, (vec, vec))
    kernel.compile((vec, vec))
    out.put((was, code, again is None, now, sum(kernel._cache_misses.values())))


@pytest.mark.realtime
def test_a_kernel_compiled_aside_is_loaded_not_compiled(tmp_path: Path):
    """`rhi.jit.compile_aside` on a cold cache: a child compiles and saves the kernel, this process then loads it."""
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    out = ctx.Queue()
    worker = ctx.Process(target=_aside_then_load, args=(str(tmp_path), out))
    worker.start()
    worker.join(timeout=400)
    assert worker.exitcode == 0
    # not cached before; the child ran to its end; asked once per process; cached after; no compile here
    assert out.get(timeout=10) == (False, 0, True, True, 0)


_FOR_CALLERS = """
import json, numpy as np
from numba import types
from rhi import jit
from rhi.devices._compiled import terms
a, m = types.Array(types.float64, 2, "C"), np.array([[2.0, 1.0], [1.0, 3.0]])
def own():  # None: not in this process; False: compiled (or loaded) for callers only
    o = terms.inv_to.overloads.get((a, a))
    return None if o is None else not getattr(o.library, "_rhi_for_callers", False)
misses = lambda: sum(terms.inv_to._cache_misses.values())
np.testing.assert_allclose(terms.inv(m) @ m, np.eye(2), atol=1e-15)  # inv from Python; inv_to compiled for it
before = [own(), jit.cached(terms.inv_to, (a, a)), misses()]
out = np.empty((2, 2))
terms.inv_to(m, out)  # a Python call: inv_to's own form
np.testing.assert_allclose(out @ m, np.eye(2), atol=1e-15)
print(json.dumps([before, [own(), jit.cached(terms.inv_to, (a, a)), misses()],
                  len(terms.inv_to._cache._cache_file._load_index())]))
"""


def test_a_kernel_compiled_for_a_caller_is_not_what_python_calls(tmp_path: Path):
    """A callee compiled for a compiled caller skips its own module passes; Python calls compile its own form.

    Both forms are cached under their own keys; a later process loads each and compiles nothing.
    """
    import json
    import os
    import subprocess
    import sys

    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    runs = [json.loads(subprocess.run([sys.executable, "-c", _FOR_CALLERS], env=env, check=True, capture_output=True,
                                      text=True).stdout.splitlines()[-1]) for _ in range(2)]
    # cold: inv_to compiled for inv only (its own form not cached), then its own form for the Python call
    assert runs[0] == [[False, False, 1], [True, True, 2], 2]
    assert runs[1] == [[None, True, 0], [True, True, 0], 2]  # warm: inv loaded whole (inv_to not needed); then loaded
