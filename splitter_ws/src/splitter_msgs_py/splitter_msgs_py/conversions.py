"""Typed conversions between the graph's standard messages and numpy.

Every ``*_from_msg`` validates what it reads and raises
:class:`MessageValidationError` naming the offending field: NaN and infinities,
wrong array sizes, unknown, missing or duplicate joint names, and non-unit
quaternions (one within ``QUATERNION_NORM_TOLERANCE`` of unit norm is
normalized). Every ``*_to_msg`` refuses to build a message holding a non-finite
number, so no node can publish NaN through these functions.

Quaternions are scalar-first ``(w, x, y, z)`` in numpy and ``(x, y, z, w)`` in
ROS messages; this module is the only place that converts between the two.
Time is integer nanoseconds of (simulated) time; :func:`checked_stamp_from_msg`
and :class:`StampGate` are how a node rejects a stamp that is negative, goes
backwards on its topic or runs far ahead of the node's time.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry
from numpy.typing import ArrayLike, NDArray
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, Range

from splitter_model.rotations import quaternion_to_matrix
from splitter_msgs_py import names
from splitter_msgs_py.core.stamps import MessageValidationError

QUATERNION_NORM_TOLERANCE = 1e-3  # accepted |1 - |q|| before a quaternion is rejected
_NS_PER_S = 1_000_000_000
_Msg = TypeVar("_Msg")  # a ROS message type with a std_msgs/Header


# --- validation helpers ----------------------------------------------------------
def _finite_vector(value: ArrayLike, size: int, field_name: str) -> NDArray[np.float64]:
    try:
        arr = np.asarray(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise MessageValidationError(f"{field_name}: not numeric ({exc})") from exc
    if arr.size != size:
        raise MessageValidationError(f"{field_name}: expected {size} values, got {arr.size}")
    if not np.isfinite(arr).all():
        raise MessageValidationError(f"{field_name}: non-finite value in {arr.tolist()}")
    return arr


def unit_quaternion(q_wxyz: ArrayLike, field_name: str = "orientation") -> NDArray[np.float64]:
    """Validated unit quaternion: normalized within tolerance, rejected beyond it."""
    q = _finite_vector(q_wxyz, 4, field_name)
    largest = max(abs(c) for c in q.tolist())
    if largest > 1.0 + QUATERNION_NORM_TOLERANCE:  # (its norm could overflow)
        raise MessageValidationError(
            f"{field_name}: quaternion norm is not 1 (a component is {largest:.6g})"
        )
    norm = math.sqrt(q.dot(q))  # what np.linalg.norm computes for a vector
    if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise MessageValidationError(f"{field_name}: quaternion norm {norm:.6g} is not 1")
    return q / norm


def _xyzw_to_wxyz(q) -> NDArray[np.float64]:
    return np.array([q.w, q.x, q.y, q.z], dtype=float)


def _set_quaternion(target, q_wxyz: NDArray[np.float64]) -> None:
    target.w, target.x, target.y, target.z = q_wxyz.tolist()


def _set_vector3(target, v: NDArray[np.float64]) -> None:
    target.x, target.y, target.z = v.tolist()


def _finite_xyz(v, field_name: str) -> NDArray[np.float64]:
    """(x, y, z) of a message's Vector3 or Point, each finite."""
    x, y, z = v.x, v.y, v.z
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise MessageValidationError(f"{field_name}: non-finite value in {[x, y, z]}")
    return np.array([x, y, z])


