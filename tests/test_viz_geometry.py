"""Visual geometry of the MuJoCo models (MjSpec), user URDF meshes, `rhi render` and its pixels."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

import rhi
from rhi.errors import InvalidInput
from rhi.sim import Plant
from rhi.sim.mobile import MobilePlant
from rhi.viz.posed import Posed, rest_configuration

SRC = str(Path(__file__).resolve().parents[1] / "src")


@pytest.mark.parametrize("name", [n for n in rhi.available_devices() if n != "wmm"])
def test_visual_geometry_is_massless_and_changes_no_dynamics(name):
    dev = rhi.device(name)
    bare, vis = Plant(dev, visual=False), Plant(dev)
    assert bare.model.ngeom == 0 and vis.model.ngeom >= 2 * dev.n
    assert np.all(vis.model.geom_contype == 0) and np.all(vis.model.geom_conaffinity == 0)
    for f in ("body_mass", "body_inertia", "body_ipos", "tendon_armature", "tendon_damping", "tendon_frictionloss",
              "tendon_range", "actuator_ctrlrange", "eq_data"):
        np.testing.assert_array_equal(getattr(vis.model, f), getattr(bare.model, f), err_msg=f)
    q0 = rest_configuration(dev)
    rng = np.random.default_rng(3)
    taus = rng.uniform(0.2 * dev.torque_min, 0.2 * dev.torque_max, size=(200, dev.n))
    out = []
    for p in (bare, vis):
        p.reset(q0)
        for tau in taus:
            p.apply(tau)
            p.step()
        out.append(np.r_[p.q, p.dq, p.ft()])
    np.testing.assert_array_equal(out[0], out[1])


def test_collision_geometry_on_request(rhi4):
    m = Plant(rhi4, collision=True).model
    assert np.all(m.geom_contype == 1) and np.all(m.geom_conaffinity == 1)


def test_links_are_capsules_of_the_real_lengths(rhi4):
    m = Plant(rhi4).model
    caps = m.geom_type == mujoco.mjtGeom.mjGEOM_CAPSULE
    lengths = 2 * m.geom_size[caps, 1]
    placements = [np.linalg.norm(rhi4.model.jointPlacements[j].translation) for j in range(2, rhi4.model.njoints)]
    for L in placements:
        if L > 1e-3:
            assert np.any(np.isclose(lengths, L, atol=1e-9)), (L, lengths)


def test_wmm_has_mecanum_base_wheels_and_floor():
    p = MobilePlant()
    m = p.model
    wheels = (m.geom_type == mujoco.mjtGeom.mjGEOM_CYLINDER) & np.isclose(m.geom_size[:, 0], 0.0762)
    assert wheels.sum() == 4
    assert (m.geom_type == mujoco.mjtGeom.mjGEOM_PLANE).sum() == 1
    bare = MobilePlant(visual=False)
    np.testing.assert_array_equal(m.body_mass[: bare.model.nbody], bare.model.body_mass)


def _mesh_urdf(tmp_path: Path) -> Path:
    import trimesh

    pkg = tmp_path / "mypkg"
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "package.xml").write_text("<package><name>mypkg</name></package>")
    trimesh.creation.box(extents=[0.3, 0.04, 0.04]).export(pkg / "meshes" / "link.stl")
    inertial = ('<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
                "</inertial>")
    urdf = tmp_path / "two.urdf"
    urdf.write_text(f"""<robot name="two">
