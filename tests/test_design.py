"""rhi.design: global indices against closed forms, IK models, bounds errors, executors, resume."""

from __future__ import annotations

import dataclasses
import functools
import importlib
import socket

import numpy as np
import pytest
from scipy import integrate

import rhi
from rhi.design import (
    DesignProblem,
    DeviceMaster,
    EvalCache,
    Phantom3Master,
    PoolExecutor,
    SerialExecutor,
    annulus,
    check_bounds,
    device_indices,
    evaluate,
    evaluate_strict,
    optimize,
    rectangle,
    slave_solution,
    sweep,
)
from rhi.errors import InfeasibleLimits, InvalidInput, Unreachable
from rhi.experiments import ch4

L1, L2 = 0.3, 0.2


def _two_r(points: np.ndarray) -> np.ndarray:
    """Jacobians (N, 2, 2) of a 2R arm (links L1, L2, elbow-up) at the points (N, 2) [m]."""
    r2 = np.sum(points**2, axis=1)
    c2 = np.clip((r2 - L1**2 - L2**2) / (2 * L1 * L2), -1, 1)
    t2 = np.arccos(c2)
    t1 = np.arctan2(points[:, 1], points[:, 0]) - np.arctan2(L2 * np.sin(t2), L1 + L2 * c2)
    s1, c1, s12, c12 = np.sin(t1), np.cos(t1), np.sin(t1 + t2), np.cos(t1 + t2)
    return np.stack([np.stack([-L1 * s1 - L2 * s12, -L2 * s12], -1), np.stack([L1 * c1 + L2 * c12, L2 * c12], -1)], -2)


def test_gm_of_2r_arm_over_its_annulus_matches_closed_form():
    # μ = l1 l2 |sin θ2|; over the full annulus |l1 − l2| <= r <= l1 + l2, GM = π l1 l2 / 4.
    ws = annulus((0.0, 0.0), abs(L1 - L2), L1 + L2, density=200)
    gm = device_indices(_two_r(ws.points), np.ones(len(ws), bool), ws.weights)["GM"]
    assert gm == pytest.approx(np.pi * L1 * L2 / 4, rel=2e-3)


@pytest.mark.parametrize("kind", ["grid", "sobol"])
def test_gm_and_gc_match_direct_numerical_integration(kind):
    r_in, r_out = 0.15, 0.45
    ws = annulus((0.0, 0.0), r_in, r_out, density=150, kind=kind)
    got = device_indices(_two_r(ws.points), np.ones(len(ws), bool), ws.weights)

    def local(r, which):
        J = _two_r(np.array([[r, 0.0]]))[0]
        s = np.linalg.svd(J, compute_uv=False)
        return s.prod() if which == "GM" else s[-1] / s[0]

    area = np.pi * (r_out**2 - r_in**2)
    for which in ("GM", "GC"):  # μ and 1/κ depend on r only: ∫_W v dW = ∫ v(r) 2πr dr
        want = integrate.quad(lambda r, which=which: local(r, which) * 2 * np.pi * r, r_in, r_out, epsabs=1e-12)[0] / area
        assert got[which] == pytest.approx(want, rel=2e-3 if kind == "grid" else 1e-2)


def test_indices_converge_as_density_doubles():
    a = evaluate(ch4.setup.problem("theta_z", density=50), [0.1])
    b = evaluate(ch4.setup.problem("theta_z", density=100), [0.1])
    for k in ("GM_M", "GC_M", "GM_T"):
        assert b[k] == pytest.approx(a[k], rel=0.01)


def test_closed_form_phantom3_matches_device_ik():
    ws = rectangle((0.40, 0.45), (-0.05, 0.05), density=40)
    slave = slave_solution("rehab_slave", ws.points, ch4.setup.SLAVE_Q0)
    x = [0.25, 0.3, -0.1]
    fast = DesignProblem(Phantom3Master(), ws, slave, (0.424, 0), 0.3, ch4.setup.BOUNDS)
    slow = dataclasses.replace(fast, master=DeviceMaster("phantom3"))
    a, b = fast.solve(x), slow.solve(x)
    assert a.ok.all() and b.ok.all()
    np.testing.assert_allclose(a.q, b.q, atol=1e-6)
    np.testing.assert_allclose(a.J, b.J, atol=1e-9)
    ea, eb = evaluate(fast, x), evaluate(slow, x)
    for k in ea:
        assert ea[k] == pytest.approx(eb[k], rel=1e-6)


