"""The one Numba decorator of rhi (`jit`) and its disk cache, refreshed when any kernel source changes.

Every compiled function of rhi is decorated with `jit` (``cache=True``: compiled once per machine;
``error_model="numpy"``: floating-point errors give inf/NaN, checked by the caller, not exceptions);
`tests/test_structure.py` checks that no other decorator exists. Importing this module imports Numba:
only the compiled modules (each layer's private ``_compiled`` package, `rhi.metrics._small`,
`rhi.design.planar`) import it, never ``import rhi``.

Numba stamps a cached function with the hash of the file that defines it. A kernel that calls
kernels of other files (`rhi.control._compiled.whole` calls `step`, `allocation`, `objectives`,
`passivity`, `rhi.devices._compiled.terms` and `rhi.devices._compiled.chain`, and the compiled simulation
loop calls the whole tick) would then load machine code compiled from the old callees after an edit of theirs.
`install` (run here, before the decorator is made) registers cache locators for the files of the rhi
package whose stamp is one hash of every rhi module that defines compiled functions or intrinsics (`kernel_files`): an
edit of any of them recompiles every rhi kernel once. Functions outside the rhi package keep Numba's own
locators. Uses Numba's cache-locator classes (``numba.core.caching``). It also listens to Numba's compile
events: the first compile of an rhi kernel in a process (a cold cache) prints `COLD` once on stderr, so
that a first use is not two minutes without a word. And it gives Numba's inliner one copy of an inlined
function's scope for all its blocks (`_InlineCopy`: linear, not quadratic, in the function's size).
`KernelRef` passes a compiled kernel to another as an argument (a function pointer), so that the caller
is compiled once for all kernels of one signature (the compiled simulation loop, for every whole tick), and
without the kernel's code (the whole tick and `chain_terms`: two processes compile them at once).
`stack_empty` gives a kernel an array on its own stack for local scratch: no allocation, no reference counting.
Processes that share the cache (test workers, `rhi reproduce`'s workers, `rhi warmup`'s) save into a function's index
one at a time (`_save_locked`), and compile one kernel for one signature one at a time (`_compile_claimed`): a
process that finds another compiling it waits, then loads what that one saved. On a cold cache `compile_aside`
compiles a kernel in a child process while this one goes on (e.g. a controller's whole tick while the first
`Device.terms` compiles the chain dynamics): two cores share a cold start. A kernel compiled because a compiled
caller calls it is compiled for callers only, without LLVM module passes of its own (`rhi._jit_callers`).
"""

from __future__ import annotations

import copy
import fcntl
import functools
import hashlib
import os
import pickle
import re
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

from llvmlite import ir as llvm_ir
from numba import njit
from numba.core import caching, cgutils, dispatcher, event, inline_closurecall, ir, sigutils, types
from numba.core.compiler_lock import global_compiler_lock
from numba.core.typing.typeof import typeof_impl
from numba.experimental.function_type import FunctionModel
from numba.extending import NativeValue, intrinsic, register_model, unbox
from numba.np.arrayobj import make_array, populate_array

from rhi import _jit_callers as callers

_ROOT = Path(__file__).resolve().parent
#: A module defines compiled functions when a line starts with one of these decorators.
_DECORATED = re.compile(rb"^@(jit|intrinsic)\b", re.M)  # kernels and the intrinsics they inline


def kernel_files(root: Path = _ROOT) -> list[Path]:
    """The modules under `root` (default: the rhi package) that define compiled functions or intrinsics, sorted."""
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


#: The line a process prints on stderr at its first compile of an rhi kernel.
COLD = ("rhi: compiling the Numba kernels (first use of this install or of an updated rhi): up to about 2 min "
        "in all, once; later runs load them from the cache (`rhi warmup` compiles them all ahead)")


class _FirstCompile(event.Listener):
    """Prints `COLD` at the first compile of a function of the rhi package, once per process."""

    said = False

    def on_start(self, ev) -> None:
        func = getattr(ev.data.get("dispatcher"), "py_func", None) if isinstance(ev.data, dict) else None
        if not _FirstCompile.said and str(getattr(func, "__module__", "")).startswith("rhi."):
            _FirstCompile.said = True
            print(COLD, file=sys.stderr, flush=True)

    def on_end(self, ev) -> None:
        pass