# --- time ---------------------------------------------------------------------------
def stamp_to_msg(t_ns: int) -> Time:
    """builtin_interfaces/Time from integer nanoseconds (>= 0)."""
    t_ns = int(t_ns)
    if t_ns < 0:
        raise MessageValidationError(f"stamp: negative time {t_ns} ns")
    return Time(sec=t_ns // _NS_PER_S, nanosec=t_ns % _NS_PER_S)


def stamp_from_msg(msg: Time) -> int:
    """Integer nanoseconds of a builtin_interfaces/Time."""
    return int(msg.sec) * _NS_PER_S + int(msg.nanosec)


def _stamped(msg_type: Callable[[], _Msg], t_ns: int, frame_id: str = "") -> _Msg:
    """A new ``msg_type`` message whose header says ``t_ns`` and ``frame_id``."""
    msg = msg_type()
    msg.header.stamp = stamp_to_msg(t_ns)  # type: ignore[attr-defined]
    msg.header.frame_id = frame_id  # type: ignore[attr-defined]
    return msg


def checked_stamp_from_msg(msg: Time) -> int:
    """Integer nanoseconds of a Time that is >= 0 with ``nanosec`` < 1e9.

    Raises :class:`MessageValidationError` otherwise (``sec`` is a signed int32 and
    ``nanosec`` an uint32 on the wire, so both can be out of range).
    """
    sec, nanosec = int(msg.sec), int(msg.nanosec)
    if sec < 0:
        raise MessageValidationError(f"header.stamp: negative time ({sec} s)")
    if nanosec >= _NS_PER_S:
        raise MessageValidationError(f"header.stamp: nanosec {nanosec} is not below 1e9")
    return sec * _NS_PER_S + nanosec


def clock_to_msg(t_ns: int) -> Clock:
    """rosgraph_msgs/Clock for simulated time ``t_ns``."""
    return Clock(clock=stamp_to_msg(t_ns))


# --- IMU ------------------------------------------------------------------------------
@dataclass(frozen=True)
class ImuSample:
    """What an IMU on ``base`` measures."""

    t_ns: int
    orientation_wxyz: NDArray[np.float64]  # world <- base
    angular_velocity_rad_s: NDArray[np.float64]  # [rad/s] body
    linear_acceleration_m_s2: NDArray[np.float64]  # [m/s^2] body, specific force


def imu_to_msg(
    t_ns: int,
    orientation_wxyz: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    linear_acceleration_m_s2: ArrayLike,
    frame_id: str = names.BASE_FRAME,
    *,
    angular_velocity_variance: float = 0.0,
    linear_acceleration_variance: float = 0.0,
) -> Imu:
    """sensor_msgs/Imu.

    ``angular_velocity_variance`` [rad^2/s^2] and ``linear_acceleration_variance``
    [m^2/s^4], per axis, go on the diagonals of their covariances; the orientation's is
    unknown: zero, as REP 145 allows for simulation (and so are those when 0).
    """
    msg = _stamped(Imu, t_ns, frame_id)
    _set_quaternion(msg.orientation, unit_quaternion(orientation_wxyz))
    _set_vector3(
        msg.angular_velocity, _finite_vector(angular_velocity_rad_s, 3, "angular_velocity")
    )
    _set_variance(msg.angular_velocity_covariance, angular_velocity_variance, "angular_velocity")
    _set_vector3(
        msg.linear_acceleration,
        _finite_vector(linear_acceleration_m_s2, 3, "linear_acceleration"),
    )
    _set_variance(
        msg.linear_acceleration_covariance, linear_acceleration_variance, "linear_acceleration"
    )
    return msg


def _set_variance(covariance, variance: float, name: str) -> None:
    """``variance`` on the diagonal of a 3 x 3 covariance (row-major); 0 leaves it zero."""
    if variance == 0.0:
        return
    value = float(variance)
    if not (math.isfinite(value) and value > 0.0):
        raise MessageValidationError(
            f"{name}_covariance: variance must be finite and >= 0, got {value!r}"
        )
    covariance[0] = covariance[4] = covariance[8] = value


def imu_from_msg(msg: Imu) -> ImuSample:
    """Validated :class:`ImuSample` from sensor_msgs/Imu."""
    return ImuSample(
        t_ns=stamp_from_msg(msg.header.stamp),
        orientation_wxyz=unit_quaternion(_xyzw_to_wxyz(msg.orientation)),
        angular_velocity_rad_s=_finite_xyz(msg.angular_velocity, "angular_velocity"),
        linear_acceleration_m_s2=_finite_xyz(msg.linear_acceleration, "linear_acceleration"),
    )


# --- odometry -----------------------------------------------------------------------------
@dataclass(frozen=True)
class OdomSample:
    """Pose and velocity of ``base`` in ``world``."""

    t_ns: int
    position_m: NDArray[np.float64]  # [m] world
    orientation_wxyz: NDArray[np.float64]  # world <- base
    velocity_world_m_s: NDArray[np.float64]  # [m/s] world
    angular_velocity_rad_s: NDArray[np.float64]  # [rad/s] body


def odom_to_msg(
    t_ns: int,
    position_m: ArrayLike,
    orientation_wxyz: ArrayLike,
    velocity_world_m_s: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
) -> Odometry:
    """nav_msgs/Odometry: pose in ``world``, twist in ``base`` (REP 105)."""
    q = unit_quaternion(orientation_wxyz)
    v_world = _finite_vector(velocity_world_m_s, 3, "velocity")
    with np.errstate(over="ignore", invalid="ignore"):  # checked just below
        v_base = _finite_vector(quaternion_to_matrix(q).T @ v_world, 3, "velocity (base frame)")
    msg = _stamped(Odometry, t_ns, names.WORLD_FRAME)
    msg.child_frame_id = names.BASE_FRAME
    _set_vector3(msg.pose.pose.position, _finite_vector(position_m, 3, "position"))
    _set_quaternion(msg.pose.pose.orientation, q)
    _set_vector3(msg.twist.twist.linear, v_base)
    _set_vector3(
        msg.twist.twist.angular, _finite_vector(angular_velocity_rad_s, 3, "angular_velocity")
    )
    return msg


def odom_from_msg(msg: Odometry) -> OdomSample:
    """Validated :class:`OdomSample`; the base-frame linear twist is rotated to world."""
    q = unit_quaternion(_xyzw_to_wxyz(msg.pose.pose.orientation), "pose.orientation")
    v_base = _finite_xyz(msg.twist.twist.linear, "twist.linear")
    with np.errstate(over="ignore", invalid="ignore"):  # checked just below
        v_world = _finite_vector(quaternion_to_matrix(q) @ v_base, 3, "twist.linear (world)")
    return OdomSample(
        t_ns=stamp_from_msg(msg.header.stamp),
        position_m=_finite_xyz(msg.pose.pose.position, "pose.position"),
        orientation_wxyz=q,
        velocity_world_m_s=v_world,
        angular_velocity_rad_s=_finite_xyz(msg.twist.twist.angular, "twist.angular"),
    )


# --- Vector3Stamped (inertia, inertia setpoint) ------------------------------------------
@dataclass(frozen=True)
class Vector3Sample:
    """A stamped 3-vector."""

    t_ns: int
    vector: NDArray[np.float64]
    frame_id: str


def vector3_to_msg(t_ns: int, vec3: ArrayLike, frame_id: str = names.BASE_FRAME) -> Vector3Stamped:
    """geometry_msgs/Vector3Stamped."""
    msg = _stamped(Vector3Stamped, t_ns, frame_id)
    _set_vector3(msg.vector, _finite_vector(vec3, 3, "vector"))
    return msg


def vector3_from_msg(msg: Vector3Stamped) -> Vector3Sample:
    """Validated :class:`Vector3Sample`."""
    return Vector3Sample(
        t_ns=stamp_from_msg(msg.header.stamp),
        vector=_finite_xyz(msg.vector, "vector"),
        frame_id=msg.header.frame_id,
    )


MAX_PRINCIPAL_INERTIA_KG_M2 = 1.0e4  # [kg m^2] a measured moment above this is corrupt


def principal_inertia_from_msg(msg: Vector3Stamped) -> Vector3Sample:
    """Validated measured principal moments: frame ``base``, each in (0, 1e4] kg m^2."""
    sample = vector3_from_msg(msg)
    if sample.frame_id != names.BASE_FRAME:
        raise MessageValidationError(
            f"header.frame_id: expected '{names.BASE_FRAME}', got {sample.frame_id!r}"
        )
    if (
        min(sample.vector.tolist()) <= 0.0
        or max(sample.vector.tolist()) > MAX_PRINCIPAL_INERTIA_KG_M2
    ):
        raise MessageValidationError(
            f"vector: moments must be in (0, {MAX_PRINCIPAL_INERTIA_KG_M2:g}] kg m^2, "
            f"got {sample.vector.tolist()}"
        )
    return sample


# --- joint states and commands -----------------------------------------------------------
@dataclass(frozen=True)
class JointSample:
    """Joint positions [rad, m] (and velocities, efforts) in ``names.JOINT_NAMES`` order."""

    t_ns: int
    position: NDArray[np.float64]
    velocity: NDArray[np.float64] | None = None
    effort: NDArray[np.float64] | None = None


def joint_state_to_msg(
    t_ns: int,
    position: ArrayLike,
    velocity: ArrayLike | None = None,
    effort: ArrayLike | None = None,
) -> JointState:
    """sensor_msgs/JointState with all 25 joints named as ``names.JOINT_NAMES``."""
    msg = _stamped(JointState, t_ns)
    msg.name = list(names.JOINT_NAMES)
    msg.position = _finite_vector(position, names.N_JOINTS, "position").tolist()
    if velocity is not None:
        msg.velocity = _finite_vector(velocity, names.N_JOINTS, "velocity").tolist()
    if effort is not None:
        msg.effort = _finite_vector(effort, names.N_JOINTS, "effort").tolist()
    return msg


_JOINT_NAME_LIST = list(names.JOINT_NAMES)


def joint_state_from_msg(msg: JointState) -> JointSample:
    """Validated :class:`JointSample` reordered to ``names.JOINT_NAMES``.

    Every joint must be named exactly once; ``velocity`` and ``effort`` are
    optional (empty) but, when present, must match the names in length.
    """
    msg_names = list(msg.name)
    order: NDArray[np.intp] | None = None  # None: already in JOINT_NAMES order
    if msg_names != _JOINT_NAME_LIST:
        unknown = sorted(set(msg_names) - set(names.JOINT_NAMES))
        if unknown:
            raise MessageValidationError(f"name: unknown joints {unknown}")
        if len(set(msg_names)) != len(msg_names):
            raise MessageValidationError("name: duplicate joint names")
        missing = [n for n in names.JOINT_NAMES if n not in msg_names]
        if missing:
            raise MessageValidationError(f"name: missing joints {missing}")
        order = np.array([msg_names.index(n) for n in names.JOINT_NAMES])

    def field_array(values: Sequence[float], field_name: str) -> NDArray[np.float64] | None:
        if len(values) == 0:
            return None
        if len(values) != len(msg_names):
            raise MessageValidationError(
                f"{field_name}: {len(values)} values for {len(msg_names)} names"
            )
        checked = _finite_vector(values, len(msg_names), field_name)
        return checked.copy() if order is None else checked[order]  # not the message's buffer

    position = field_array(msg.position, "position")
    if position is None:
        raise MessageValidationError("position: empty")
    return JointSample(
        t_ns=stamp_from_msg(msg.header.stamp),
        position=position,
        velocity=field_array(msg.velocity, "velocity"),
        effort=field_array(msg.effort, "effort"),
    )


# --- wrench ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class WrenchSample:
    """A stamped force [N] and torque [Nm]."""

    t_ns: int
    force_n: NDArray[np.float64]
    torque_nm: NDArray[np.float64]
    frame_id: str


def wrench_to_msg(
    t_ns: int,
    force_n: ArrayLike,
    torque_nm: ArrayLike = (0.0, 0.0, 0.0),
    frame_id: str = names.WORLD_FRAME,
) -> WrenchStamped:
    """geometry_msgs/WrenchStamped."""
    msg = _stamped(WrenchStamped, t_ns, frame_id)
    _set_vector3(msg.wrench.force, _finite_vector(force_n, 3, "force"))
    _set_vector3(msg.wrench.torque, _finite_vector(torque_nm, 3, "torque"))
    return msg


def wrench_from_msg(msg: WrenchStamped) -> WrenchSample:
    """Validated :class:`WrenchSample`."""
    return WrenchSample(
        t_ns=stamp_from_msg(msg.header.stamp),
        force_n=_finite_xyz(msg.wrench.force, "wrench.force"),
        torque_nm=_finite_xyz(msg.wrench.torque, "wrench.torque"),
        frame_id=msg.header.frame_id,
    )


# --- rangefinder ----------------------------------------------------------------------------
def range_to_msg(
    t_ns: int,
    range_m: float,
    frame_id: str,
    *,
    min_range_m: float,
    max_range_m: float,
    field_of_view_rad: float,
) -> Range:
    """sensor_msgs/Range of an infrared rangefinder; +-inf as REP 117 (no return / too close)."""
    value = float(range_m)
    if math.isnan(value):
        raise MessageValidationError("range: NaN")
    msg = _stamped(Range, t_ns, frame_id)
    msg.radiation_type = Range.INFRARED
    msg.field_of_view = float(field_of_view_rad)
    msg.min_range = float(min_range_m)
    msg.max_range = float(max_range_m)
    msg.range = value
    return msg


def range_from_msg(msg: Range) -> tuple[int, float]:
    """(stamp [ns], range [m]); +-inf (REP 117) kept, NaN and negative finite values refused."""
    value = float(msg.range)
    if math.isnan(value) or (math.isfinite(value) and value < 0.0):
        raise MessageValidationError(f"range: {value} is not a distance")
    return stamp_from_msg(msg.header.stamp), value


# --- attitude reference -----------------------------------------------------------------------
def twist_to_msg(
    t_ns: int, angular_rad_s: ArrayLike, frame_id: str = names.BASE_FRAME
) -> TwistStamped:
    """geometry_msgs/TwistStamped carrying an angular velocity (linear part zero)."""
    msg = _stamped(TwistStamped, t_ns, frame_id)
    _set_vector3(msg.twist.angular, _finite_vector(angular_rad_s, 3, "twist.angular"))
    return msg


def twist_from_msg(msg: TwistStamped) -> tuple[int, NDArray[np.float64]]:
    """(t_ns, angular velocity [rad/s]) of a TwistStamped."""
    return (
        stamp_from_msg(msg.header.stamp),
        _finite_xyz(msg.twist.angular, "twist.angular"),
    )


def pose_to_msg(
    t_ns: int,
    orientation_wxyz: ArrayLike,
    position_m: ArrayLike = (0.0, 0.0, 0.0),
    frame_id: str = names.WORLD_FRAME,
) -> PoseStamped:
    """geometry_msgs/PoseStamped."""
    msg = _stamped(PoseStamped, t_ns, frame_id)
    _set_vector3(msg.pose.position, _finite_vector(position_m, 3, "pose.position"))
    _set_quaternion(msg.pose.orientation, unit_quaternion(orientation_wxyz, "pose.orientation"))
    return msg


def pose_from_msg(msg: PoseStamped) -> tuple[int, NDArray[np.float64], NDArray[np.float64]]:
    """(t_ns, orientation (w, x, y, z), position [m]) of a PoseStamped."""
    return (
        stamp_from_msg(msg.header.stamp),
        unit_quaternion(_xyzw_to_wxyz(msg.pose.orientation), "pose.orientation"),
        _finite_xyz(msg.pose.position, "pose.position"),
    )


# --- diagnostics --------------------------------------------------------------------------------
@dataclass(frozen=True)
class DiagnosticStatusSample:
    """One diagnostic status: ``values`` keys carry their unit (``solve_time_ms``)."""

    name: str
    level: int  # 0 OK, 1 WARN, 2 ERROR, 3 STALE
    message: str
    values: Mapping[str, float | int | str | bool] = field(default_factory=dict)
    hardware_id: str = "splitter"


def _format_value(key: str, value: float | int | str | bool) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float | np.floating | np.integer):
        number = float(value)
        if not math.isfinite(number):
            raise MessageValidationError(f"diagnostics value {key}: non-finite {number}")
        return repr(int(value)) if isinstance(value, int | np.integer) else repr(number)
    return str(value)