def _plane_reached(l2: float, z: float, r: np.ndarray) -> np.ndarray:
    """Whether phantom3 reaches (r, z) on its vertical plane (r: (k,) [m]; z [m]).

    Both elbow branches of (r, z) = l1 (c2, s2) + l2 (s3, −c3) (eq. 4.25b integrated), each checked against the
    device's θ2, θ3 and parallelogram limits.
    """
    dev = rhi.device("phantom3")
    q_min, q_max, lin = dev.q_min, dev.q_max, dev.linear_limits
    l1 = Phantom3Master().l1
    out = np.zeros(len(r), dtype=bool)
    c = (r**2 + z**2 - l1**2 - l2**2) / (2 * l1 * l2)  # cos of the angle from link 1 to link 2
    for sign in (1.0, -1.0):
        rel = sign * np.arccos(np.clip(c, -1, 1))
        t2 = np.arctan2(z, r) - np.arctan2(l2 * np.sin(rel), l1 + l2 * np.cos(rel))
        t3 = t2 + rel + np.pi / 2  # link 2 points along (sin θ3, −cos θ3) = (cos(θ3 − 90°), sin(θ3 − 90°))
        t3 = (t3 + np.pi) % (2 * np.pi) - np.pi
        out |= ((np.abs(c) <= 1) & (t2 >= q_min[1] - 1e-12) & (t2 <= q_max[1] + 1e-12) & (t3 >= q_min[2] - 1e-12)
                & (t3 <= q_max[2] + 1e-12) & (t2 - t3 >= lin.lower[0] - 1e-12) & (t2 - t3 <= lin.upper[0] + 1e-12))
    return out


@pytest.mark.parametrize(("l2", "z"), [(0.165, 0.0539), (0.269, -0.065), (0.365, -0.2162), (0.365, -0.51), (0.2, 0.15)])
def test_radial_range_is_the_interval_the_hi_reaches(l2, z):
    """r0 = "auto" places W's centre mid-way in this interval: its ends are reached, and nothing beyond them is.

    The θ2 grid it was once computed on (2001 values) fell short of the outer end by 0.12 mm at §4.4's first
    round (0.35370 instead of 0.35382 m), so §4.4's optima were found at a misplaced centre.
    """
    lo, hi = Phantom3Master().radial_range({"l2": l2, "z_ph": z})
    r = np.linspace(1e-6, Phantom3Master().l1 + l2, 200_001)
    reached = r[_plane_reached(l2, z, r)]
    assert reached.size > 1000
    assert lo <= reached.min() and reached.max() <= hi
    assert _plane_reached(l2, z, np.array([hi - 1e-7, lo + 1e-7])).all()
    assert not _plane_reached(l2, z, np.array([hi + 1e-6])).any()
    assert lo < 1e-6 or not _plane_reached(l2, z, np.array([lo - 1e-6])).any()


