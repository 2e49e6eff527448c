"""Run configurations: a TOML file describing a controller on a device, for `rhi run`.

A file holds these tables (every key optional unless marked; the shipped files in
``rhi/runtime/configs/`` are commented examples, `shipped_configs()` lists them):

- ``description``: one line about the set-up.
- ``[run]``: ``rate`` [Hz] (1000), ``duration`` [s] (none: until a fault or Ctrl-C).
- ``[device]``: ``name`` of a bundled device, ``params`` (its design parameters, e.g. ``{ d2 = 0.1405 }``);
  or your robot: ``urdf``, ``mjcf`` or ``description`` with ``ee_frame`` and optionally ``task``, ``ee_offset``,
  ``lock``, ``armature``, ``torque_min``, ``torque_max``, ``friction`` (``damping``, ``frictionloss``) and
  ``inertia`` = "fill" (`rhi.devices.source`; relative paths from the configuration's folder).
- ``[controller]`` (required): ``damping`` k_D [N m s/rad], ``saturation`` ("none", "scaling", "ascm", "lp",
  or a strategy registered with `rhi.control.allocation.register`),
  ``projector`` ("dynamic", "pseudoinverse"), ``torque_min``/``torque_max`` [N m],
  ``gravity_compensation``, ``aso_shape``, ``implementation``, ``null_space`` ("scaled", "clipped") — the fields
  of `rhi.control.ControllerConfig`; ``[controller.tank]`` (``initial``, ``capacity`` [J]) turns on the null-space
  energy tank (`rhi.control.tank`);
  ``[controller.primary]`` (required) with ``law`` = "impedance" | "force_rendering" | "spring" and that law's
  parameters (``damping``, ``coriolis``, ``gravity``, ``[controller.primary.friction]``, ...; the rendering
  laws take ``passivity`` = "motors" (default) | "handle" | "off", `rhi.control.passivity`);
  ``[[controller.objectives]]``, each with ``type`` = "vme" | "ellipsoid" | "fme" | "tmi" | "manipulability" |
  "joint_limits" (or any type registered with `rhi.control.registry`, whose keys it declares) or an installed
  plugin's type (`rhi.runtime.objective_plugins`), its parameters and its step ``gain``;
  ``[controller.fme]``: the ASO-switched desired-FME schedule (``free_direction``, ``contact_direction``, ``mu``,
  ``home``, ``gain``, ``[controller.fme.transition]`` eps1, eps2, rho, S).
- ``[[virtual]]``: the rendered environment, each with ``type`` = "wall" | "spring" | "fixture" | "stop".
- ``[sim]`` (for ``--link sim`` only): ``q0``, ``dq0``, ``friction`` ("device", "none" or a table), ``timestep``,
  ``handle_mass``, ``[sim.hand]`` (``path``, ``repeat`` (more traversals, back and forth), ``speed``, ``start``,
  ``stiffness``, ``damping``, ``max_force``),
  ``[[sim.physical]]`` (environments acting on the plant's handle).
- ``[safety]``: the fields of `rhi.runtime.SafetyConfig`.

Unknown keys and values of the wrong type raise `InvalidInput` naming the key path, and so do values
outside these plausibility bounds, checked against the device and physics when the file is read:
``[run]`` rate 10 Hz–100 kHz, duration ≤ 10⁶ s; ``[controller]`` torque limits within the device's, damping
≤ 100 N m s/rad, primary damping ≤ 10⁴ N s/m, force_rendering gain ≤ 100, spring stiffness ≤ 10⁶ N/m,
objective gains ≤ 10⁶, ``joint_limits`` margin ≤ π rad, ``ellipsoid`` and ``fme`` desired
matrices (m, m); ``[sim]`` q0 inside the joint ranges, |dq0| ≤ 10 rad/s, friction damping ≤ 100 N m s/rad and
frictionloss ≤ 100 N m, timestep ≤ 10 ms, hand repeat ≤ 1000, speed ≤ 5 m/s,
stiffness ≤ 10⁵ N/m, damping ≤ 10³ N s/m, max_force ≤ 1000 N; environments' stiffness ≤ 10⁶ N/m, damping ≤
10⁴ N s/m; ``[safety]`` stale_ticks ≤ 1000, frozen_ticks ≤ 10⁵, frozen_motion ≤ 0.1 rad, silence ≤ 1 s,
max_joint_speed ≤ 100 rad/s, range_margin ≤ 0.5 rad, max_handle_speed ≤ 10 m/s (a limit above these does
not guard anything). A document nested too deeply is refused as well.
"""

