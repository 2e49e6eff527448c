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
    with pytest.raises(TypeError, match="declared"):
        caller(np.zeros(1), np.ones(1), ref)


def test_a_ref_pickles_without_its_address_and_finds_it_again():
    """Another process's address would be a pointer into nothing: a ref sent there resolves its kernel anew."""
    import pickle

    from numba import types

    from rhi.devices._compiled.terms import dot
    from rhi.jit import KernelRef

    vec = types.float64[::1]
    ref = KernelRef(dot, (vec, vec))
    state = ref.__getstate__()
    assert "_address" not in state and state["_sig"] == ref.signature()
    copy = pickle.loads(pickle.dumps(ref))
    assert copy.kernel is dot and "_address" not in copy.__dict__
    assert copy._address == ref._address  # this process: the same compiled kernel


def test_the_whole_tick_gets_chain_terms_as_device_terms_compiles_it(rhi4):
    """One compile of `chain_terms` serves `Device.terms` and the whole tick (which calls it by address)."""
    from rhi.control import ControllerConfig, ForceRendering, NullSpaceController
    from rhi.devices._compiled.chain import chain_terms
    from rhi.jit import KernelRef

    ctrl = NullSpaceController(rhi4, ControllerConfig(ForceRendering(damping=0.01, passivity=None)))
    ref = ctrl._kernel._chain[-1]
    assert isinstance(ref, KernelRef) and ref.kernel is chain_terms
    rhi4.terms(np.array([0.3, 0.5, 0.2, 0.4]), np.full(4, 0.1))
    assert ref._args in chain_terms.overloads