def test_compiled_planar_indices_match_the_metrics_composition():
    """`evaluate`'s one-pass kernel gives GM, GC (`device_indices`) and GM_T (`teleoperation_index`) to round-off."""
    from rhi.design import penalize, teleoperation_index
    from rhi.design.planar import planar_indices

    prob = ch4.setup.problem("full", density=40)
    rng = np.random.default_rng(3)
    lo, hi = (np.array([b[i] for b in prob.bounds.values()]) for i in (0, 1))
    for x in [rng.uniform(lo, hi) for _ in range(12)] + [np.array([0.25, 0.3, -0.1])]:
        sol = prob.solve(x)
        ok = sol.ok & prob.slave.ok
        if not ok.any():
            continue
        Jm = penalize(sol.J, sol.q, sol.q_min, sol.q_max, prob.k_q)
        Js = prob._slave_Jq
        Jm[0] = 0.0  # a zero Jacobian (μ = 1/κ = λ = 0) and a singular one (a lost axis)
        Jm[1, 1] = 2.0 * Jm[1, 0]
        want = device_indices(Jm, ok, prob.workspace.weights)
        got = planar_indices(Jm, Js, ok, prob.workspace.weights)
        for k in ("GM", "GC", "coverage"):
            assert got[k] == pytest.approx(want[k], rel=1e-13, abs=1e-16)
        assert got["GM_T"] == pytest.approx(teleoperation_index(Jm, Js, ok, prob.workspace.weights), rel=1e-13)
    with pytest.raises(InvalidInput, match="J_master"):
        planar_indices(np.zeros((3, 3, 2)), np.zeros((3, 2, 2)), np.ones(3, bool), np.ones(3))
    with pytest.raises(InvalidInput, match="J_master"):
        planar_indices(np.full((3, 2, 2), np.nan), np.zeros((3, 2, 2)), np.ones(3, bool), np.ones(3))
    with pytest.raises(InvalidInput, match="ok/weights"):
        planar_indices(np.zeros((3, 2, 2)), np.zeros((3, 2, 2)), np.ones(2, bool), np.ones(3))
    with pytest.raises(Unreachable):
        planar_indices(np.zeros((3, 2, 2)), np.zeros((3, 2, 2)), np.zeros(3, bool), np.ones(3))


def test_bad_bounds_raise_clear_errors():
    with pytest.raises(InfeasibleLimits, match="theta_z"):
        check_bounds({"theta_z": (1.0, -1.0)})
    with pytest.raises(InvalidInput, match="link length"):
        check_bounds({"l2": (0.0, 0.3)})
    with pytest.raises(InvalidInput, match="link length"):
        ch4.setup.problem("full").__class__(Phantom3Master(), ch4.setup.problem("theta_z", density=20).workspace,
                                      ch4.setup.problem("theta_z", density=20).slave, (0.424, 0), "auto",
                                      {"l2": (-0.1, 0.2)})
    with pytest.raises(InfeasibleLimits):
        rectangle((0.5, 0.3), (-0.1, 0.1))
    with pytest.raises(InvalidInput, match="finite"):
        check_bounds({"z_ph": (-np.inf, 0.1)})
    prob = ch4.setup.problem("theta_z", density=20)
    with pytest.raises(InvalidInput, match=r"fixed\['l2'\].*link length"):
        dataclasses.replace(prob, fixed={"l2": 0.0, "z_ph": 0.0539})
    with pytest.raises(InvalidInput, match="l2"):
        Phantom3Master().solve({"l2": -0.1}, np.zeros((1, 2)))


def test_workspace_out_of_reach_raises():
    far = rectangle((3.0, 3.2), (-0.1, 0.1), density=20)
    with pytest.raises(Unreachable, match="slave"):
        DesignProblem(Phantom3Master(), far, slave_solution("rehab_slave", far.points, ch4.setup.SLAVE_Q0), (3.1, 0),
                      "auto", {"theta_z": (-1, 1)})
    prob = ch4.setup.problem("theta_z", density=20)
    high = dataclasses.replace(prob, fixed={"l2": 0.165, "z_ph": 0.19})  # plane above the HI's reach
    with pytest.raises(Unreachable, match="every workspace sample"):
        evaluate_strict(high, [0.0])
    with pytest.raises(Unreachable):
        device_indices(np.zeros((3, 2, 2)), np.zeros(3, bool), np.ones(3))
    # the optimiser refuses to return an "optimum" that reaches nothing: every Z_PH in the bounds is above reach
    out_of_reach = dataclasses.replace(prob, bounds={"z_ph": (0.5, 0.6)}, fixed={"l2": 0.165, "theta_z": 0.0})
    with pytest.raises(Unreachable, match="no design within the bounds"):
        optimize(out_of_reach, "C2", maxiter=2, popsize=4, refine=False)


