"""Property-based damage to robot descriptions (issue 24): generated mutations of a valid URDF and a valid MJCF.

Each example loads a mutated file and must end in an `rhi.errors` error naming the file (the loader's ``path``
argument) or in a valid device, never in a foreign exception or a hang (an alarm bounds each load).
"""

from __future__ import annotations

import signal
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from bad_values import examples
from hypothesis import given, strategies as st

import rhi
from rhi.devices._description_checks import MAX_JOINTS
from rhi.errors import ModelError, RhiError

_INERTIAL = '<inertial><mass value="1.0"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
_LIMIT = '<limit effort="2" velocity="1" lower="-2" upper="2"/>'


def _joint(name: str, parent: str, child: str, x: float) -> str:
    return (f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{x} 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/>{_LIMIT}<dynamics damping="0.1"/></joint>')


URDF = ('<robot name="arm">' + "".join(f'<link name="l{i}">{_INERTIAL if i else ""}</link>' for i in range(4))
        + _joint("j1", "l0", "l1", 0.0) + _joint("j2", "l1", "l2", 0.3) + _joint("j3", "l2", "l3", 0.3) + "</robot>")


def _body(i: int, inner: str) -> str:
    return (f'<body name="b{i}" pos="{0.3 if i > 1 else 0} 0 0"><joint name="j{i}" type="hinge" axis="0 0 1" '
            f'range="-2 2" damping="0.1"/><geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="1"/>{inner}</body>')


MJCF = ('<mujoco model="arm"><compiler angle="radian"/><worldbody>'
        + _body(1, _body(2, _body(3, '<site name="tip" pos="0.3 0 0"/>'))) + '</worldbody><actuator>'
        + "".join(f'<motor joint="j{i}" gear="1" ctrlrange="-2 2" ctrllimited="true"/>' for i in (1, 2, 3))
        + "</actuator></mujoco>")

BAD_NUMBERS = st.sampled_from(["nan", "inf", "-inf", "", "abc", "1e400", "-1", "0", "1 2", "NaN 0 0", "1e308 1e308 1e308"])
NAMES = st.sampled_from(["l0", "l1", "l2", "l3", "j1", "j2", "nope", "", "b1", "b2", "tip", "inf"])


class _Hang(Exception):
    pass


def _alarm(signum, frame):
    raise _Hang


def _mutate(draw, text: str) -> str:
    """One generated mutation of XML `text`.

    An attribute's value, a removed or doubled element, a renamed reference, or the text cut short.
    """
    root = ET.fromstring(text)
    elems = list(root.iter())
    kind = draw(st.sampled_from(["attribute", "name", "remove", "double", "cut", "extra_chain"]), label="mutation")
    if kind == "cut":
        return text[:draw(st.integers(0, len(text) - 1), label="cut at")]
    if kind == "extra_chain":  # a chain longer than the documented limit
        if root.tag == "robot":
            n = MAX_JOINTS + 1
            extra = "".join(f'<link name="x{i}">{_INERTIAL}</link>' for i in range(n))
            extra += "".join(_joint(f"xj{i}", "l3" if i == 0 else f"x{i - 1}", f"x{i}", 0.1) for i in range(n))
            return text.replace("</robot>", extra + "</robot>")
        inner = '<site name="far"/>'
        for i in range(MAX_JOINTS + 1, 3, -1):
            inner = _body(i, inner)
        return text.replace('<site name="tip" pos="0.3 0 0"/>', '<site name="tip" pos="0.3 0 0"/>' + inner)
    elem = draw(st.sampled_from(elems[1:]), label="element")
    if kind == "attribute" and elem.attrib:
        attr = draw(st.sampled_from(sorted(elem.attrib)), label="attribute")
        elem.set(attr, draw(BAD_NUMBERS, label="value"))
    elif kind == "name" and elem.attrib:
        attr = draw(st.sampled_from(sorted(elem.attrib)), label="attribute")
        elem.set(attr, draw(NAMES, label="value"))
    elif kind in ("remove", "double"):
        parent = next(p for p in root.iter() if elem in list(p))
        if kind == "remove":
            parent.remove(elem)
        else:
            parent.append(ET.fromstring(ET.tostring(elem)))
    return ET.tostring(root, encoding="unicode")


def _load(fn, path: Path, ee_frame: str):
    """fn(path, ee_frame=...) under a 120 s alarm: a device, or the rhi error (anything else fails the test)."""
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(120)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return fn(path, ee_frame=ee_frame, task="xy")
    except RhiError as exc:
        return exc
    except _Hang:
        pytest.fail(f"{path.name}: the loader did not return within 120 s")
    except Exception as exc:  # noqa: BLE001 - the point of the suite
        pytest.fail(f"foreign {type(exc).__name__}: {exc}\n{path.read_text()[:2000]}")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _check(out, path: Path) -> None:
    if isinstance(out, RhiError):
        assert str(path) in str(out) or str(out).startswith(("ee_frame", "torque_max", "inertia")), out
        return
    assert isinstance(out, rhi.Device) and out.n >= 1
    q = np.clip(np.zeros(out.n), out.q_min, out.q_max)
    assert np.isfinite(out.fk(q)).all() and np.isfinite(out.mass_matrix(q)).all()


@pytest.mark.parametrize("fn,text,suffix,ee", [(rhi.device_from_urdf, URDF, "urdf", "l3"),
                                               (rhi.device_from_mjcf, MJCF, "xml", "tip")])
def test_the_valid_descriptions_load(fn, text, suffix, ee, tmp_path):
    path = tmp_path / f"arm.{suffix}"
    path.write_text(text)
    assert _load(fn, path, ee).n == 3


@examples(150)
@given(data=st.data())
def test_urdf_loader_on_generated_damage(data, tmp_path_factory):
    path = tmp_path_factory.mktemp("urdf") / "arm.urdf"
    path.write_text(_mutate(data.draw, URDF))
    _check(_load(rhi.device_from_urdf, path, data.draw(st.one_of(st.just("l3"), NAMES), label="ee_frame")), path)


@examples(100)
@given(data=st.data())
def test_mjcf_loader_on_generated_damage(data, tmp_path_factory):
    path = tmp_path_factory.mktemp("mjcf") / "arm.xml"
    path.write_text(_mutate(data.draw, MJCF))
    _check(_load(rhi.device_from_mjcf, path, data.draw(st.one_of(st.just("tip"), NAMES), label="ee_frame")), path)


@pytest.mark.parametrize("edit,match", [
    (lambda t: t.replace('<parent link="l1"/>', '<parent link="lx"/>'), r"<joint name='j2'>: <parent link='lx'>: no link"),
    (lambda t: t.replace("</robot>", _joint("j4", "l3", "l1", 0.1) + "</robot>"), r"'l1'.*already the child of joint 'j1'"),
    (lambda t: t.replace("</robot>", '<link name="l2"/></robot>'), r"<link name='l2'>: the name is used twice"),
    (lambda t: t.replace("</robot>", f'<link name="l9">{_INERTIAL}</link></robot>'), r"2 root links \('l0', 'l9'\)"),
    (lambda t: t.replace('<origin xyz="0.3 0 0"', '<origin xyz="nan 0 0"', 1), r"<joint name='j2'> <origin>: attribute xyz"),
    (lambda t: t.replace('<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>', "", 1),
     r"link 'l1' <inertia>: a point mass .*inertia=\"fill\""),
    (lambda t: t.replace('<link name="l1">', '<link name="l1"><visual><geometry><mesh filename="m/x.stl"/></geometry>'
                                             "</visual>"), r"<link name='l1'> <mesh filename='m/x.stl'>: no file"),
    (lambda t: t.replace('name="j3"', 'name="l3"'), r"ee_frame: 'l3' names 2 frames"),
])
def test_urdf_errors_name_the_file_and_the_element(edit, match, tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(edit(URDF))
    with pytest.raises(ModelError, match=match) as info:
        rhi.device_from_urdf(path, ee_frame="l3", task="xy")
    assert "ee_frame" in str(info.value) or str(path) in str(info.value)


def test_mjcf_nan_pose_and_missing_file_name_the_file(tmp_path):
    path = tmp_path / "arm.xml"
    path.write_text(MJCF.replace('<body name="b2" pos="0.3 0 0"', '<body name="b2" pos="nan 0 0"'))
    with pytest.raises(ModelError, match=rf"{path}: <body name='b2'>: attribute pos='nan 0 0' must be finite"):
        rhi.device_from_mjcf(path, ee_frame="tip")
    with pytest.raises(ModelError, match=rf"{tmp_path / 'no.xml'}: file does not exist"):
        rhi.device_from_mjcf(tmp_path / "no.xml", ee_frame="tip")

