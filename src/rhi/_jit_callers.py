"""Compiles of rhi kernels for compiled callers only (`rhi.jit` installs these patches of Numba).

A kernel compiled because a compiled caller's typing asks for it (Numba's ``get_call_template``) is compiled for
callers only, without LLVM's module passes (O3) of its own: each caller links its code into its own module and
optimises that whole, so those passes and the machine code of their result were spent twice (cold path to the first
tick: module passes 4.9 -> 1.7 s CPU, machine code 4.4 -> 2.6 s). Its overload is kept out of the table Python calls
dispatch on and is cached under a key of its own; its own form is compiled when Python calls it or takes its address
(`rhi.jit.KernelRef`, `rhi.jit.compile_aside`), and a compile for callers loads the own form where that is cached
(`rhi.jit._compile_claimed` decides which).
"""

from __future__ import annotations

from numba.core import caching, codegen, dispatcher


def numba_own(owner, name: str):
    """Numba's own `owner.name`, which `rhi.jit.install` replaces (also where rhi.jit is imported again after it)."""
    f = getattr(owner, name)
    return getattr(f, "__wrapped__", f)


def for_callers(cres) -> bool:
    """Whether an overload (Numba's compile result) was compiled for compiled callers only."""
    return getattr(cres.library, "_rhi_for_callers", False)


#: Whether each compile this process is inside is for compiled callers only, innermost last, and whether the next
#: `Dispatcher.compile` is asked for by a caller's typing (module-wide: Numba compiles one function at a time).
FOR: list[bool] = []
FOR_CALLERS = [False]

_NUMBA_COMPILE = numba_own(dispatcher.Dispatcher, "compile")
_NUMBA_TEMPLATE = numba_own(dispatcher.Dispatcher, "get_call_template")
_NUMBA_ADD = numba_own(dispatcher.Dispatcher, "add_overload")
_NUMBA_MODULE_PASSES = numba_own(codegen.CPUCodeLibrary, "_optimize_final_module")
_NUMBA_INDEX_KEY = numba_own(caching.Cache, "_index_key")


def compile_as(self, sig, for_callers: bool):
    """Numba's `Dispatcher.compile`, for callers only or not (`FOR`: the cache key, module passes, overload table)."""
    FOR.append(for_callers)
    try:
        return _NUMBA_COMPILE(self, sig)
    finally:
        FOR.pop()


def _template_for_caller(self, args, kws):
    """Numba's `Dispatcher.get_call_template` (a compiled caller typing a call): its compile is for callers only."""
    FOR_CALLERS[0] = True
    try:
        return _NUMBA_TEMPLATE(self, args, kws)
    finally:
        FOR_CALLERS[0] = False


def _add_overload(self, cres) -> None:
    """Numba's `Dispatcher.add_overload`; one for callers only is not in the table Python calls run (they compile)."""
    if FOR and FOR[-1]:
        cres.library._rhi_for_callers = True
        self.overloads[tuple(cres.signature.args)] = cres
    else:
        _NUMBA_ADD(self, cres)


def _module_passes(self) -> None:
    """Numba's module passes of a library; for callers only: its first, cheap pass alone (inlining, refcount pruning)."""
    if not (FOR and FOR[-1]):
        return _NUMBA_MODULE_PASSES(self)
    cg = self._codegen
    mpm, mpb = cg._module_pass_manager(loop_vectorize=cg._loopvect, slp_vectorize=False, opt=cg._opt_level, cost="cheap")
    mpm.run(self._final_module, mpb)
    return None


def _index_key(self, sig, cg):
    """Numba's cache index key; a kernel compiled for callers only is saved beside its own form, not as it."""
    key = _NUMBA_INDEX_KEY(self, sig, cg)
    return (*key, "for callers") if FOR and FOR[-1] else key


#: What `rhi.jit.install` replaces in Numba for these compiles: (owner, name, rhi's, Numba's own)
CALLER_PATCHES = ((dispatcher.Dispatcher, "get_call_template", _template_for_caller, _NUMBA_TEMPLATE),
                  (dispatcher.Dispatcher, "add_overload", _add_overload, _NUMBA_ADD),
                  (codegen.CPUCodeLibrary, "_optimize_final_module", _module_passes, _NUMBA_MODULE_PASSES),
                  (caching.Cache, "_index_key", _index_key, _NUMBA_INDEX_KEY))