from __future__ import annotations

import dataclasses
import tomllib
import typing
from collections.abc import Iterator, Mapping
from importlib import resources
from pathlib import Path

import numpy as np

from rhi.control import (
    ControllerConfig,
    FMESchedule,
    ForceRendering,
    ImpedanceControl,
    JointFriction,
    NullSpaceController,
    NullSpaceTank,
    ObjectiveTerm,
    Passivity,
    SpringPalpation,
    TransitionConfig,
    desired_fme_free,
    desired_fme_stiff,
)
from rhi.control.allocation import method_names
from rhi.control.objectives import fme_axes
from rhi.control.registry import REQUIRED, Key, objective_type, objective_types
from rhi.devices.model import Device
from rhi.devices.source import SOURCES, device_from_table
from rhi.errors import InvalidInput, RhiError
from rhi.runtime import objective_plugins, schema as S
from rhi.runtime.objective_plugins import ObjectiveSpecs
from rhi.runtime.safety import SafetyConfig
from rhi.runtime.simlink import SimLink
from rhi.sim import Fixture, Hand, HandPath, Plant, PlantFriction, Spring, Wall, compose, stop

_num, _pos, _nonneg = S.number(), S.number(low=0.0, strict=True), S.number(low=0.0)
_stiff, _damp = S.number(low=0.0, high=1e6), S.number(low=0.0, high=1e4)  # of a rendered environment [N/m, N s/m]
_vec = S.vector()
_num_or_vec = S.either(_num, _vec, want="a number or a list of numbers")
_num_or_mat = S.either(_num, S.matrix, want="a number or a matrix (a list of equally long lists of numbers)")
R = S.REQUIRED

_FRICTION = {"viscous": (_num_or_vec, 0.0), "coulomb": (_num_or_vec, 0.0), "velocity_scale": (_pos, 0.01)}
_COMPENSATED = {"damping": (_num_or_mat, 0.0), "coriolis": (S.boolean, True), "gravity": (S.boolean, True),
                "friction": (S.table(_FRICTION), None)}
_PASSIVITY = S.choice("motors", "handle", "off")  # rhi.control.passivity port, or off (the thesis's laws)
_PRIMARY: dict[str, S.Spec] = {
    "impedance": {**_COMPENSATED, "inertia": (S.matrix, None), "sensor": (S.string, "ft")},
    "force_rendering": {**_COMPENSATED, "gain": (S.number(low=0.0, high=100.0), 1.0), "passivity": (_PASSIVITY, "motors")},
    "spring": {**_COMPENSATED, "stiffness": (_stiff, R), "x0": (_vec, R), "normal": (_vec, None),
               "passivity": (_PASSIVITY, "motors")},
}
_GAIN = {"gain": (S.number(low=0.0, high=1e6), R)}


def _check(key: Key) -> S.Check:
    """The schema check of a registered objective key (`rhi.control.registry.Key`)."""
    if key.kind == "number":
        return S.number(low=key.low, strict=key.strict, high=key.high)
    if key.kind == "choice":
        return S.choice(*key.options)
    return {"vector": _vec, "matrix": S.matrix, "boolean": S.boolean, "string": S.string,
            "numbers": S.numbers_table}[key.kind]