_LISTENER = _FirstCompile()


def announced(value: bool = True) -> None:
    """Mark `COLD` as said in this process (e.g. by `rhi warmup`'s own progress bar), or not yet."""
    _FirstCompile.said = value


class _InlineCopy:
    """Numba's inliner's ``copy`` module, but the blocks of one copied function share one copy of its scope.

    Numba (0.68) inlines a function (``inline="always"``, `jit`'s ``inline=True``) by deep-copying its IR block by
    block, each block with a copy of the function's whole scope (every variable): quadratic in the function's size
    (12 s of the whole tick's cold compile). Here the first block copies the scope once and the function's other
    blocks reuse that copy and its variables, as the blocks of the original share one scope; the inliner then
    renames the variables by name and gives every block the caller's scope. Anything else goes to `copy`.
    """

    def __init__(self) -> None:
        self._last: tuple[ir.Scope, dict] | None = None  # (the scope copied last, the memo of its copy)

    def deepcopy(self, x, memo=None):
        if memo is not None or not isinstance(x, ir.Block):
            return copy.deepcopy(x, memo)
        if self._last is None or self._last[0] is not x.scope:
            scope_memo: dict = {}
            copy.deepcopy(x.scope, scope_memo)
            self._last = (x.scope, scope_memo)
        return copy.deepcopy(x, dict(self._last[1]))

    def __getattr__(self, name: str):
        return getattr(copy, name)


_NUMBA_SAVE = callers.numba_own(caching.IndexDataCacheFile, "save")


def _save_locked(self, key, data) -> None:
    """Numba's cache save, one process at a time per index: an exclusive lock on a file beside the index.

    Numba's own save reads the index, takes the lowest free data file number, and writes the index and then the
    data file. Two processes saving two overloads of one function at once (e.g. two controllers' whole ticks, one
    closure) took the same number: the index kept one key, and it could name the data file of the other overload.
    """
    with open(self._index_path + ".lock", "ab") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        _NUMBA_SAVE(self, key, data)


_NUMBA_COMPILE = callers.numba_own(dispatcher.Dispatcher, "compile")


def claim_path(cache: caching.Cache, args: tuple) -> str:
    """The lock file of one kernel's compile for the Numba argument types `args`: beside its cache index."""
    key = hashlib.sha256(repr(tuple(str(a) for a in args)).encode()).hexdigest()[:16]
    return f"{cache._cache_file._index_path}.{key}.claim"


def _compile_claimed(self, sig):
    """Numba's `Dispatcher.compile` of an rhi kernel, holding an exclusive lock on its `claim_path` meanwhile.

    Without it, processes starting on a cold cache at once (`rhi warmup`'s workers, test workers) each compiled
    every kernel they shared. With it the first to reach a kernel compiles and saves it while the others wait,
    then load it from the cache (Numba's compile looks there first). Held under Numba's compiler lock, which is
    re-entrant and taken by every compile anyway: a thread never waits on a claim another thread of its process
    holds. The claims a process holds are its kernel and the callees it is compiling, taken in call order, so
    two processes cannot wait on each other. A process that dies releases its claims.

    A compile a compiled caller asks for is for callers only (`rhi._jit_callers`) unless the kernel's own form is
    cached; a Python call of a kernel compiled only for callers so far compiles (or loads) its own form.
    """
    asked, callers.FOR_CALLERS[0] = callers.FOR_CALLERS[0], False  # by a compiled caller
    cache = self._cache
    if not isinstance(cache, caching.Cache) or not isinstance(cache._impl.locator, _PackageStamp):
        return callers.compile_as(self, sig, False)
    with global_compiler_lock:
        args = tuple(sigutils.normalize_signature(sig)[0])
        existing = self.overloads.get(args)
        if existing is not None:
            if asked or not callers.for_callers(existing):
                return existing.entry_point
            del self.overloads[args]  # a Python call: its own form now (Numba compiles or loads it, then lists it)
        path = claim_path(cache, args)
        if path in _HELD:  # a kernel whose compile reaches itself (recursion): this process holds its claim
            return callers.compile_as(self, sig, asked)
        try:
            claim = open(path, "ab")
        except OSError:  # a read-only cache: Numba compiles in memory
            return callers.compile_as(self, sig, asked)
        with claim:
            fcntl.flock(claim, fcntl.LOCK_EX)  # released when the file closes
            _HELD.add(path)
            try:
                return callers.compile_as(self, sig, asked and not cached(self, args))
            finally:
                _HELD.discard(path)


