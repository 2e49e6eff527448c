"""`DeviceSpec`: a bundled device description (`models/<name>/device.toml`) read once, as data.

This module is the only reader of ``device.toml`` (format: models/README.md). A spec holds
what the URDF cannot say (task, actuation map, limits in motor coordinates, design
parameters, plant friction, the Mecanum base geometry) already converted to SI units;
`rhi.devices.model.device` builds the `Device` from it and the Device carries it (`Device.spec`),
so controllers, the plant and the design code read the device, never the file.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin

from rhi._validate import as_array
from rhi.errors import InvalidInput, ModelError, UnknownDevice

MODELS = Path(__file__).parents[1] / "models"
#: Keys of the ``[mobile_base]`` table (eq. A.21 / B.21) [m].
MOBILE_BASE_KEYS = ("wheel_radius", "half_length", "half_width")
_AXES = {"x": 0, "y": 1, "z": 2}


@dataclasses.dataclass(frozen=True)
class LinearLimits:
    """Linear joint inequalities `lower <= C q <= upper`.

    Attributes:
        C: (k, n) coefficient matrix.
        lower: (k,) lower bounds [rad].
        upper: (k,) upper bounds [rad].
    """

    C: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    def fix(self, locked: np.ndarray, values: np.ndarray) -> LinearLimits | None:
        """The inequalities left on the other coordinates when coordinates `locked` are held at `values`.

        Args:
            locked: (k,) indices of the fixed coordinates.
            values: (k,) their values [rad or m].

        Returns:
            The remaining inequalities (rows that no longer involve a free coordinate dropped), or None.

        Raises:
            InvalidInput: the values violate an inequality that involves only fixed coordinates.
        """
        locked = np.asarray(locked, dtype=int)
        free = np.setdiff1d(np.arange(self.C.shape[1]), locked)
        shift = self.C[:, locked] @ values if len(locked) else 0.0
        C, lo, hi = self.C[:, free], self.lower - shift, self.upper - shift
        keep = np.any(C != 0, axis=1)
        if np.any(~keep & ((lo > 1e-12) | (hi < -1e-12))):
            raise InvalidInput("lock: the locked values violate a linear joint limit")
        return LinearLimits(C[keep], lo[keep], hi[keep]) if keep.any() else None


@dataclasses.dataclass(frozen=True)
class ParameterSpec:
    """A design parameter: one component of a joint or frame placement.

    Attributes:
        target: ``"joint:NAME"`` or ``"frame:NAME"``.
        component: ``"x"``, ``"y"``, ``"z"`` or ``"yaw"``.
        default: value of the bundled device [m or rad].
        bounds: (min, max) the design may explore [m or rad], or None.
    """

    target: str
    component: str
    default: float
    bounds: tuple[float, float] | None = None


@dataclasses.dataclass(frozen=True, eq=False)
class DeviceSpec:
    """The contents of one ``device.toml``, in SI units (angles in rad).

    A derived device (``base = ...``) holds only `base` and `lock`; every other field
    then describes nothing (the base's spec does).

    Attributes:
        name: device name.
        folder: the device's folder.
        urdf: path of the URDF, or None for a derived device.
        ee_frame: end-effector frame (a URDF link).
        task: world axes of the position task ("xy", "xyz").
        joint_names: names of the motor coordinates, or None (q1, q2, ...).
        actuation: (nθ, n) actuation map A of θ = A q + b, or None (identity).
        offset: (nθ,) offset b [rad or m], or None.
        armature: (n,) rotor inertia [kg m²], or None.
        q_min, q_max: (n,) joint limits [rad or m], or None (unbounded).
        torque_min, torque_max: (n,) actuator limits [N m], or None.
        linear_limits: joint inequalities, or None.
        velocity_max, acceleration_max: (n,) symmetric joint velocity [rad/s or m/s] and
            acceleration [rad/s² or m/s²] limits (Table B.1), or None.
        damping, frictionloss: (n,) plant motor friction [N m s/rad], [N m] (`[plant]`), or None.
        parameters: {name: ParameterSpec} design parameters.
        mobile_base: {wheel_radius, half_length, half_width} [m] of a Mecanum base, or None.
        base: name of the device this one is derived from by locking joints, or None.
        lock: {joint name: value [rad]} of a derived device.
    """

    name: str
    folder: Path
    urdf: Path | None = None
    ee_frame: str | None = None
    task: str = "xyz"
    joint_names: list[str] | None = None
    actuation: np.ndarray | None = None
    offset: np.ndarray | None = None
    armature: np.ndarray | None = None
    q_min: np.ndarray | None = None
    q_max: np.ndarray | None = None
    torque_min: np.ndarray | None = None
    torque_max: np.ndarray | None = None
    linear_limits: LinearLimits | None = None
    velocity_max: np.ndarray | None = None
    acceleration_max: np.ndarray | None = None
    damping: np.ndarray | None = None
    frictionloss: np.ndarray | None = None
    parameters: dict[str, ParameterSpec] = dataclasses.field(default_factory=dict)
    mobile_base: dict[str, float] | None = None
    base: str | None = None
    lock: dict[str, float] = dataclasses.field(default_factory=dict)

    def chain(self) -> tuple[Path, str]:
        """(URDF path, end-effector frame) of a spec that is not derived.

        Raises:
            ModelError: a derived spec (``base = ...``) has neither.
        """
        if self.urdf is None or self.ee_frame is None:
            raise ModelError(f"{self.name}: a device derived from {self.base!r} has no URDF of its own")
        return self.urdf, self.ee_frame

    @property
    def parameter_bounds(self) -> dict[str, tuple[float, float]]:
        """{name: (min, max)} of the parameters that declare bounds [m or rad]."""
        return {k: p.bounds for k, p in self.parameters.items() if p.bounds is not None}


def available_devices() -> list[str]:
    """Names of the bundled devices."""
    return sorted(p.parent.name for p in MODELS.glob("*/device.toml"))


def bundled_spec(name: str) -> DeviceSpec:
    """The spec of a bundled device by name (see `available_devices()`).

    Raises:
        UnknownDevice: no bundled device has that name.
        ModelError: its device.toml is malformed.
    """
    if not isinstance(name, str) or not name or "/" in name or name.startswith("."):
        raise UnknownDevice(f"name: expected a bundled device name, got {name!r}; available: {', '.join(available_devices())}")
    if not (MODELS / name / "device.toml").is_file():
        raise UnknownDevice(f"name: unknown device {name!r}; available: {', '.join(available_devices())}")
    return read_spec(MODELS / name)


def read_spec(folder: str | Path) -> DeviceSpec:
    """Read a device folder's ``device.toml`` (format: models/README.md).

    Args:
        folder: folder holding device.toml (and its URDF).

    Raises:
        ModelError: the file is missing or malformed.
    """
    folder = Path(folder)
    path = folder / "device.toml"
    try:
        doc = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ModelError(f"{folder}: cannot read device.toml ({exc})") from None
    try:
        return _parse(folder, doc)
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelError(f"{path}: malformed entry ({type(exc).__name__}: {exc})") from None


def _floats(value) -> np.ndarray | None:
    return None if value is None else np.array(value, dtype=float)


def _parse(folder: Path, doc: dict) -> DeviceSpec:
    name = doc.get("name", folder.name)
    if "base" in doc:  # a device derived from another by locking joints
        lock = {k: float(np.deg2rad(v)) for k, v in doc.get("lock_deg", {}).items()}
        return DeviceSpec(name=name, folder=folder, base=doc["base"], lock=lock)
    lim = doc.get("limits", {})
    deg = lim.get("unit", "deg") == "deg"

    def to_rad(values) -> np.ndarray:
        v = np.array(values, dtype=float)
        return np.deg2rad(v) if deg else v

    def angles(key: str) -> np.ndarray | None:
        return None if lim.get(key) is None else to_rad(lim[key])

    lin = None
    if "linear" in lim:
        rows = lim["linear"]
        lin = LinearLimits(np.array([r["coefficients"] for r in rows], dtype=float),
                           to_rad([r["min"] for r in rows]), to_rad([r["max"] for r in rows]))
    params = {}
    for pname, p in doc.get("parameters", {}).items():
        bounds = (float(p["min"]), float(p["max"])) if "min" in p and "max" in p else None
        params[pname] = ParameterSpec(p["target"], p["component"], float(p["default"]), bounds)
    plant = doc.get("plant", {})
    base = doc.get("mobile_base")
    mobile = None if base is None else {k: float(base[k]) for k in MOBILE_BASE_KEYS}
    return DeviceSpec(
        name=name,
        folder=folder,
        urdf=folder / doc["urdf"],
        ee_frame=doc["ee_frame"],
        task=doc.get("task", "xyz"),
        joint_names=doc.get("joint_names"),
        actuation=_floats(doc.get("actuation")),
        offset=_floats(doc.get("offset")),
        armature=_floats(doc.get("armature")),
        q_min=angles("q_min"),
        q_max=angles("q_max"),
        torque_min=_floats(lim.get("torque_min")),
        torque_max=_floats(lim.get("torque_max")),
        linear_limits=lin,
        velocity_max=angles("velocity_max"),
        acceleration_max=angles("acceleration_max"),
        damping=_floats(plant.get("damping")),
        frictionloss=_floats(plant.get("frictionloss")),
        parameters=params,
        mobile_base=mobile,
    )


def build_model(spec: DeviceSpec, params: dict[str, float],
                links: dict[str, dict[str, float]] | None = None) -> tuple[pin.Model, dict[str, float]]:
    """The Pinocchio model of a spec's URDF with its design parameters set.

    Args:
        spec: a spec that is not derived (``spec.base is None``).
        params: {parameter: value} overriding the declared defaults [m or rad].
        links: inertial overrides of a parameter variant (`rhi.devices.variant`), or None.

    Returns:
        (model, {parameter: value used}).

    Raises:
        InvalidInput: an unknown parameter, or a value that is not one finite number within its bounds.
        ModelError: the URDF is missing or malformed, or a parameter names an unknown target.
    """
    model = load_urdf(spec.chain()[0])
    if links:
        from rhi.devices.variant import model_with_links

        model = model_with_links(spec.chain()[0], links)
    unknown = set(params) - set(spec.parameters)
    if unknown:
        raise InvalidInput(f"params: unknown parameter(s) {sorted(unknown)} for {spec.name}; "
                           f"known: {sorted(spec.parameters)}")
    values = {}
    for pname, p in spec.parameters.items():
        arr = as_array(pname, params[pname]) if pname in params else np.asarray(p.default)
        if arr.ndim != 0:
            raise InvalidInput(f"{pname}: expected one value, got shape {arr.shape}")
        v = float(arr)
        if not np.isfinite(v):
            raise InvalidInput(f"{pname}: must be finite, got {v}")
        if p.bounds is not None and not p.bounds[0] <= v <= p.bounds[1]:
            raise InvalidInput(f"{pname}: {v} outside [{p.bounds[0]}, {p.bounds[1]}]")
        set_placement(model, p.target, p.component, v)
        values[pname] = v
    return model, values


def load_urdf(path: Path) -> pin.Model:
    """The Pinocchio model of a URDF file (ModelError naming the path if missing or malformed)."""
    if not path.is_file():
        raise ModelError(f"path: URDF file {str(path)!r} does not exist")
    try:
        return pin.buildModelFromUrdf(str(path))
    except Exception as exc:  # Pinocchio raises ValueError/RuntimeError with its own text
        raise ModelError(f"path: malformed URDF {str(path)!r}: {exc}") from None


def set_placement(model: pin.Model, target: str, component: str, value: float) -> None:
    """Set one component of a joint or frame placement: component in x, y, z, yaw [m or rad]."""
    kind, _, name = target.partition(":")
    if kind == "joint" and model.existJointName(name):
        M = model.jointPlacements[model.getJointId(name)]
    elif kind == "frame" and model.existFrame(name):
        M = model.frames[model.getFrameId(name)].placement
    else:
        raise ModelError(f"parameters: unknown target {target!r}")
    if component in _AXES:
        t = M.translation.copy()
        t[_AXES[component]] = value
        M.translation = t
    elif component == "yaw":
        M.rotation = pin.utils.rotate("z", value)
    else:
        raise ModelError(f"parameters: unknown component {component!r}")
    if kind == "joint":
        model.jointPlacements[model.getJointId(name)] = M
    else:
        model.frames[model.getFrameId(name)].placement = M