class _Registered(Mapping):
    """{type: spec} of the registered objective types (`rhi.control.registry`), read when asked."""

    def __getitem__(self, kind: str) -> S.Spec:
        t = objective_type(kind)
        if t is None:
            raise KeyError(kind)
        return {**_GAIN, **{k: (_check(key), S.REQUIRED if d is REQUIRED else d) for k, (key, d) in t.keys.items()}}

    def __iter__(self) -> Iterator[str]:
        return iter(objective_types())

    def __len__(self) -> int:
        return len(objective_types())


_OBJECTIVES = ObjectiveSpecs(_Registered(), _GAIN)  # and the installed plugins' types (rhi.objectives)
_TRANSITION = {"eps1": (_num, 0.7), "eps2": (_num, 0.95), "rho": (_num, 0.003), "S": (_num, 50.0)}
_FME = {"free_direction": (_vec, R), "contact_direction": (_vec, R), "mu": (_pos, 5.0), "home": (_vec, None),
        "gain": (_nonneg, 20.0), "transition": (S.table(_TRANSITION), {})}
_CONTROLLER = {
    "primary": (S.tagged("law", _PRIMARY), R),
    "objectives": (S.tables(S.tagged("type", _OBJECTIVES)), []),
    "fme": (S.table(_FME), None),
    "damping": (S.number(low=0.0, high=100.0), 0.1),
    "saturation": (S.one_of(lambda: tuple(sorted(method_names()))), "ascm"),  # every registered strategy
    "projector": (S.choice(*typing.get_args(typing.get_type_hints(ControllerConfig)["projector"])), "dynamic"),
    "torque_min": (_vec, None),
    "torque_max": (_vec, None),
    "gravity_compensation": (S.boolean, True),
    "aso_shape": (_pos, 50.0),
    "implementation": (S.choice(*typing.get_args(typing.get_type_hints(ControllerConfig)["implementation"])), "fast"),
    "null_space": (S.choice(*typing.get_args(typing.get_type_hints(ControllerConfig)["null_space"])), "scaled"),
    "tank": (S.table({"initial": (_nonneg, 0.0), "capacity": (_nonneg, 0.05)}), None),
}
_ENV = S.tagged("type", {
    "wall": {"point": (_vec, R), "normal": (_vec, R), "stiffness": (_stiff, R), "damping": (_damp, 0.0)},
    "spring": {"point": (_vec, R), "stiffness": (_stiff, R), "damping": (_damp, 0.0), "direction": (_vec, None)},
    "fixture": {"point": (_vec, R), "direction": (_vec, R), "stiffness": (_stiff, 1000.0), "damping": (_damp, 5.0)},
    "stop": {"point": (_vec, R), "normal": (_vec, R), "stiffness": (_stiff, 2.0e4), "damping": (_damp, 50.0)},
})
_HAND = {"path": (S.either(S.matrix, _vec, want="a point or a list of points"), R),
         "speed": (S.number(low=0.0, high=5.0), 0.0), "repeat": (S.integer(low=0, high=1000), 0),
         "start": (_nonneg, 0.0), "stiffness": (S.number(low=0.0, high=1e5), 300.0),
         "damping": (S.number(low=0.0, high=1e3), 10.0),
         "max_force": (S.either(S.number(low=0.0, strict=True, high=1e3), S.choice("none"),
                                want='a number > 0 and <= 1000 or "none"'), 20.0)}
_PLANT_LOSS = S.either(S.number(low=0.0, high=100.0), S.vector(low=0.0, high=100.0),
                       want="a number or a list of numbers, each >= 0 and <= 100 (plausibility bound)")
_PLANT_FRICTION = {"damping": (_PLANT_LOSS, 0.0), "frictionloss": (_PLANT_LOSS, 0.0)}
_SIM: S.Spec = {
    "q0": (_vec, None), "dq0": (_vec, None),
    "friction": (S.either(S.choice("device", "none"), S.table(_PLANT_FRICTION),
                          want='"device", "none" or a table with damping and frictionloss'), "device"),
    "timestep": (S.number(low=0.0, strict=True, high=0.01), 5e-4), "handle_mass": (_pos, 1e-3),
    "hand": (S.table(_HAND), None), "physical": (S.tables(_ENV), []),
}