_HELD: set[str] = set()  # the claims this process holds (a second lock of one file by one process would wait forever)

#: What `install` replaces in Numba: (owner, name, rhi's, Numba's own)
_PATCHES = ((caching.IndexDataCacheFile, "save", _save_locked, _NUMBA_SAVE),
            (dispatcher.Dispatcher, "compile", _compile_claimed, _NUMBA_COMPILE), *callers.CALLER_PATCHES)


def cached(kernel, args: tuple) -> bool:
    """Whether `kernel` (a `jit` dispatcher) for the Numba argument types `args` is in this process or the disk cache.

    Its own form: a compile for compiled callers only does not count.
    """
    existing = kernel.overloads.get(tuple(args))
    if existing is not None and not callers.for_callers(existing):
        return True
    cache = kernel._cache
    if not isinstance(cache, caching.Cache):
        return False
    callers.FOR.append(False)  # its own form's key
    try:
        return cache._index_key(tuple(args), kernel.targetctx.codegen()) in cache._cache_file._load_index()
    except (OSError, EOFError, pickle.UnpicklingError):
        return False
    finally:
        callers.FOR.pop()


#: Whether `compile_aside` starts children (False in processes that are themselves one of several compiling).
ASIDE = [True]
_ASKED: set = set()  # (kernel, Numba types) `compile_aside` was asked for in this process: looked up once
_CHILDREN: list[subprocess.Popen] = []  # the last child started: one at a time (one more process than compiling)


def compile_aside(kernel, factory: str, factory_args: tuple | None, args: tuple) -> subprocess.Popen | None:
    """Compile `kernel` for the Numba types `args` in a child process, unless it is cached; returns the child.

    The child finds the kernel as `factory` (``"module:name"``), or makes it as ``factory(*factory_args)`` (e.g. a
    closure's maker), compiles it and saves it into the cache this process uses (asked once per process and types).
    Meanwhile this process goes on; when it needs the kernel, its compile waits on the child's claim
    (`_compile_claimed`) and loads the child's work. The child dies with this process; a failed child only costs
    the time: this process then compiles it itself.

    Args:
        kernel: the `jit` dispatcher (this process's).
        factory: where the child finds it, ``"module:name"``.
        factory_args: None: `factory` is the kernel; else the arguments the kernel is made with.
        args: the Numba types to compile it for.

    Returns:
        The child process, or None (cached, asked before, not a Numba dispatcher (e.g. a wrapper), `ASIDE` off, or a
        child of this process still compiling: one at a time).
    """
    if (not ASIDE[0] or not isinstance(kernel, dispatcher.Dispatcher) or (kernel, tuple(args)) in _ASKED
            or any(c.poll() is None for c in _CHILDREN)):
        return None
    _ASKED.add((kernel, tuple(args)))
    if cached(kernel, args):
        return None
    try:
        path = os.pathsep.join([str(_ROOT.parent), *filter(None, [os.environ.get("PYTHONPATH")])])  # this rhi
        child = subprocess.Popen([sys.executable, "-c", "from rhi.jit import _aside; _aside()"], stdin=subprocess.PIPE,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 env={**os.environ, "PYTHONPATH": path})
        assert child.stdin is not None
        child.stdin.write(pickle.dumps((factory, factory_args, tuple(args), os.getpid())))
        child.stdin.close()
    except OSError:
        return None
    threading.Thread(target=child.wait, name="rhi.jit aside", daemon=True).start()  # reaped (and counted) when it ends
    _CHILDREN[:] = [child]
    return child


def _aside() -> None:
    """A `compile_aside` child: read (factory, its arguments, Numba types, parent's pid) on stdin and compile."""
    import importlib

    from rhi._lifetime import die_with_parent

    factory, factory_args, args, parent = pickle.loads(sys.stdin.buffer.read())
    die_with_parent(parent)
    ASIDE[0] = False
    module, name = factory.split(":")
    kernel = getattr(importlib.import_module(module), name)
    (kernel if factory_args is None else kernel(*factory_args)).compile(args)