def diagnostics_to_msg(t_ns: int, statuses: Sequence[DiagnosticStatusSample]) -> DiagnosticArray:
    """diagnostic_msgs/DiagnosticArray; numbers are written with full precision."""
    msg = _stamped(DiagnosticArray, t_ns)
    for sample in statuses:
        if sample.level not in (0, 1, 2, 3):
            raise MessageValidationError(f"diagnostics {sample.name}: level {sample.level}")
        status = DiagnosticStatus(
            level=bytes([sample.level]),
            name=sample.name,
            message=sample.message,
            hardware_id=sample.hardware_id,
        )
        status.values = [
            KeyValue(key=k, value=_format_value(k, v)) for k, v in sample.values.items()
        ]
        msg.status.append(status)
    return msg


def _parse_value(text: str) -> float | str | bool:
    if text in ("true", "false"):
        return text == "true"
    try:
        return float(text)
    except ValueError:
        return text


def diagnostics_from_msg(msg: DiagnosticArray) -> list[DiagnosticStatusSample]:
    """Statuses of a DiagnosticArray with numeric values parsed back to float."""
    out = []
    for status in msg.status:
        level = status.level
        level_int = level[0] if isinstance(level, bytes | bytearray) else int(level)
        out.append(
            DiagnosticStatusSample(
                name=status.name,
                level=level_int,
                message=status.message,
                values={kv.key: _parse_value(kv.value) for kv in status.values},
                hardware_id=status.hardware_id,
            )
        )
    return out