#: The plausibility bounds of `[safety]` (module docstring): a limit above them guards nothing.
_SAFETY_MAX = {"stale_ticks": 1000, "frozen_ticks": 100000, "frozen_motion": 0.1, "silence": 1.0,
               "max_joint_speed": 100.0, "range_margin": 0.5, "max_handle_speed": 10.0}


def _safety(path: str, v) -> SafetyConfig:
    if not isinstance(v, dict):
        raise InvalidInput(f"{path}: expected a table of settings, got {v!r}")
    for k, x in v.items():
        _num_or_vec(f"{path}.{k}", x)
        if k in _SAFETY_MAX and np.any(np.asarray(x, dtype=float) > _SAFETY_MAX[k]):
            raise InvalidInput(f"{path}.{k}: expected <= {_SAFETY_MAX[k]:g} (plausibility bound), got {x!r}")
    try:
        return SafetyConfig.from_dict(v)
    except InvalidInput as exc:
        msg = str(exc)
        raise InvalidInput(msg if msg.startswith(path) else f"{path}.{msg}") from None


_ROOT = {
    "description": (S.string, ""),
    "run": (S.table({"rate": (S.number(low=10.0, high=1e5), 1000.0),
                     "duration": (S.number(low=0.0, strict=True, high=1e6), None)}), {}),
    "device": (S.table({"name": (S.string, None), "params": (S.numbers_table, {}), "urdf": (S.string, None),
                        "mjcf": (S.string, None), "description": (S.string, None), "ee_frame": (S.string, None),
                        "task": (S.string, None), "ee_offset": (_vec, None), "lock": (S.numbers_table, None),
                        "armature": (_num_or_vec, None), "torque_min": (_num_or_vec, None),
                        "torque_max": (_num_or_vec, None), "friction": (S.table(_PLANT_FRICTION), None),
                        "inertia": (S.choice("strict", "fill"), None)}), {}),
    "controller": (S.table(_CONTROLLER), R),
    "virtual": (S.tables(_ENV), []),
    "sim": (S.table(_SIM), {}),
    "safety": (_safety, {}),
}


# ------------------------------------------------------------------------------------------ building
def _dim(path: str, v: np.ndarray | None, shape: tuple[int, ...]) -> None:
    if v is not None and v.shape != shape:
        raise InvalidInput(f"{path}: expected shape {shape} for this device, got {v.shape}")


def _environment(path: str, e: dict, m: int):
    kind = e.pop("type")
    for key in ("point", "normal", "direction"):
        _dim(f"{path}.{key}", e.get(key), (m,))
    cls = {"wall": Wall, "spring": Spring, "fixture": Fixture}.get(kind)
    return S.prefixed(path, stop if cls is None else cls, **e)


def _environments(path: str, envs: list[dict], m: int):
    parts = [_environment(f"{path}[{i}]", dict(e), m) for i, e in enumerate(envs)]
    return None if not parts else parts[0] if len(parts) == 1 else compose(*parts)


def _primary(dev: Device, p: dict):
    p = dict(p)
    law = p.pop("law")
    if np.abs(np.asarray(p["damping"], dtype=float)).max() > 1e4:
        raise InvalidInput(f"controller.primary.damping: expected entries <= 1e4 N s/m (plausibility bound), got "
                           f"{np.asarray(p['damping']).tolist()!r:.80}")
    if p["friction"] is not None:
        p["friction"] = S.prefixed("controller.primary.friction", JointFriction, **p["friction"])
    if law == "spring":
        _dim("controller.primary.x0", p["x0"], (dev.m,))
        _dim("controller.primary.normal", p["normal"], (dev.m,))
    if "passivity" in p:
        p["passivity"] = None if p["passivity"] == "off" else Passivity(port=p["passivity"])
    cls = {"impedance": ImpedanceControl, "force_rendering": ForceRendering, "spring": SpringPalpation}[law]
    return S.prefixed("controller.primary", cls, **p)


