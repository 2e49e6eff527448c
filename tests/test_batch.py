"""Batch kinematics and dynamics (`rhi.devices.batch`) against Pinocchio, one configuration at a time."""

from __future__ import annotations

import importlib.metadata
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from rhi.devices import batch
from rhi.devices.model import BATCH_MIN, Device, available_devices, device

TERMS = ("x", "J", "dJ", "M", "g")


def _robots_dir() -> Path | None:
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    path = Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))
    return path if path.is_dir() else None


def _device(name: str) -> Device:
    if name == "panda_tree":  # the raw model: 7 revolute joints + 2 prismatic fingers on a branch
        model = pin.buildModelFromUrdf(str(_robots_dir() / "panda_description/urdf/panda.urdf"))
        return Device(model, name=name, ee_frame="panda_hand_tcp", q_min=model.lowerPositionLimit,
                      q_max=model.upperPositionLimit, torque_max=model.effortLimit)
    if name in ("panda", "ur5"):
        from rhi.devices.loaders import device_from_description

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the locked Panda fingers
            return device_from_description(name, ee_frame={"panda": "panda_hand_tcp", "ur5": "tool0"}[name])
    return device(name)


def _pinocchio(dev: Device, th: np.ndarray) -> dict[str, np.ndarray]:
    """The terms from Pinocchio's own algorithms at one chain configuration θ, in motor coordinates."""
    model, data, A, rows = dev.model, dev.model.createData(), dev.A, dev.task_rows
    fid = model.getFrameId(dev.ee_frame)
    J6 = pin.computeFrameJacobian(model, data, th, fid, pin.LOCAL_WORLD_ALIGNED)
    x = data.oMf[fid].translation[rows].copy()
    M = pin.crba(model, data, th)
    M = np.triu(M) + np.triu(M, 1).T
    g = pin.computeGeneralizedGravity(model, data, th)
    H = []
    for k in range(model.nv):  # ∂J/∂θ_k is dJ/dt along θ̇ = e_k
        pin.computeJointJacobiansTimeVariation(model, data, th, np.eye(model.nv)[k])
        pin.updateFramePlacements(model, data)
        H.append(pin.getFrameJacobianTimeVariation(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[rows])
    dJ = np.einsum("kib,ba,kc->iac", np.array(H), A, A)
    return {"x": x, "J": J6[rows] @ A, "dJ": dJ, "M": A.T @ M @ A + np.diag(dev.armature), "g": A.T @ g}


def _configurations(dev: Device, k: int, seed: int = 0) -> np.ndarray:
    lo = np.where(np.isfinite(dev.q_min), dev.q_min, -np.pi)
    hi = np.where(np.isfinite(dev.q_max), dev.q_max, np.pi)
    return np.random.default_rng(seed).uniform(lo, hi, size=(k, dev.n))


def _assert_equal_to_pinocchio(dev: Device, Q: np.ndarray, got: dict[str, np.ndarray]) -> None:
    ref = [_pinocchio(dev, th) for th in dev.theta(Q)]
    for term in TERMS:
        want = np.array([r[term] for r in ref])
        scale = max(1.0, float(np.max(np.abs(want))))
        np.testing.assert_allclose(got[term], want, rtol=0, atol=1e-12 * scale, err_msg=f"{dev.name} {term}")


@pytest.mark.parametrize("name", available_devices() + ["panda", "ur5", "panda_tree"])
def test_batch_terms_equal_pinocchio(name):
    dev = _device(name)
    assert dev._batch is not None, f"{name}: every joint is revolute or prismatic"
    Q = _configurations(dev, 40)
    got = {"x": dev.fk(Q), "J": dev.jacobian(Q), "dJ": dev.jacobian_derivative(Q), "M": dev.mass_matrix(Q),
           "g": dev.gravity(Q)}
    _assert_equal_to_pinocchio(dev, Q, got)


def test_batch_leading_axes_blocks_and_subsets():
    """Leading batch axes, a last block of the compiled loop that is partial, and any subset of terms."""
    from rhi.devices._compiled.batch import BLOCK

    dev = device("rhi4")
    Q = _configurations(dev, 3 * (2 * BLOCK + 5), seed=3).reshape(3, 2 * BLOCK + 5, dev.n)
    whole = dev._batch.evaluate(dev.theta(Q), TERMS)
    for term in TERMS:
        assert whole[term].shape[:2] == Q.shape[:2] and whole[term].flags.c_contiguous
        alone = dev._batch.evaluate(dev.theta(Q), (term,))
        assert set(alone) == {term}
        np.testing.assert_array_equal(alone[term], whole[term])
    flat = {k: v.reshape((-1,) + v.shape[2:]) for k, v in whole.items()}
    _assert_equal_to_pinocchio(dev, Q.reshape(-1, dev.n), flat)
    strided = dev._batch.evaluate(dev.theta(Q)[:, ::2], ("J", "M"))  # a non-contiguous θ
    np.testing.assert_array_equal(strided["J"], whole["J"][:, ::2])
    np.testing.assert_array_equal(strided["M"], whole["M"][:, ::2])


def _random_tree(seed: int) -> pin.Model:
    """A tree of revolute/prismatic joints with unaligned axes, generic placements and inertias.

    Joints are added depth first (each one's parent on the path to the previous joint), as Pinocchio requires.
    """
    rng = np.random.default_rng(seed)
    model = pin.Model()
    joints = [0]  # the world, then the path from it to the joint added last
    for k in range(7):
        joints = joints[: int(rng.integers(1, len(joints) + 1))] if k > 2 else joints
        parent = joints[-1]
        axis = rng.normal(size=3)
        jm = pin.JointModelPrismaticUnaligned(axis / np.linalg.norm(axis)) if k == 4 else \
            pin.JointModelRevoluteUnaligned(axis / np.linalg.norm(axis))
        place = pin.SE3(pin.exp3(rng.normal(size=3)), rng.uniform(-0.3, 0.3, 3))
        jid = model.addJoint(parent, jm, place, f"j{k}")
        L = rng.normal(size=(3, 3))
        model.appendBodyToJoint(jid, pin.Inertia(float(rng.uniform(0.2, 2.0)), rng.uniform(-0.1, 0.1, 3),
                                                 L @ L.T * 0.01 + np.eye(3) * 1e-3), pin.SE3.Identity())
        joints.append(jid)
    model.armature = rng.uniform(0.0, 0.01, model.nv)
    tip = pin.SE3(pin.exp3(rng.normal(size=3)), rng.uniform(-0.2, 0.2, 3))
    deepest = max(range(1, model.njoints), key=lambda j: len(model.supports[j]))
    model.addFrame(pin.Frame("tip", deepest, 0, tip, pin.FrameType.OP_FRAME))
    return model


@pytest.mark.parametrize("seed", [0, 1])
def test_batch_generic_tree_equals_pinocchio(seed):
    """No axis-aligned constant for the compiled loop to skip: every product is taken."""
    model = _random_tree(seed)
    dev = Device(model, name=f"tree{seed}", ee_frame="tip", q_min=-np.pi * np.ones(7), q_max=np.pi * np.ones(7),
                 torque_max=np.ones(7))
    assert dev._batch is not None
    Q = _configurations(dev, 45, seed=seed)
    _assert_equal_to_pinocchio(dev, Q, dev._batch.evaluate(dev.theta(Q), TERMS))


def test_batch_mimic_and_locked_joints():
    """A mimic joint (θ3 = −0.5 θ2 + 0.2) and a locked one, both through the actuation map A, b."""
    base = device("planar3r")
    A = np.array([[1.0, 0.0], [0.0, 1.0], [0.0, -0.5]])
    dev = Device(base.model, name="mimic", ee_frame=base.ee_frame, task_axes="xy", actuation=A,
                 offset=np.array([0.0, 0.0, 0.2]), armature=np.array([1e-4, 2e-4]), torque_max=[1.0, 1.0])
    Q = _configurations(dev, BATCH_MIN + 5, seed=1)
    got = dev._batch.evaluate(dev.theta(Q), TERMS)
    _assert_equal_to_pinocchio(dev, Q, got)
    locked = device("rhi4").lock(q2=0.3)
    Q = _configurations(locked, BATCH_MIN, seed=2)
    _assert_equal_to_pinocchio(locked, Q, locked._batch.evaluate(locked.theta(Q), TERMS))


def test_batch_matches_per_configuration_api():
    """Below and above BATCH_MIN the batch API gives the same numbers (to round-off)."""
    dev = device("phantom3")
    Q = _configurations(dev, BATCH_MIN, seed=4)
    loop = np.array([dev.mass_matrix(q) for q in Q])
    np.testing.assert_allclose(dev.mass_matrix(Q), loop, rtol=0, atol=1e-15)
    np.testing.assert_allclose(dev.mass_matrix(Q[:2]), loop[:2], rtol=0, atol=0)  # small batches: Pinocchio


def test_terms_in_one_pass_equal_the_device_methods():
    """`rhi.devices.batch.terms` runs one pass for several terms; each equals the `Device` method's batch."""
    from rhi.errors import InvalidInput

    dev = device("gen3")
    Q = _configurations(dev, BATCH_MIN + 3, seed=6).reshape(-1, 1, dev.n)
    got = batch.terms(dev, Q, ("x", "J", "dJ", "M", "g"))
    for term in TERMS:
        np.testing.assert_array_equal(got[term], getattr(dev, batch.TERMS[term])(Q))
    assert set(batch.terms(dev, Q)) == {"J", "dJ", "M", "g"}
    one = batch.terms(dev, Q[0, 0], ("J", "g"))  # a single configuration: the Pinocchio path
    np.testing.assert_array_equal(one["J"], dev.jacobian(Q[0, 0]))
    with pytest.raises(InvalidInput, match="what"):
        batch.terms(dev, Q, ("J", "Lambda"))
    with pytest.raises(InvalidInput, match="q"):
        batch.terms(dev, Q[..., :3])


def test_unsupported_joint_falls_back_to_pinocchio():
    model = pin.Model()
    jid = model.addJoint(0, pin.JointModelRZ(), pin.SE3.Identity(), "hinge")
    offset = pin.SE3(np.eye(3), np.array([0.3, 0.0, 0.0]))
    jid = model.addJoint(jid, pin.JointModelHZ(0.05), offset, "screw")  # helical: not in rhi.devices.batch
    model.appendBodyToJoint(jid, pin.Inertia.FromBox(1.0, 0.1, 0.2, 0.3), pin.SE3.Identity())
    model.addFrame(pin.Frame("tip", jid, 0, offset, pin.FrameType.OP_FRAME))
    dev = Device(model, name="screw", ee_frame="tip", torque_max=[1.0, 1.0])
    assert not batch.supported(model) and dev._batch is None
    Q = np.random.default_rng(5).uniform(-1.0, 1.0, (BATCH_MIN + 1, 2))
    np.testing.assert_array_equal(dev.jacobian(Q), np.array([dev.jacobian(q) for q in Q]))


def test_evaluate_refuses_bad_input():
    from rhi.errors import InvalidInput

    chain = device("gen3")._batch
    good = np.zeros((BATCH_MIN, 7))
    for bad in (np.zeros((BATCH_MIN, 6)), np.zeros(()), np.where(np.eye(BATCH_MIN, 7) > 0, np.nan, 0.0),
                np.full((2, 7), np.inf), "theta"):
        with pytest.raises(InvalidInput, match="theta"):
            chain.evaluate(bad, ("J",))
    for what in ((), ("J", "Lambda")):
        with pytest.raises(InvalidInput, match="what"):
            chain.evaluate(good, what)
    assert chain.evaluate(good.astype(int), ("g",))["g"].shape == (BATCH_MIN, 7)  # integers are read as floats


@pytest.mark.parametrize("name", available_devices() + ["panda", "ur5"])
def test_batch_measures_equal_the_per_configuration_loop(name):
    """ρ, Λ, μ of a batch (compiled closed forms and kernels of rhi.metrics) equal a per-configuration loop to 1e-10."""
    from rhi import metrics
    from rhi.metrics._common import SMALL_BATCH_MIN

    dev = _device(name)
    Q = _configurations(dev, 2 * SMALL_BATCH_MIN)
    u = np.ones(dev.m) / np.sqrt(dev.m)
    t = batch.terms(dev, Q, ("J", "M"))
    got = np.stack([metrics.effective_manipulability(t["J"], u), metrics.effective_inertia(t["J"], t["M"], u),
                    metrics.manipulability(t["J"])], axis=-1)
    want = []
    for q in Q:  # one configuration at a time: Pinocchio's J and M, LAPACK's factorizations
        J, M = dev.jacobian(q), dev.mass_matrix(q)
        want.append([metrics.effective_manipulability(J, u), metrics.effective_inertia(J, M, u),
                     metrics.manipulability(J)])
    np.testing.assert_allclose(got, want, rtol=1e-10, err_msg=name)