def test_pool_equals_serial_and_resume(tmp_path):
    prob = ch4.setup.problem("theta_z", density=30)
    xs = [[t] for t in np.linspace(-1.5, 1.5, 12)]
    ref = sweep(prob, xs, executor=SerialExecutor())
    with PoolExecutor(2) as ex:
        assert sweep(prob, xs, executor=ex) == ref
    # interrupted after the first batch, then resumed from the checkpoint
    path = tmp_path / "ck.json"

    def stop(done, total):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        sweep(prob, xs, checkpoint=str(path), batch=4, progress=stop)
    assert len(EvalCache(path, "sweep|" + __import__("rhi.design.optimize", fromlist=["_tag"])._tag(prob, ""))) == 4
    assert sweep(prob, xs, checkpoint=str(path), batch=4) == ref


def test_optimizer_gives_the_same_optimum_on_the_pool():
    prob = ch4.setup.problem("full", density=20)
    a = optimize(prob, "C2", seed=3, maxiter=4, popsize=5)
    with PoolExecutor(2) as ex:
        b = optimize(prob, "C2", seed=3, maxiter=4, popsize=5, executor=ex)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.values == b.values and a.evaluations == b.evaluations
    # the refinement polishes up to `starts` distinct regions and keeps the best: never worse than DE's optimum
    assert a.values["C2"] >= evaluate(prob, a.x_global)["C2"]
    with pytest.raises(InvalidInput, match="starts"):
        optimize(prob, "C2", starts=0)


def test_optimizer_is_seeded_and_resumes(tmp_path):
    prob = ch4.setup.problem("theta_z", density=30)
    a = optimize(prob, "C2", seed=1, maxiter=8, checkpoint=str(tmp_path / "o.json"))
    b = optimize(prob, "C2", seed=1, maxiter=8, checkpoint=str(tmp_path / "o.json"))
    np.testing.assert_array_equal(a.x, b.x)
    assert a.values == b.values and a.evaluations == b.evaluations


def test_nelder_mead_starts_in_lockstep_equal_one_after_another(monkeypatch):
    """The refinement's starts run together, each round's designs one `evaluate_many` batch: the same polished designs."""
    opt = importlib.import_module("rhi.design.optimize")  # the module (rhi.design.optimize is also its function)
    prob = ch4.setup.problem("full", density=20)
    lo, hi = (np.array([b[i] for b in prob.bounds.values()]) for i in (0, 1))
    x0s = list(lo + (hi - lo) * np.random.default_rng(4).uniform(size=(3, len(lo))))
    ref = [opt._nelder_mead(prob, "C2", x0) for x0 in x0s]
    sizes: list[int] = []
    many = opt.evaluate_many

    def counted(problem, xs):
        sizes.append(len(xs))
        return many(problem, xs)

    monkeypatch.setattr(opt, "evaluate_many", counted)
    assert opt._nelder_mead_many(prob, "C2", x0s) == ref
    assert sum(sizes) == sum(r["nfev"] for r in ref) and max(sizes) == 3  # the three starts in each early round
    assert len(sizes) == max(r["nfev"] for r in ref)

    def fails(problem, xs):  # the fifth round fails: every run stops with its error, none hangs
        if len(sizes) == 4:
            raise InvalidInput("x: broken")
        sizes.append(len(xs))
        return many(problem, xs)

    sizes.clear()
    monkeypatch.setattr(opt, "evaluate_many", fails)
    with pytest.raises(InvalidInput, match="broken"):
        opt._nelder_mead_many(prob, "C2", x0s)


