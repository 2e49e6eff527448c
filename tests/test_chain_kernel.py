"""The compiled chain dynamics behind `Device.terms` (`rhi.devices._compiled.chain`) against Pinocchio's algorithms."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_batch import _device

from rhi.devices import batch, terms_pass
from rhi.devices.model import Device, available_devices, device

NAMES = available_devices() + ["panda", "ur5", "panda_tree"]


def _reference(model: pin.Model, fid: int, th: np.ndarray, dth: np.ndarray) -> dict[str, np.ndarray]:
    data = model.createData()
    pin.computeJointJacobians(model, data, th)
    J6 = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    x = data.oMf[fid].translation.copy()
    C = pin.computeCoriolisMatrix(model, data, th, dth)
    M = pin.crba(model, data, th)
    return {"x": x, "J6": J6, "M": np.triu(M) + np.triu(M, 1).T, "g": pin.computeGeneralizedGravity(model, data, th),
            "C": C}


@pytest.mark.parametrize("name", NAMES)
def test_chain_dynamics_equal_pinocchio(name):
    """x, the 6-D frame Jacobian, CRBA (with armature), gravity and the Coriolis matrix at 50 random states."""
    from rhi.devices._compiled import chain as chain_kernel

    dev = _device(name)
    model, fid = dev.model, dev.ee_frame_id
    assert batch.supported(model)
    consts = batch.pack(model, fid)
    rng = np.random.default_rng(7)
    for _ in range(50):
        th = rng.uniform(-np.pi, np.pi, model.nv)
        dth = rng.normal(0.0, 2.0, model.nv)
        got = dict(zip(("x", "J6", "M", "g", "C"), chain_kernel.chain_dynamics(*consts, th, dth)))
        for term, want in _reference(model, fid, th, dth).items():
            scale = max(1.0, float(np.linalg.norm(want)))
            np.testing.assert_allclose(got[term], want, rtol=0, atol=1e-12 * scale, err_msg=f"{name} {term}")


@pytest.mark.parametrize("name", ["rhi4", "gen3", "ur5"])
def test_device_terms_use_the_chain_kernel(name):
    """`Device.terms` takes the compiled chain path and equals the per-call Pinocchio methods (C included)."""
    dev = _device(name)
    rng = np.random.default_rng(8)
    q = np.clip(rng.normal(0.3, 0.5, dev.n), dev.q_min, dev.q_max)
    dq = rng.normal(size=dev.n)
    kin = dev.terms(q, dq)
    assert dev._fast_maps.chain is not None
    np.testing.assert_allclose(kin.x, dev.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(kin.J, dev.jacobian(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(kin.M, dev.mass_matrix(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(kin.g, dev.gravity(q), rtol=0, atol=1e-12 * max(1.0, np.abs(kin.g).max()))
    np.testing.assert_allclose(kin.C, dev.coriolis(q, dq), rtol=0, atol=1e-12 * max(1.0, np.abs(kin.C).max()))


def test_terms_with_a_mimic_map():
    """Through an actuation map with an offset (θ = A q + b) the chain path equals Pinocchio's."""
    base = device("planar3r")
    A = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, -0.5]])
    dev = Device(base.model, name="mimic", ee_frame=base.ee_frame, task_axes="xy", actuation=A,
                 offset=np.array([0.0, 0.0, 0.2]), armature=np.array([1e-4, 2e-4]), torque_max=[1.0, 1.0])
    q, dq = np.array([0.3, -0.7]), np.array([1.5, -2.0])
    kin = dev.terms(q, dq)
    assert dev._fast_maps.chain is not None
    np.testing.assert_allclose(kin.M, dev.mass_matrix(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(kin.C, dev.coriolis(q, dq), rtol=0, atol=1e-12)
    np.testing.assert_allclose(kin.dJ, dev.jacobian_derivative(q), rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", ["rhi4", "gen3"])
def test_chain_path_equals_pinocchio_path(name, monkeypatch):
    """Every term of `Device.terms`, task-space dynamics included, equals the Pinocchio + `task_terms` path."""
    q, dq = np.full(device(name).n, 0.3), np.linspace(-1.0, 1.0, device(name).n)
    fast = device(name).terms(q, dq)
    monkeypatch.setattr(batch, "supported", lambda model: False)  # one-DoF joints the chain kernel would not take
    dev = device(name)
    slow = dev.terms(q, dq)
    assert dev._fast_maps.chain is None and dev._fast_maps.kernel is not None
    for term in ("x", "J", "dJ", "M", "g", "Minv", "Lambda", "Jsharp", "Gx", "xdot", "Jdot", "C", "Cx"):
        want = getattr(slow, term)
        np.testing.assert_allclose(getattr(fast, term), want, rtol=0, atol=1e-12 * max(1.0, np.abs(want).max()),
                                   err_msg=term)


@pytest.mark.parametrize("name", ["rhi4", "gen3"])
def test_pinocchio_pass_equals_the_chain_pass(name, monkeypatch):
    """The pass for joints that are not one-DoF (`terms_pass.pinocchio_terms`) equals the chain pass on every term."""
    q, dq = np.full(device(name).n, 0.3), np.linspace(-1.0, 1.0, device(name).n)
    fast = device(name).terms(q, dq)
    monkeypatch.setattr(terms_pass, "hessian_mask", lambda model: None)  # as for a joint that is not one-DoF
    dev = device(name)
    slow = dev.terms(q, dq)
    assert dev._fast_maps.kernel is None and dev._fast_maps.chain is None
    for term in ("x", "J", "dJ", "M", "g", "Minv", "Lambda", "Jsharp", "Gx", "xdot", "Jdot", "C", "Cx"):
        want = getattr(slow, term)
        np.testing.assert_allclose(getattr(fast, term), want, rtol=0, atol=1e-10 * max(1.0, np.abs(want).max()),
                                   err_msg=term)