def install() -> None:
    """Stamped locators, the first-compile listener, `_InlineCopy`, and `_PATCHES` (idempotent)."""
    classes = caching.CacheImpl._locator_classes
    if classes[:len(_LOCATORS)] != list(_LOCATORS):
        classes[:] = [*_LOCATORS, *(c for c in classes if c not in _LOCATORS)]
    if _LISTENER not in event._registered.get("numba:compile", ()):
        event.register("numba:compile", _LISTENER)
    if not isinstance(inline_closurecall.copy, _InlineCopy):
        inline_closurecall.copy = _InlineCopy()  # type: ignore[assignment]
    for owner, name, patch, numba in _PATCHES:
        if getattr(owner, name) is not patch:
            patch.__wrapped__ = numba  # type: ignore[union-attr]
            setattr(owner, name, patch)


install()  # before the decorator: the cache refreshes when any kernel source changes

_PLAIN = njit(cache=True, error_model="numpy")
_INLINED = njit(cache=True, error_model="numpy", inline="always")


def jit(func=None, *, inline: bool = False):
    """The decorator of every compiled function of rhi: ``@jit``, or ``@jit(inline=True)``.

    ``inline=True`` is for a kernel with one compiled call site (e.g. `rhi.control._compiled.step.tick` in
    `rhi.control._compiled.whole`): Numba inlines its IR into that caller instead of compiling it on its
    own first and linking it in, which saves its own optimisation passes and machine code (a cold compile pays them
    once per kernel, and the caller optimises the linked code again). Called from Python, it compiles on its own as
    usual. Each compiled call site types and compiles it again: for kernels with one such site on the way to the
    first tick (a second one, e.g. `rhi.control._compiled.sources`, pays its own copy).
    """
    deco = _INLINED if inline else _PLAIN
    return deco if func is None else deco(func)


class KernelType(types.FunctionType):
    """A `KernelRef`'s Numba type: Numba's first-class function type, unboxed from the ref's address attribute."""


register_model(KernelType)(FunctionModel)


@unbox(KernelType)
def _unbox_kernel_ref(typ, obj, c) -> NativeValue:
    """A `KernelRef` passed to compiled code: the address of its C wrapper read from its ``_address``.

    Numba's own unboxing of a first-class function imports a module, unpickles the signature and calls Python
    twice: ~2.5 µs per call of the kernel it is passed to (a sixth of a controller tick). This reads one attribute;
    where it is 0 (not found yet) a call of it asks the ref (`KernelRef.__wrapper_address__`) through Python.
    """
    builder, voidptr = c.builder, c.context.get_value_type(types.voidptr)
    fn = cgutils.create_struct_proxy(typ)(c.context, builder)
    address = c.pyapi.object_getattr_string(obj, "_address")  # NULL with an exception set where it failed
    failed = cgutils.is_null(builder, address)
    slot = cgutils.alloca_once_value(builder, llvm_ir.Constant(voidptr, None))
    with builder.if_then(builder.not_(failed), likely=True):
        builder.store(c.pyapi.long_as_voidptr(address), slot)
        c.pyapi.decref(address)
    fn.c_addr = builder.load(slot)
    fn.py_addr = builder.ptrtoint(obj, voidptr)
    fn.jit_addr = llvm_ir.Constant(voidptr, None)  # called through the C wrapper: no exception crosses
    return NativeValue(fn._getvalue(), is_error=failed)