def test_parallel_map_runs_anywhere_in_order_with_progress():
    from rhi.design.executors import parallel_map

    prob = ch4.setup.problem("theta_z", density=20)
    xs = [np.array([t]) for t in np.linspace(-1.5, 1.5, 5)]
    ref = [evaluate(prob, x) for x in xs]
    fn = functools.partial(evaluate, prob)
    for kw in ({"executor": "serial"}, {"workers": 1}, {"executor": SerialExecutor()}):
        ticks = []
        assert parallel_map(fn, xs, progress=lambda k, n, ticks=ticks: ticks.append((k, n)), units=[2] * 5, **kw) == ref
        assert ticks == [(2 * (i + 1), 10) for i in range(5)]
    with PoolExecutor(2) as ex:
        assert parallel_map(fn, xs, executor=ex) == ref
        assert list(ex.imap(fn, xs)) == ref
    with pytest.raises(InvalidInput, match="units"):
        parallel_map(fn, xs, workers=1, units=[1])
    with pytest.raises(InvalidInput, match="workers"):
        parallel_map(fn, xs, workers=0)
    with pytest.raises(InvalidInput, match="executor"):
        parallel_map(fn, xs, executor="threads")
    with pytest.raises(InvalidInput, match="executor"):
        parallel_map(fn, xs, executor=object())


def test_ray_matches_local_pool():
    pytest.importorskip("ray")
    from rhi.design import RayExecutor
    from rhi.design.executors import parallel_map

    prob = ch4.setup.problem("theta_z", density=30)
    xs = [[t] for t in np.linspace(-1.5, 1.5, 8)]
    with PoolExecutor(2) as ex:
        ref = sweep(prob, xs, executor=ex)
    with RayExecutor(workers=2) as ex:
        got = sweep(prob, xs, executor=ex)
        streamed = parallel_map(functools.partial(evaluate, prob), [np.array(x) for x in xs], executor=ex)
    assert got == ref
    assert streamed == ref


@pytest.mark.parametrize("kind", ["theta_z", "full"])
def test_population_as_one_batch_equals_design_by_design(kind):
    """evaluate_many (one (P, N) IK pass, one compiled index call) gives evaluate's numbers bit for bit."""
    from rhi.design.cost import evaluate_many
    from rhi.design.planar import planar_indices_many
    from rhi.experiments.ch4.setup import problem

    p = problem(kind, density=40.0)
    lo, hi = (np.array([b[i] for b in p.bounds.values()]) for i in (0, 1))
    X = lo + (hi - lo) * np.random.default_rng(3).uniform(size=(40, len(lo)))
    if kind == "full":
        X[0] = hi + 10.0  # l2 and Z_PH 10 m beyond their bounds: reaches no sample, scores 0
    got = evaluate_many(p, X)
    assert got == [evaluate(p, x) for x in X]
    assert (got[0]["coverage"] == 0.0) == (kind == "full") and got[1]["coverage"] > 0.0
    Jm = np.zeros((2, 4, 2, 3))
    with pytest.raises(Unreachable, match="workspace"):
        planar_indices_many(Jm, np.zeros((4, 2, 2)), np.array([[True] * 4, [False] * 4]), np.ones(4))
    with pytest.raises(InvalidInput, match="ok/weights"):
        planar_indices_many(Jm, np.zeros((4, 2, 2)), np.ones((2, 3), bool), np.ones(4))


def test_a_bad_ray_address_fails_at_once_with_one_line(monkeypatch, tmp_path, capsys):
    """`--executor ray --address` is checked before any work: malformed, nothing listening, or without ray."""
    from rhi.cli import main
    from rhi.design import executors as ex

    monkeypatch.setattr(ex, "DEFAULTS", dict(ex.DEFAULTS))  # configure() must not leak into other tests
    with socket.socket() as s:  # a port where nothing listens (bound, then closed)
        s.bind(("127.0.0.1", 0))
        closed = f"127.0.0.1:{s.getsockname()[1]}"
    for extra, want in ((["--executor", "ray", "--address", "bogus"], "address: expected 'auto', 'host:port'"),
                        (["--executor", "ray", "--address", closed], f"address: no Ray cluster answers at {closed!r}"),
                        (["--executor", "ray", "--address", f"ray://{closed}"], "no Ray cluster answers"),
                        (["--address", closed], "address: a Ray cluster address is for executor 'ray', not 'local'")):
        assert main(["reproduce", "--only", "ch3", "--quick", "--out", str(tmp_path / "r"), *extra]) == 2, extra
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and want in err[0], (extra, err)
    assert not (tmp_path / "r").exists()  # nothing started
    assert ex.DEFAULTS["executor"] == "local"  # a refused configure() sets nothing