def _objective(path: str, dev: Device, o: dict, hi: np.ndarray):
    """The objective of a ``[[controller.objectives]]`` table: a registered type (`rhi.control.registry`) or a plugin's."""
    kind = o["type"]
    t = objective_type(kind)
    if t is None:
        return objective_plugins.build(path, kind, dev, o)
    return S.keyed(path, t.keys, t.build, dev, hi, **{k: o[k] for k in t.keys})


def _controller(dev: Device, c: dict) -> ControllerConfig:
    lo, hi = c["torque_min"], c["torque_max"]
    _dim("controller.torque_max", hi, (dev.n,))
    _dim("controller.torque_min", lo, (dev.n,))
    if hi is not None and lo is None:
        lo = -hi
    for key, v, inside in (("torque_max", hi, lambda v: v <= dev.torque_max), ("torque_min", lo,
                                                                                lambda v: v >= dev.torque_min)):
        if v is not None and not inside(v).all():
            raise InvalidInput(f"controller.{key}: {v.tolist()} exceeds the device's limits {dev.torque_min.tolist()} "
                               f"to {dev.torque_max.tolist()} [N m]")
    t_hi = dev.torque_max if hi is None else hi
    terms = []
    for i, o in enumerate(c["objectives"]):
        path = f"controller.objectives[{i}]"
        obj = _objective(path, dev, o, t_hi)
        terms.append(S.prefixed(f"{path}.gain", ObjectiveTerm, obj, o["gain"]))
    if c["fme"] is not None:  # the ASO-scheduled FME matching (rhi.control.schedule), an objective term
        f = c["fme"]
        _dim("controller.fme.free_direction", f["free_direction"], (dev.m,))
        _dim("controller.fme.contact_direction", f["contact_direction"], (dev.m,))
        K, z = S.keyed("controller.fme", ("mu", "home"), fme_axes, dev, t_hi, f["mu"], f["home"])
        tc = S.prefixed("controller.fme.transition", TransitionConfig, **f["transition"])
        free = S.prefixed("controller.fme.free_direction", desired_fme_free, f["free_direction"], K, z)
        stiff = S.prefixed("controller.fme.contact_direction", desired_fme_stiff, f["contact_direction"], K, z)
        sched = S.prefixed("controller.fme", FMESchedule, free, stiff, transition=tc)
        terms.append(S.prefixed("controller.fme.gain", ObjectiveTerm, sched, f["gain"]))
    cfg = ControllerConfig(primary=_primary(dev, c["primary"]), objectives=tuple(terms), damping=c["damping"],
                           saturation=c["saturation"], projector=c["projector"], torque_min=lo, torque_max=hi,
                           gravity_compensation=c["gravity_compensation"], aso_shape=c["aso_shape"],
                           implementation=c["implementation"], null_space=c["null_space"],
                           tank=None if c["tank"] is None else S.prefixed("controller", NullSpaceTank, **c["tank"]))
    S.prefixed("controller", NullSpaceController, dev, cfg)  # every check the controller makes, now
    return cfg


def _objectives_at_start(dev: Device, cfg: ControllerConfig, q0: np.ndarray, listed: int) -> None:
    """Evaluate each objective's value and gradient once at ``sim.q0`` (the first `listed` from ``[[controller.objectives]]``).

    What an objective finds only when it runs (a misspelt frame or joint name a plugin looks up, a value it
    cannot use) is then an error of its key path when the file is read, not at the first tick.
    """
    for i, term in enumerate(cfg.objectives):
        path = f"controller.objectives[{i}]" if i < listed else "controller.fme"
        try:
            v = float(term.objective.value(dev, q0))
            g = np.asarray(term.objective.gradient(dev, q0), dtype=float)
        except RhiError as exc:
            raise type(exc)(f"{path}: {exc}") from None
        except Exception as exc:  # noqa: BLE001 - a plugin's own failure, named by its key path
            raise InvalidInput(f"{path}: the objective fails at sim.q0 ({type(exc).__name__}: {exc})") from None
        if not np.isfinite(v) or g.shape != (dev.n,) or not np.isfinite(g).all():
            raise InvalidInput(f"{path}: at sim.q0 the objective gives value {v:g} and a gradient of shape {g.shape} "
                               f"(expected a finite value and {dev.n} finite values)")