# --- joint health (/splitter/joint_health) ---------------------------------------
_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class JointHealth:
    """The faulty joints the allocator found and the radius bounds that remain [m]."""

    symptoms: Mapping[str, str]  # joint name -> symptom
    radius_min_m: NDArray[np.float64]  # (3,) r_x, r_y, r_z
    radius_max_m: NDArray[np.float64]


def joint_health_status(symptoms: Mapping[int, str], reachable, node_name: str):
    """The status of ``/splitter/joint_health``: faulty joints (``JOINT_NAMES`` indices ->
    symptom) and the radius bounds of ``reachable`` (a ``ReachableSet``)."""
    values: dict[str, float | int | str | bool] = {
        names.JOINT_NAMES[j]: symptom for j, symptom in sorted(symptoms.items())
    }
    for axis, low, high in zip(_AXES, reachable.radius_min_m, reachable.radius_max_m, strict=True):
        values[f"radius_min_{axis}_m"] = float(low)
        values[f"radius_max_{axis}_m"] = float(high)
    joints = ", ".join(f"{names.JOINT_NAMES[j]} {s}" for j, s in sorted(symptoms.items()))
    return DiagnosticStatusSample(
        name=f"{node_name}: joint health", level=2, message=joints, values=values
    )


def joint_health_from_msg(msg: DiagnosticArray) -> JointHealth:
    """:class:`JointHealth` of a ``/splitter/joint_health`` message; MessageValidationError
    unless it names known joints and finite radius bounds with 0 < min < max."""
    statuses = diagnostics_from_msg(msg)
    if len(statuses) != 1:
        raise MessageValidationError(f"joint health: 1 status expected, got {len(statuses)}")
    values = statuses[0].values
    try:
        low = np.array([float(values[f"radius_min_{a}_m"]) for a in _AXES])
        high = np.array([float(values[f"radius_max_{a}_m"]) for a in _AXES])
    except (KeyError, TypeError, ValueError) as exc:
        raise MessageValidationError(f"joint health: radius bounds missing ({exc})") from None
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
        raise MessageValidationError("joint health: radius bounds must be finite")
    if not (np.all(low > 0.0) and np.all(low < high)):
        raise MessageValidationError(f"joint health: need 0 < min < max, got {low}, {high}")
    symptoms = {k: str(v) for k, v in values.items() if k in names.JOINT_INDEX}
    unknown = [k for k in values if not k.startswith("radius_") and k not in names.JOINT_INDEX]
    if unknown:
        raise MessageValidationError(f"joint health: unknown joints {unknown}")
    return JointHealth(symptoms, low, high)


# --- types ---------------------------------------------------------------------
def message_class(type_name: str) -> type:
    """The rclpy message class of a ``pkg/msg/Type`` name."""
    parts = type_name.split("/")
    if len(parts) != 3 or parts[1] != "msg":
        raise ValueError(f"not a message type name: {type_name!r} (expected pkg/msg/Type)")
    module = importlib.import_module(f"{parts[0]}.msg")
    try:
        return getattr(module, parts[2])
    except AttributeError:
        raise ValueError(f"no message type {type_name!r}") from None


TOPIC_MESSAGE_CLASSES: dict[str, type] = {
    topic: message_class(type_name) for topic, type_name in names.TOPIC_TYPES.items()
}