<link name="base"><visual><geometry><box size="0.1 0.1 0.05"/></geometry></visual></link>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.05"/><axis xyz="0 0 1"/>
<limit lower="-3" upper="3" effort="5" velocity="1"/></joint>
<link name="l1">{inertial}<visual><origin xyz="0.15 0 0"/>
<geometry><mesh filename="package://mypkg/meshes/link.stl"/></geometry></visual></link>
<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.3 0 0"/><axis xyz="0 0 1"/>
<limit lower="-3" upper="3" effort="5" velocity="1"/></joint>
<link name="l2">{inertial}<visual><origin xyz="0.1 0 0"/>
<geometry><mesh filename="mypkg/meshes/link.stl" scale="0.66 1 1"/></geometry></visual></link>
<joint name="ee" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.2 0 0"/></joint><link name="tip"/>
</robot>""")
    return urdf


def test_user_urdf_meshes_package_and_relative_paths(tmp_path):
    dev = rhi.device_from_urdf(_mesh_urdf(tmp_path), ee_frame="tip", task="xy")
    posed = Posed(dev)
    m = posed.model
    meshes = np.flatnonzero(m.geom_type == mujoco.mjtGeom.mjGEOM_MESH)
    assert len(meshes) == 2 and m.nmesh == 2
    posed.set([0.0, 0.0])
    # the package:// mesh spans 0..0.3 m along x; the relative one (0.198 m long after its 0.66 scale,
    # centred 0.1 m beyond the second joint at 0.3 m) 0.301..0.499 m
    spans = []
    for g in meshes:
        i = m.geom_dataid[g]
        V = m.mesh_vert[m.mesh_vertadr[i]: m.mesh_vertadr[i] + m.mesh_vertnum[i]]
        R = posed.data.geom_xmat[g].reshape(3, 3)
        W = posed.data.geom_xpos[g] + V @ R.T
        spans.append((W[:, 0].min(), W[:, 0].max()))
    np.testing.assert_allclose(sorted(spans), [(0.0, 0.3), (0.301, 0.499)], atol=1e-6)
    assert (m.geom_type == mujoco.mjtGeom.mjGEOM_BOX).sum() == 1  # the base's <box>


def test_user_urdf_without_visuals_gets_capsules(tmp_path):
    from rhi.devices.model import MODELS

    dev = rhi.device_from_urdf(MODELS / "planar3r" / "planar3r.urdf", ee_frame="tip", task="xy", torque_max=1.0)
    m = Posed(dev).model
    assert (m.geom_type == mujoco.mjtGeom.mjGEOM_CAPSULE).sum() >= 3


def test_posed_rejects_bad_q(rhi4):
    with pytest.raises(InvalidInput, match="q"):
        Posed(rhi4).set([0.0, 1.0])


def _render_or_skip(dev, q, **kw):
    from rhi.viz.render import RenderUnavailable, render

    try:
        return render(dev, q, **kw)
    except RenderUnavailable as exc:
        if os.environ.get("CI"):
            raise
        pytest.skip(f"no OpenGL backend here: {exc}")


@pytest.mark.parametrize("name", ["rhi4", "gen3"])
def test_render_shows_the_device(name):
    dev = rhi.device(name)
    posed = Posed(dev)
    q = rest_configuration(dev)
    img = _render_or_skip(posed, q, width=320, height=240)
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8
    posed.model.geom_rgba[:, 3] = 0.0  # the same picture without the device
    empty = _render_or_skip(posed, q, width=320, height=240)
    device_px = np.abs(img.astype(int) - empty.astype(int)).sum(axis=-1) > 40
    assert 0.005 < device_px.mean() < 0.6
    orange = (img[..., 0] > 180) & (img[..., 1] > 80) & (img[..., 1] < 170) & (img[..., 2] < 90)
    assert orange.sum() > 10  # the handle
    assert empty[-30:].astype(float).mean(axis=-1).std() > 3.0  # a checker floor, not the sky's smooth gradient


def test_renders_stand_on_a_floor(rhi4):
    """MuJoCo's pictures and videos get the browser's floor: a checker plane under the lowest point drawn."""
    from rhi.sim.geometry import FLOOR_MATERIAL
    from rhi.viz.posed import FLOOR_GAP
    from rhi.viz.render import RenderUnavailable, frames

    posed = Posed(rhi4)
    Q = np.array([rest_configuration(rhi4), [0.3, 1.2, -0.4, 0.9]])
    lowest, seen = [], []
    for q in Q:
        posed.set(q)
        lowest.append(posed.bounds()[0][2])

    def look(scene, i):
        planes = [scene.geoms[k] for k in range(scene.ngeom) if scene.geoms[k].type == mujoco.mjtGeom.mjGEOM_PLANE]
        seen.append([(float(g.pos[2]), int(g.matid)) for g in planes])

    try:
        list(frames(posed, Q, width=64, height=48, decorate=look))
    except RenderUnavailable as exc:
        if os.environ.get("CI"):
            raise
        pytest.skip(f"no OpenGL backend here: {exc}")
    grid = posed.model.material(FLOOR_MATERIAL).id
    assert seen == [[(pytest.approx(min(lowest) - FLOOR_GAP), grid)]] * 2
    wmm = Posed(rhi.device("wmm"))  # a model with a floor of its own keeps it, and only it
    assert wmm.floor() == pytest.approx(float(wmm.data.geom_xpos[wmm.model.geom_type == mujoco.mjtGeom.mjGEOM_PLANE][0, 2]))


_MJCF_ARM = """<mujoco>
 <asset><material name="red" rgba="0.8 0.1 0.1 1"/>
  <mesh name="tet" vertex="0 0 0  0.1 0 0  0 0.1 0  0 0 0.1"/></asset>
 <worldbody>
  <geom type="box" size=".1 .1 .02" pos="0 0 -0.05" rgba="0.2 0.6 0.2 1"/>
  <body name="a" pos="0 0 0.1" euler="0 0 0.2"><joint name="j1" type="hinge" axis="0 0 1" actuatorfrcrange="-5 5"/>
   <geom type="capsule" fromto="0 0 0 0.5 0 0" size=".03" material="red" mass="1"/>
   <body name="b" pos="0.5 0 0" euler="0 0 0.3"><joint name="j2" type="hinge" axis="0 0 1" pos="0.01 0 0"
     actuatorfrcrange="-5 5"/>
    <geom type="mesh" mesh="tet" pos="0.2 0 0" euler="0.3 0 0" rgba="0.1 0.1 0.8 1" mass="1"/>
    <geom type="sphere" size=".02" group="3" pos="0.1 0 0"/>
    <body name="c" pos="0.3 0 0"><geom type="cylinder" size=".02 .05" rgba="0.9 0.9 0.1 1" mass="0.1"/></body>
    <site name="tip" pos="0.4 0 0"/></body></body></worldbody></mujoco>"""


def test_user_mjcf_is_drawn_from_its_own_geoms(tmp_path):
    """An --mjcf robot is drawn as MuJoCo shows it (groups 0-2, in place, in its colours), not as a skeleton."""
    from rhi.sim.geometry import HANDLE_RGBA
    from rhi.viz.view import View

    path = tmp_path / "arm.xml"
    path.write_text(_MJCF_ARM)
    dev = rhi.device_from_mjcf(path, ee_frame="tip", task="xy")
    posed = Posed(dev)
    m, q = posed.model, np.array([0.4, -0.7])
    posed.set(q)
    mj = mujoco.MjModel.from_xml_path(str(path))
    md = mujoco.MjData(mj)
    md.qpos[:] = q
    mujoco.mj_kinematics(mj, md)
    drawn = [g for g in range(m.ngeom) if not np.allclose(m.geom_rgba[g], HANDLE_RGBA)]
    shown = [g for g in range(mj.ngeom) if mj.geom_group[g] <= 2]  # the group-3 sphere is left out
    assert len(drawn) == len(shown) == 4
    for g, h in zip(drawn, shown):
        assert m.geom_type[g] == mj.geom_type[h]
        np.testing.assert_allclose(posed.data.geom_xpos[g], md.geom_xpos[h], atol=1e-12)
        np.testing.assert_allclose(posed.data.geom_xmat[g], md.geom_xmat[h], atol=1e-12)
    np.testing.assert_allclose(m.geom_rgba[drawn], [[0.2, 0.6, 0.2, 1], [0.8, 0.1, 0.1, 1], [0.1, 0.1, 0.8, 1],
                                                    [0.9, 0.9, 0.1, 1]], atol=1e-7)  # the material's red
    mesh = drawn[2]
    i, k = m.geom_dataid[mesh], mj.geom_dataid[shown[2]]
    W = posed.data.geom_xpos[mesh] + m.mesh_vert[m.mesh_vertadr[i]:][:4] @ posed.data.geom_xmat[mesh].reshape(3, 3).T
    Wj = md.geom_xpos[shown[2]] + mj.mesh_vert[mj.mesh_vertadr[k]:][:4] @ md.geom_xmat[shown[2]].reshape(3, 3).T
    np.testing.assert_allclose(np.sort(W, axis=0), np.sort(Wj, axis=0), atol=1e-9)  # the tetrahedron in place
    v = View(dev, None, port=0)  # the browser draws the same parts in the same colours
    try:
        colours = {tuple(h.color) for name, h in v.scene.meshes.items() if "/g" in name}
        assert {tuple(int(round(255 * float(c))) for c in m.geom_rgba[g, :3]) for g in drawn} <= colours, colours
    finally:
        v.close()


def test_render_rejects_bad_size(rhi4):
    from rhi.viz.render import render

    with pytest.raises(InvalidInput, match="width"):
        render(rhi4, rest_configuration(rhi4), width=3)


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-c", "import sys; from rhi.cli import main; sys.exit(main())", *args],
                          capture_output=True, text=True, env={**os.environ, "PYTHONPATH": SRC, **(env or {})},
                          timeout=120)


def test_cli_render_writes_png(tmp_path):
    out = tmp_path / "rhi4.png"
    r = _cli("render", "rhi4", "--q", "0.1,0.3,0.5,0.2", "-o", str(out), "--width", "200", "--height", "150")
    if r.returncode != 0 and "MUJOCO_GL" in r.stderr and not os.environ.get("CI"):
        pytest.skip("no OpenGL backend here")
    assert r.returncode == 0, r.stderr
    from PIL import Image

    assert Image.open(out).size == (200, 150)


def test_cli_render_names_mujoco_gl_without_a_backend(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    env["MUJOCO_GL"] = "glfw"  # needs a display, which a test machine has not
    r = subprocess.run([sys.executable, "-c", "import sys; from rhi.cli import main; sys.exit(main())", "render",
                        "rhi4", "-o", str(tmp_path / "x.png")], capture_output=True, text=True,
                       env={**env, "PYTHONPATH": SRC}, timeout=120)
    assert r.returncode == 2
    assert "MUJOCO_GL" in r.stderr and "osmesa" in r.stderr


def test_report_render_grid_and_its_line_fallback(monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    from rhi.plots import renders
    from rhi.viz.render import RenderUnavailable

    dev = rhi.device("rhi4")
    panels = [("a", dev, rest_configuration(dev)), ("b", dev, rest_configuration(dev) + 0.1)]
    try:
        renders.render(dev, rest_configuration(dev), width=16, height=16)
        gl = True
    except RenderUnavailable:
        gl = bool(os.environ.get("CI"))  # CI must have one: then the grid below fails loudly
    if gl:
        fig = renders._grid(panels, "t")
        assert len(fig.axes[0].images) == 1 and fig.axes[0].images[0].get_array().shape == (420, 560, 3)

    def no_gl(*a, **k):
        raise RenderUnavailable("no OpenGL backend for offscreen rendering (MUJOCO_GL=''); set MUJOCO_GL=egl")

    monkeypatch.setattr(renders, "render", no_gl)
    fig = renders._grid(panels, "t")
    assert "line drawing" in fig._suptitle.get_text() and len(fig.axes[1].lines) == 1


def _two_material_obj(path: Path) -> None:
    """An OBJ of two 0.15 m boxes along x (x in −0.15..0.15 m) in a red and a blue material (its own MTL)."""
    import trimesh

    boxes = [trimesh.creation.box(extents=[0.15, 0.04, 0.04]) for _ in range(2)]
    boxes[0].apply_translation([-0.075, 0.0, 0.0])
    boxes[1].apply_translation([0.075, 0.0, 0.0])
    lines = [f"mtllib {path.stem}.mtl"] + [f"v {x:.6f} {y:.6f} {z:.6f}" for b in boxes for x, y, z in b.vertices]
    for k, (b, mat) in enumerate(zip(boxes, ("red", "blue"))):
        lines.append(f"usemtl {mat}")
        lines += [f"f {' '.join(str(i + 1 + k * len(boxes[0].vertices)) for i in face)}" for face in b.faces]
    path.write_text("\n".join(lines) + "\n")
    path.with_suffix(".mtl").write_text("newmtl red\nKd 0.9 0.1 0.1\nnewmtl blue\nKd 0.1 0.2 0.9\n")


def test_user_meshes_are_drawn_in_their_own_colours(tmp_path):
    """A mesh's own materials colour its parts; a URDF colour wins; the browser's scene gets the same colours."""
    from rhi.viz.view import View

    _two_material_obj(tmp_path / "link.obj")
    inertial = ('<inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
                "</inertial>")
    urdf = tmp_path / "two.urdf"
    urdf.write_text(f"""<robot name="two">