@dataclasses.dataclass(frozen=True, eq=False)
class RunConfig:
    """A loaded run configuration.

    Attributes:
        name: the file's stem (e.g. "ch7_ascm_tertiary"); source: its path.
        description: the file's one-line description.
        device: the device model the controller uses.
        controller_config: the `ControllerConfig`; `controller()` builds a fresh controller from it.
        virtual: the rendered environment `force(x, ẋ)`, or None.
        safety: the safety limits.
        rate: control rate [Hz]; duration: run time [s] or None.
        sim: the simulated link's settings: q0, dq0 (n,) [rad, rad/s], friction, timestep [s], handle_mass [kg],
            hand (a `rhi.sim.Hand` or None), physical (an environment or None).
    """

    name: str
    source: str
    description: str
    device: Device
    controller_config: ControllerConfig
    virtual: object
    safety: SafetyConfig
    rate: float
    duration: float | None
    sim: dict

    def controller(self) -> NullSpaceController:
        """A fresh controller (its own state) for one run."""
        return NullSpaceController(self.device, self.controller_config)

    def sim_link(self, *, rate: float | None = None) -> SimLink:
        """The simulated device of `[sim]`: a MuJoCo plant at q0 with the hand and the physical environment."""
        s = self.sim
        plant = Plant(self.device, friction=s["friction"], timestep=s["timestep"], handle_mass=s["handle_mass"])
        plant.reset(s["q0"], s["dq0"])
        return SimLink(plant, rate=self.rate if rate is None else rate, hand=s["hand"], physical=s["physical"])


def _sim(dev: Device, s: dict) -> dict:
    s = dict(s)
    lo, hi = dev.joint_limits
    if s["q0"] is None:
        s["q0"] = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi), 0.0)
    _dim("sim.q0", s["q0"], (dev.n,))
    _dim("sim.dq0", s["dq0"], (dev.n,))
    out = (s["q0"] < lo - 1e-9) | (s["q0"] > hi + 1e-9)
    if out.any():
        j = int(np.flatnonzero(out)[0])
        raise InvalidInput(f"sim.q0: joint {j + 1} at {s['q0'][j]:g} is outside its range [{lo[j]:g}, {hi[j]:g}]")
    if s["dq0"] is not None and np.abs(s["dq0"]).max() > 10.0:
        raise InvalidInput(f"sim.dq0: expected |dq0| <= 10 rad/s (plausibility bound), got {s['dq0'].tolist()}")
    fr = s["friction"]
    s["friction"] = None if fr == "none" else fr if fr == "device" else \
        S.prefixed("sim.friction", PlantFriction(fr["damping"], fr["frictionloss"]).check, dev.n)
    h = s["hand"]
    if h is not None:
        P = np.atleast_2d(h["path"])
        pts = np.vstack([P] + [(P[::-1] if i % 2 == 0 else P)[1:] for i in range(h["repeat"])])  # back and forth
        _dim("sim.hand.path", pts[:1], (1, dev.m))
        mf = None if h["max_force"] == "none" else h["max_force"]
        path = S.prefixed("sim.hand", HandPath, pts, speed=h["speed"], start=h["start"])
        s["hand"] = S.prefixed("sim.hand", Hand, path, stiffness=h["stiffness"], damping=h["damping"], max_force=mf)
    s["physical"] = _environments("sim.physical", s["physical"], dev.m)
    return s


