"""`rhi.jit.KernelRef`: a kernel passed by address, compiled apart from its caller, unboxed from one attribute."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")


def _kernels():
    from numba import njit

    @njit(error_model="numpy")  # not cached: a test's own kernels
    def add_first(a, b):
        a[0] += b[0]

    @njit(error_model="numpy")
    def caller(a, b, fn):
        fn(a, b)
        fn(a, b)
        return a[0]

    return add_first, caller


def test_a_ref_made_with_its_return_type_compiles_its_kernel_at_first_use_not_with_its_caller():
    from numba import typeof, types

    from rhi.jit import KernelRef, KernelType

    add_first, caller = _kernels()
    vec = types.float64[::1]
    ref = KernelRef(add_first, (vec, vec), types.none)
    assert isinstance(typeof(ref), KernelType) and not add_first.overloads
    caller.compile((vec, vec, typeof(ref)))
    assert not add_first.overloads  # the caller's code does not contain the kernel's
    a, b = np.array([1.0, 0.0]), np.array([2.5, 0.0])
    assert caller(a, b, ref) == 6.0 and (vec, vec) in add_first.overloads
    assert caller(a, b, ref) == 11.0  # the address read at the first call stays


def test_a_ref_whose_declared_return_type_is_wrong_raises_at_the_call():
    from numba import types

    from rhi.jit import KernelRef

    add_first, caller = _kernels()
    vec = types.float64[::1]
    ref = KernelRef(add_first, (vec, vec), types.float64)  # it returns None
    with pytest.raises(RuntimeError, match="address is null"):  # Numba's error where the ref gave no address
        caller(np.zeros(1), np.ones(1), ref)
    with pytest.raises(TypeError, match=r"declared .* -> float64, compiled .* -> none"):
        ref.resolve()


def test_a_ref_pickles_without_its_address_and_finds_it_again():
    """Another process's address would be a pointer into nothing: a ref sent there resolves its kernel anew."""
    import pickle

    from numba import types

    from rhi.devices._compiled.terms import dot
    from rhi.jit import KernelRef

    vec = types.float64[::1]
    ref = KernelRef(dot, (vec, vec))
    state = ref.__getstate__()
    assert state["_address"] == 0 and ref._address != 0 and state["_sig"] == ref.signature()
    copy = pickle.loads(pickle.dumps(ref))
    assert copy.kernel is dot and copy._address == 0
    assert copy.resolve() == ref._address  # this process: the same compiled kernel


def test_the_whole_tick_calls_chain_terms_and_ascm_by_address(rhi4):
    """One compile of `chain_terms` serves `Device.terms` and the whole tick; ASCM's kernel is compiled at the first tick.

    The controller compiles ASCM before it calls the whole tick (which a child compiles meanwhile, on a cold cache).
    """
    from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
    from rhi.control._compiled import ASCM
    from rhi.control._compiled.allocation import ascm_into
    from rhi.devices._compiled.chain import chain_terms
    from rhi.jit import KernelRef

    ctrl = NullSpaceController(rhi4, ControllerConfig(ForceRendering(damping=0.01, passivity=None)))
    k = ctrl._kernel
    assert k.whole_ok and k.parts.code == ASCM
    refs = {r.kernel: r for r in k._chain if isinstance(r, KernelRef)}
    assert set(refs) == {chain_terms, ascm_into} and refs[ascm_into] is k._ascm
    q = np.array([0.3, 0.5, 0.2, 0.4])
    rhi4.terms(q, np.full(4, 0.1))
    assert refs[chain_terms]._args in chain_terms.overloads
    ctrl.step(0.0, q, np.zeros(4), {"force": np.zeros(2)})
    assert k._ascm._address != 0 and k._ascm._args in ascm_into.overloads