<material name="green"><color rgba="0.1 0.7 0.2 1"/></material>
<link name="base"/>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
<limit lower="-3" upper="3" effort="5" velocity="1"/></joint>
<link name="l1">{inertial}<visual><origin xyz="0.15 0 0"/><geometry><mesh filename="link.obj"/></geometry></visual></link>
<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.3 0 0"/><axis xyz="0 0 1"/>
<limit lower="-3" upper="3" effort="5" velocity="1"/></joint>
<link name="l2">{inertial}<visual><origin xyz="0.15 0 0"/><geometry><mesh filename="link.obj"/></geometry>
<material name="green"/></visual></link>
<joint name="ee" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.3 0 0"/></joint><link name="tip"/>
</robot>""")
    dev = rhi.device_from_urdf(urdf, ee_frame="tip", task="xy")
    posed = Posed(dev)
    m = posed.model
    meshes = np.flatnonzero(m.geom_type == mujoco.mjtGeom.mjGEOM_MESH)
    colours = m.geom_rgba[meshes, :3]
    assert len(meshes) == 3
    for want in ([0.9, 0.1, 0.1], [0.1, 0.2, 0.9], [0.1, 0.7, 0.2]):  # red, blue, the URDF's green (8-bit materials)
        assert np.min(np.abs(colours - want).max(axis=1)) < 3e-3, colours
    posed.set([0.0, 0.0])
    red = meshes[np.argmax(m.geom_rgba[meshes, 0])]
    i = m.geom_dataid[red]
    V = m.mesh_vert[m.mesh_vertadr[i]: m.mesh_vertadr[i] + m.mesh_vertnum[i]]
    W = posed.data.geom_xpos[red] + V @ posed.data.geom_xmat[red].reshape(3, 3).T
    np.testing.assert_allclose([W[:, 0].min(), W[:, 0].max()], [0.0, 0.15], atol=1e-6)  # the red half, in place
    v = View(dev, None, port=0)
    try:
        drawn = {tuple(h.color) for name, h in v.scene.meshes.items() if "/g" in name}
        assert {tuple(int(round(255 * float(c))) for c in m.geom_rgba[g, :3]) for g in meshes} <= drawn, drawn
    finally:
        v.close()


def test_rhi4_is_drawn_with_its_parallelograms_on_a_floor():
    """The crank turns with the link it drives, the coupler stays parallel to the link before it: they close.

    The browser's scene and MuJoCo's renders draw them.
    """
    from rhi.viz.posed import CRANK, parallelograms
    from rhi.viz.render import add_linkages
    from rhi.viz.view import View

    assert parallelograms(rhi.device("rhi4")) == [(1, 2), (3, 4)]  # the Quanser arm's and the PHANToM's
    assert parallelograms(rhi.device("planar3r")) == [] and parallelograms(rhi.device("gen3")) == []
    dev = rhi.device("rhi4")
    v = View(dev, None, port=0)
    try:
        sc, posed = v.scene, v.posed
        body = [posed.model.body(f"b_theta{i}").id for i in range(1, 5)]
        assert len(sc.links) == 6 and sum("/link" in name for name in sc.meshes) == 6
        for q in ([0.3, 1.2, -0.4, 0.9], [1.0, 2.0, 0.5, 1.7]):
            snap = v._rest_snapshot()
            snap.q = np.array(q)
            v._draw(snap, force=True)
            d = posed.data
            segs = posed.linkages()
            after = [d.xpos[body[2]], d.xpos[posed.handle]]  # where links θ2 and θ4 end
            for k, (p, j) in enumerate(((0, 1), (2, 3))):
                O, P = d.xpos[body[p]], d.xpos[body[j]]
                crank, coupler, rear = segs[3 * k: 3 * k + 3]
                c = crank[1] - crank[0]
                link_j = after[k] - P
                np.testing.assert_allclose(crank[0], O, atol=1e-12)
                assert np.linalg.norm(c) == pytest.approx(CRANK * np.linalg.norm(P - O))
                assert np.dot(c, link_j) / np.linalg.norm(c) / np.linalg.norm(link_j) == pytest.approx(-1.0)
                np.testing.assert_allclose(coupler, [O + c, P + c], atol=1e-12)  # parallel to link p, closing
                np.testing.assert_allclose(rear, [P, P + c], atol=1e-12)
            for frame, (a, b) in zip(sc.links, segs):  # the browser's capsules sit on the segments
                np.testing.assert_allclose(frame.position, a, atol=1e-9)
                np.testing.assert_allclose(_rot(frame.wxyz)[:, 2], (b - a) / np.linalg.norm(b - a), atol=1e-9)
        scene = mujoco.MjvScene(posed.model, maxgeom=1000)
        mujoco.mjv_updateScene(posed.model, posed.data, mujoco.MjvOption(), None, mujoco.MjvCamera(),
                               mujoco.mjtCatBit.mjCAT_ALL, scene)
        n = scene.ngeom
        add_linkages(scene, posed)
        assert scene.ngeom == n + 6  # and in MuJoCo's renders (`rhi render`, videos)
        assert sc.floor < float(posed.bounds()[0][2])  # a floor under the device
    finally:
        v.close()


def _rot(wxyz) -> np.ndarray:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(wxyz, dtype=float))
    return R.reshape(3, 3)