def parse_config(data: dict, *, name: str = "config", source: str = "<dict>", device_name: str | None = None,
                 device: dict | None = None, base: Path | None = None) -> RunConfig:
    """A `RunConfig` from a parsed TOML document.

    Args:
        data: the document (e.g. from `tomllib.loads`).
        name: the configuration's name (for messages and the run summary).
        source: where it was read from (for messages and the run summary).
        device_name: the device asked for (e.g. `rhi run DEVICE`); must match ``[device] name`` if the file names one
            (and the loaded device's name for a file source).
        device: the device given on the command line (a `rhi.devices.source` table), for a file whose
            ``[device]`` names none.
        base: the folder of ``[device]``'s relative paths (default: the working directory).

    Raises:
        InvalidInput: an unknown key or a value of the wrong type (naming its key path), a device mismatch,
            a parameter the controller refuses.
    """
    try:
        d = S.parse("", data, _ROOT)
    except RecursionError:
        raise InvalidInput(f"config: {name} is nested too deeply") from None
    table = {k: v for k, v in d["device"].items() if v is not None and v != {}}
    if device is not None:
        if table:
            raise InvalidInput(f"device: {name} describes its device ([device] {', '.join(sorted(table))}); give "
                               "the device in the file or on the command line, not both")
        table = dict(device)
    dname = table.get("name")
    if dname is not None and device_name is not None and dname != device_name:
        raise InvalidInput(f"device: {name} is written for {dname!r} ([device] name), got {device_name!r}")
    if dname is None and not any(k in table for k in SOURCES):
        if device_name is None:
            raise InvalidInput(f"device.name: missing ({name} names no device and none was given)")
        table["name"] = device_name
    dev = device_from_table(table, base=base, path="device")
    if device_name is not None and dev.name != device_name:
        raise InvalidInput(f"device: {name} describes {dev.name!r} ([device]), got {device_name!r}")
    cfg, sim = _controller(dev, d["controller"]), _sim(dev, d["sim"])
    _objectives_at_start(dev, cfg, sim["q0"], len(d["controller"]["objectives"]))
    return RunConfig(name=name, source=source, description=d["description"], device=dev, controller_config=cfg,
                     virtual=_environments("virtual", d["virtual"], dev.m), safety=d["safety"],
                     rate=d["run"]["rate"], duration=d["run"]["duration"], sim=sim)


def shipped_configs() -> list[str]:
    """Names of the configurations shipped with rhi (``rhi run DEVICE --config NAME``)."""
    folder = resources.files("rhi.runtime") / "configs"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def config_path(config: str | Path) -> Path:
    """The file of `config`: a path to a TOML file, or the name of a shipped configuration.

    Raises:
        InvalidInput: neither exists (naming `config` and listing the shipped ones).
    """
    p = Path(config)
    if p.is_file():
        return p
    if isinstance(config, str) and p.name == config and config.removesuffix(".toml") in shipped_configs():
        return Path(str(resources.files("rhi.runtime") / "configs" / f"{config.removesuffix('.toml')}.toml"))
    raise InvalidInput(f"config: no file {str(config)!r} and no shipped configuration of that name "
                       f"(shipped: {', '.join(shipped_configs())})")


def load_config(config: str | Path, *, device_name: str | None = None, device: dict | None = None,
                defaults: dict | None = None) -> RunConfig:
    """Load a run configuration from a TOML file or by the name of a shipped one (see `parse_config`).

    `defaults`: top-level tables the file may leave out (e.g. ``controller`` for `rhi identify`, whose programme
    is the controller).
    """
    p = config_path(config)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InvalidInput(f"config: cannot read {str(p)!r} as TOML ({exc})") from None
    except RecursionError:
        raise InvalidInput(f"config: {str(p)!r} is nested too deeply") from None
    return parse_config({**(defaults or {}), **data}, name=p.stem, source=str(p), device_name=device_name,
                        device=device, base=p.parent)


__all__ = ["RunConfig", "config_path", "load_config", "parse_config", "shipped_configs"]