class KernelRef(types.WrapperAddressProtocol):
    """A compiled kernel as an argument of another kernel: a pointer to it, typed by its signature.

    The caller is compiled (and cached) once for every kernel of this signature, where an argument that is the
    dispatcher itself would compile the caller again for each kernel; and the caller's code does not contain the
    kernel's (its compile neither repeats nor waits for the kernel's). The call goes through Numba's C wrapper
    of the kernel, which no exception crosses: a kernel that raises prints the error and returns 0, so a
    caller must read the kernel's own sign of completion (e.g. `rhi.control._compiled.whole`'s R_DONE).

    Args:
        kernel: a `jit` function (its dispatcher); compiled (or loaded from the cache) for `args` here, or where
            `restype` is given at its first call or `resolve` (a caller can be typed, and compiled elsewhere,
            before the kernel is; a caller that never calls it never compiles it).
        args: the Numba types of its arguments, as the caller passes them.
        restype: the Numba type the kernel returns for `args`, or None (found by compiling it now).
    """

    def __init__(self, kernel, args: tuple, restype=None) -> None:
        self.kernel, self._args = kernel, tuple(args)
        self._address = 0  # not found yet: a compiled call then asks `__wrapper_address__` (Numba's own fallback)
        if restype is None:
            self.resolve()
        else:
            self._sig = restype(*self._args)
            self._type = KernelType(self._sig)

    def resolve(self) -> int:
        """The address of the kernel's C wrapper: compiled (or loaded) for its types here, unless done before.

        A ref made with its `restype` does so at its first call, or here where its caller asks ahead (e.g. to
        compile it while another process compiles the caller).

        Raises:
            TypeError: the kernel compiled returns another type than the `restype` declared.
        """
        if not self._address:
            self.kernel.compile(self._args)
            cres = self.kernel.overloads[self._args]
            if getattr(self, "_sig", cres.signature) != cres.signature:
                raise TypeError(f"{self.kernel.py_func.__qualname__}: declared {self._sig}, compiled {cres.signature}")
            self._sig = cres.signature
            self._type = KernelType(self._sig)
            self._address = cres.library.get_pointer_to_function(cres.fndesc.llvm_cfunc_wrapper_name)
        return self._address

    def __getstate__(self) -> dict:
        """Pickled (to another process) without its address: found again there at its first use."""
        return {**self.__dict__, "_address": 0}

    def __wrapper_address__(self) -> int:
        return self.resolve()

    def signature(self):
        """The kernel's Numba signature (return type and argument types)."""
        return self._sig


@typeof_impl.register(KernelRef)
def _typeof_kernel_ref(val: KernelRef, c) -> KernelType:
    """A `KernelRef`'s Numba type, made once.

    Numba's own typeof of a function pointer builds it at every call of the kernel it is passed to: ~0.1 ms of
    typing its argument types, as much as ten ticks of the compiled simulation loop.
    """
    return val._type


@intrinsic
def _stack_empty(typingctx, shape, dtype):
    """``stack_empty(shape, dtype)`` in compiled code: an uninitialised C-contiguous array on the function's stack.

    `shape` an int or a tuple of ints, `dtype` a NumPy scalar type (``np.float64``, ``np.bool_``, ...). No
    allocation, no owner (meminfo NULL), so no reference counting of it or its views (an array from the heap costs
    a malloc, a free and an atomic operation per count). Freed when the compiled function holding it returns (the
    caller, where that function is inlined): only for arrays that do not outlive it (never returned or kept), never
    inside a long loop (each evaluation takes more stack until the function returns), small sizes only.
    """
    if isinstance(shape, types.Integer):
        nd = 1
    elif isinstance(shape, types.BaseTuple) and all(isinstance(t, types.Integer) for t in shape.types):  # type: ignore[attr-defined]
        nd = len(shape.types)  # type: ignore[attr-defined]
    else:
        return None
    if not isinstance(dtype, types.NumberClass):
        return None
    ret = types.Array(dtype.instance_type, nd, "C")

    def codegen(context, builder, sig, args):
        shape_ty, intp = sig.args[0], context.get_value_type(types.intp)
        if isinstance(shape_ty, types.Integer):
            dims = [context.cast(builder, args[0], shape_ty, types.intp)]
        else:
            dims = [context.cast(builder, builder.extract_value(args[0], i), t, types.intp)
                    for i, t in enumerate(shape_ty.types)]
        total = llvm_ir.Constant(intp, 1)
        for d in dims:
            total = builder.mul(total, d)
        element = context.get_data_type(ret.dtype)
        data = builder.alloca(element, size=total)
        data.align = 16
        itemsize = context.get_abi_sizeof(element)
        strides: list = []
        step = llvm_ir.Constant(intp, itemsize)
        for d in reversed(dims):
            strides.insert(0, step)
            step = builder.mul(step, d)
        out = make_array(ret)(context, builder)
        populate_array(out, data=data, shape=dims, strides=strides, itemsize=itemsize, meminfo=None)
        return out._getvalue()

    return ret(shape, dtype), codegen


stack_empty: Any = _stack_empty  # as kernels call it: stack_empty(shape, dtype) (the intrinsic takes the typing context first)
