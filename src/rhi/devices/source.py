"""Which device: a bundled name, a URDF, an MJCF or an installed description, with its options as one table.

The table is what the `rhi` commands' device options (``rhi measure --urdf arm.urdf --ee-frame tool0``)
and a run configuration's ``[device]`` hold:

- exactly one source: ``name`` (a bundled device, `rhi.available_devices`, with ``params``), ``urdf``
  (a URDF or xacro file), ``mjcf`` (an MJCF file) or ``description`` (an installed description package's
  robot, `rhi.devices.loaders.available_descriptions`); with a file source ``name`` names the loaded device
  (default: the file's stem);
- with a file source: ``ee_frame`` (required), ``task`` (world axes, "xyz"), ``ee_offset`` (3,) [m],
  ``lock`` {joint: value [rad or m]}, ``armature`` [kg m²], ``torque_min`` / ``torque_max`` [N m],
  ``friction`` {``damping`` [N m s/rad], ``frictionloss`` [N m]}, each a scalar or one value per motor,
  and for URDF sources ``inertia`` ("strict" or "fill": point-mass links get a small documented inertia,
  with a warning naming them; `rhi.devices.loaders.device_from_urdf`).

Relative file paths are taken from `base` (a configuration's folder).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from rhi.devices.loaders import device_from_description, device_from_mjcf, device_from_urdf
from rhi.devices.model import Device, device
from rhi.errors import InvalidInput, RhiError

SOURCES = ("urdf", "mjcf", "description")
"""The file sources (a bundled device is ``name`` alone)."""
FILE_OPTIONS = ("ee_frame", "task", "ee_offset", "lock", "armature", "torque_min", "torque_max", "friction", "inertia")
"""The options of a file source (the loaders' keyword arguments)."""
KEYS = ("name", "params", *SOURCES, *FILE_OPTIONS)


def device_from_table(table: Mapping, *, base: Path | None = None, path: str = "device") -> Device:
    """The device `table` describes (see the module docstring); None values count as absent.

    Args:
        table: {key: value}.
        base: the folder relative file paths are taken from (default: the working directory).
        path: the table's name in messages (e.g. "device" for a configuration's ``[device]``).

    Raises:
        InvalidInput: an unknown key, no source or two, an option that does not fit the source (named
            as ``path.key``).
        UnknownDevice, ModelError: from the loaders, with ``path`` before the message.
    """
    t = {k: v for k, v in table.items() if v is not None}
    unknown = sorted(set(t) - set(KEYS))
    if unknown:
        raise InvalidInput(f"{path}.{unknown[0]}: unknown key (known: {', '.join(KEYS)})")
    sources = [k for k in SOURCES if k in t]
    if len(sources) > 1:
        raise InvalidInput(f"{path}: give one of {', '.join(SOURCES)}, got {' and '.join(sources)}")
    if not sources:
        if "name" not in t:
            raise InvalidInput(f"{path}: no device: give a bundled device's name or one of {', '.join(SOURCES)}")
        stray = [k for k in FILE_OPTIONS if k in t]
        if stray:
            raise InvalidInput(f"{path}.{stray[0]}: an option of a device loaded from a file ({', '.join(SOURCES)}); "
                               f"{t['name']!r} is a bundled device")
        return _call(path, "name", device, t["name"], **dict(t.get("params") or {}))
    src = sources[0]
    if t.get("params"):
        raise InvalidInput(f"{path}.params: design parameters are for bundled devices, not a {src} source")
    if "ee_frame" not in t:
        raise InvalidInput(f"{path}.ee_frame: missing (the end-effector link or frame of the {src})")
    if "inertia" in t and src == "mjcf":
        raise InvalidInput(f"{path}.inertia: for URDF sources (MuJoCo's compiler options inertiafromgeom and "
                           "balanceinertia serve an MJCF)")
    kw = {k: t[k] for k in FILE_OPTIONS if k in t}
    if "lock" in kw:
        kw["lock"] = dict(kw["lock"])
    if "friction" in kw:
        kw["friction"] = dict(kw["friction"])
    if "name" in t:
        kw["name"] = t["name"]
    if src == "description":
        return _call(path, src, device_from_description, t[src], **kw)
    f = Path(t[src]).expanduser()
    if not f.is_absolute() and base is not None:
        f = base / f
    if not f.is_file():
        raise InvalidInput(f"{path}.{src}: no file {str(f)!r}")
    return _call(path, src, device_from_urdf if src == "urdf" else device_from_mjcf, f, **kw)


def _call(path: str, src: str, fn, *args, **kwargs) -> Device:
    """fn(*args, **kwargs), its errors named by key path: "ee_frame: ..." → "device.ee_frame: ..."."""
    try:
        return fn(*args, **kwargs)
    except RhiError as exc:
        msg = str(exc)
        head, sep, rest = msg.partition(":")
        key = src if head in ("path", "robot", "name") else head
        known = key.split("[")[0] in KEYS
        raise type(exc)(f"{path}.{key}:{rest}" if sep and known else f"{path}: {msg}") from None


__all__ = ["FILE_OPTIONS", "KEYS", "SOURCES", "device_from_table"]
