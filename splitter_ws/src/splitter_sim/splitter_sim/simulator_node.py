"""``simulator``: the SPLITTER physics as a ROS 2 node, and the clock of the graph.

A thin layer over :class:`splitter_sim.core.simulator.Simulator`. The node is the
source of simulated time (it publishes ``/clock`` and does not use sim time).

Every step ``t`` it publishes, stamped ``t`` and in this order: ``/clock``,
``/splitter/joint_states``, ``/splitter/inertia`` (principal moments, the
diagonal of the body inertia tensor), ``/splitter/odom``, the two contact
wrenches (world frame, ground on hemi, torque about the hemi body) and
``/splitter/imu``; ``/splitter/markers`` every ``markers_period_s`` and
``/diagnostics`` every ``diagnostics_period_s`` of simulated time.

Modes (docs/ARCHITECTURE.md, "Lockstep protocol"):

* ``lockstep``: on a control tick (``t`` a multiple of ``control_period_s``) the
  node steps only once every lockstep command topic that has a publisher
  (``/splitter/joint_commands``, ``/splitter/jump_command``) has delivered a
  message stamped ``t``; between ticks it steps without waiting. Nothing blocks:
  a steady-clock timer and the command callbacks drive the stepping, so the node
  shares a ``SingleThreadedExecutor`` with the controllers. A wait longer than
  ``lockstep_timeout_s`` (wall) is logged with its reason and the node steps on
  the last good commands. At start-up it waits up to ``startup_wait_s`` for the
  command publishers and state subscribers to be discovered.
* ``real_time``: steps on a wall-clock timer at ``dt_s / rate_factor`` and never
  waits for commands (at start-up, up to ``startup_wait_s`` for state subscribers).

Bad input never raises out of a callback; it is rejected with a throttled warning
(counted, reported on ``/diagnostics``) and the last good command stays in force:

* a command whose stamp is negative, earlier than the last one of its topic (a
  stamp of 0 once time has advanced) or later than the simulated time (commands
  answer states the simulator published; one from the future is corrupt) is
  dropped: it is not applied and does not answer a lockstep tick;
* a well-stamped joint command with NaN or infinite values, unknown, missing or
  duplicate joint names, mismatched array lengths, or positions / velocities out
  of the joint / tether range or speed; a well-stamped jump command with
  non-finite values, a frame other than ``world``, a force above
  ``MAX_JUMP_FORCE_N`` or a torque above ``MAX_JUMP_TORQUE_NM``: not applied, but
  it still answers its lockstep tick (the simulator steps on the last good command).

Invalid parameters stop the node at start-up with a message naming the parameter.
"""

from __future__ import annotations

import math
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point, Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMsg
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import Imu, JointState
from visualization_msgs.msg import Marker, MarkerArray

from splitter_model.model import RobotModel, gravity_from_name
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    DiagnosticStatusSample,
    MessageValidationError,
    checked_stamp_from_msg,
    clock_to_msg,
    diagnostics_to_msg,
    imu_to_msg,
    joint_state_from_msg,
    joint_state_to_msg,
    odom_to_msg,
    stamp_to_msg,
    vector3_to_msg,
    wrench_from_msg,
    wrench_to_msg,
)
from splitter_msgs_py.core.latency import InputLatency
from splitter_msgs_py.core.stamps import StampGate
from splitter_msgs_py.node_pattern import run_node
from splitter_msgs_py.parameters import (
    READ_ONLY_NOTE,
    InvalidParameterError,
    ParameterSpec,
    declare_parameters,
    rejection_counts,
    warn_throttled,
)
from splitter_msgs_py.presence import PublisherPresence
from splitter_msgs_py.qos import qos_for
from splitter_msgs_py.signals import spin_until_stopped
from splitter_sim.core.actuators import validate_joint_command
from splitter_sim.core.scene import scene_arrows
from splitter_sim.core.simulator import InitialState, SimConfig, SimState, Simulator
from splitter_sim.core.stepping import (
    CommandQueue,
    LockstepWait,
    RealTimePacer,
    check_jump_wrench,
    check_trajectory_stamp,
    pushing_hemi,
)

NODE_NAME = "simulator"
# Contact wrench topics (docs/ARCHITECTURE.md); the names live in splitter_msgs_py.names.
CONTACT_WRENCH_A = names.CONTACT_WRENCH_A
CONTACT_WRENCH_B = names.CONTACT_WRENCH_B
LOCKSTEP_TOPICS = (names.JOINT_COMMANDS, names.JUMP_COMMAND)
STATE_TOPICS = (
    names.JOINT_STATES,
    names.INERTIA,
    names.ODOM,
    CONTACT_WRENCH_A,
    CONTACT_WRENCH_B,
    names.IMU,
)
MODES = ("lockstep", "real_time")
LOCKSTEP_POLL_S = 0.005  # [s] wall period of the lockstep driver timer
SLACK_WARNING_PERIOD_S = 1.0  # [s] wall: at most one tether-slack warning per period
BATCH_WALL_S = 0.02  # [s] longest a free-running callback steps before yielding
# [ns] commands may not be stamped later than the simulated time: they answer states
MAX_COMMAND_LEAD_NS = 0
# [ns] real time: a joint command may be stamped this far ahead (a trajectory point
# planned over the latency; it waits for its stamp); further ahead it is corrupt
MAX_TRAJECTORY_LEAD_NS = 2_000_000_000
_DEFAULT_CONFIG = SimConfig()

PARAMETERS = (
    ParameterSpec("mode", "lockstep", "stepping mode", choices=MODES),
    ParameterSpec(
        "rate_factor",
        1.0,
        "real_time mode: simulated seconds per wall second",
        min_value=1e-3,
        max_value=1e4,
    ),
    ParameterSpec(
        "lockstep_timeout_s",
        5.0,
        "lockstep: longest wall wait for the commands of a tick before stepping on [s]",
        min_value=1e-3,
        max_value=3600.0,
    ),
    ParameterSpec(
        "startup_wait_s",
        3.0,
        "longest wall wait at start for state subscribers (and, lockstep, command publishers) [s]",
        min_value=0.0,
        max_value=600.0,
    ),
    ParameterSpec(
        "startup_wait_for_nodes",
        [],
        "nodes that must be in the graph before stepping starts (e.g. the controllers)",
        item_type=str,
    ),
    ParameterSpec(
        "startup_wait_for_publishers",
        [],
        "topics that must have a publisher before stepping starts (e.g. the MPC's setpoints)",
        item_type=str,
    ),
    ParameterSpec(
        "startup_settle_s",
        0.0,
        "the start condition must hold this long before stepping: time for the other nodes' "
        "endpoints to match each other, which this node cannot see [s]",
        min_value=0.0,
        max_value=60.0,
    ),
    ParameterSpec(
        "startup_wait_for_subscribers",
        [],
        "nodes that must subscribe to every state topic before stepping starts (a recorder)",
        item_type=str,
    ),
    ParameterSpec(
        "duration_s",
        0.0,
        "simulated time after which the node stops stepping (0: never) [s]",
        min_value=0.0,
        max_value=1e7,
    ),
    ParameterSpec("dt_s", 0.005, "simulation step [s]", min_value=1e-4, max_value=0.05),
    ParameterSpec(
        "control_period_s",
        0.01,
        "lockstep tick period, a multiple of dt_s [s]",
        min_value=1e-4,
        max_value=10.0,
    ),
    ParameterSpec(
        "markers_period_s",
        0.04,
        "markers period in simulated time, a multiple of dt_s [s]",
        min_value=1e-4,
        max_value=100.0,
    ),
    ParameterSpec(
        "diagnostics_period_s",
        0.1,
        "diagnostics period in simulated time, a multiple of dt_s [s]",
        min_value=1e-4,
        max_value=100.0,
    ),
    ParameterSpec(
        "progress_period_s",
        1.0,
        "period in simulated time of the 't = ... s' progress log line [s]",
        min_value=1e-3,
        max_value=1e6,
    ),
    ParameterSpec("ground_contact", True, "spring-damper ground plane at z = 0"),
    ParameterSpec("initial_position_m", [0.0, 0.0, 10.0], "centre of mass, world [m]", length=3),
    ParameterSpec("initial_velocity_m_s", [0.0, 0.0, 0.0], "world frame [m/s]", length=3),
    ParameterSpec(
        "initial_orientation_euler_deg",
        [0.0, 0.0, 0.0],
        "attitude, extrinsic xyz Euler angles (scipy 'xyz') [deg]",
        length=3,
    ),
    ParameterSpec(
        "initial_angular_velocity_rad_s",
        [-0.3, -0.9, 0.9],
        "body frame [rad/s] (paper Table I)",
        length=3,
    ),
    ParameterSpec("initial_radii_m", [2.8, 0.2, 0.2], "r_x, r_y, r_z [m]", length=3),
    ParameterSpec(
        "contact_stiffness_n_m",
        _DEFAULT_CONFIG.contact_stiffness_n_m,
        "ground stiffness per lumped mass [N/m]",
        min_value=1.0,
        max_value=1e8,
    ),
    ParameterSpec(
        "contact_damping_n_s_m",
        _DEFAULT_CONFIG.contact_damping_n_s_m,
        "ground damping per lumped mass [N s/m]",
        min_value=0.0,
        max_value=1e6,
    ),
    ParameterSpec(
        "friction_coefficient",
        _DEFAULT_CONFIG.friction_coefficient,
        "Coulomb friction coefficient mu [-]",
        min_value=0.0,
        max_value=10.0,
    ),
    ParameterSpec(
        "friction_damping_n_s_m",
        _DEFAULT_CONFIG.friction_damping_n_s_m,
        "slope of the regularised friction law below the cone [N s/m]",
        min_value=1e-3,
        max_value=1e6,
    ),
    ParameterSpec(
        "contact_substeps",
        _DEFAULT_CONFIG.contact_substeps,
        "RK4 sub-steps per step while a mass can touch the ground",
        min_value=1,
        max_value=100,
    ),
    ParameterSpec(
        "thrust_stroke_m",
        _DEFAULT_CONFIG.thrust_stroke_m,
        "leg push-off stroke: a hemi pushes while within this height of the ground [m]",
        min_value=0.0,
        max_value=10.0,
    ),
    ParameterSpec(
        "compliant_legs",
        _DEFAULT_CONFIG.compliant_legs,
        "stance legs under impedance control over the stroke (splitter_sim.core.legs)",
    ),
    ParameterSpec(
        "leg_stiffness_n_m",
        _DEFAULT_CONFIG.leg_stiffness_n_m,
        "stiffness of a hemi's legs in stance [N/m]",
        min_value=0.0,
        max_value=1e6,
    ),
    ParameterSpec(
        "leg_damping_n_s_m",
        _DEFAULT_CONFIG.leg_damping_n_s_m,
        "vertical damping of a hemi's legs in stance [N s/m]",
        min_value=0.0,
        max_value=1e6,
    ),
    ParameterSpec(
        "leg_tangential_damping_n_s_m",
        _DEFAULT_CONFIG.leg_tangential_damping_n_s_m,
        "horizontal damping of a hemi's legs in stance (feet planted) [N s/m]",
        min_value=0.0,
        max_value=1e6,
    ),
    ParameterSpec(
        "leg_force_max_n",
        _DEFAULT_CONFIG.leg_force_max_n,
        "largest stance force of a hemi's legs (limbs' dynamic limit) [N]",
        min_value=1e-3,
        max_value=1e5,
    ),
    ParameterSpec(
        "knot_blend_s",
        _DEFAULT_CONFIG.knot_blend_s,
        "a corner of the joint trajectory whose next point is queued ahead (real time) "
        "is rounded by a parabolic blend this long (0: off) [s]",
        min_value=0.0,
        max_value=1.0,
    ),
    ParameterSpec(
        "command_extrapolation_s",
        _DEFAULT_CONFIG.command_extrapolation_s,
        "a joint command's velocity is followed this long past its stamp when no newer "
        "point arrives, then its position is held (real time: cover a late point) [s]",
        min_value=0.0,
        max_value=10.0,
    ),
)


def _period_ns(values: dict, name: str, dt_ns: int) -> int:
    period = round(float(values[name]) * 1e9)
    if period % dt_ns != 0:
        raise InvalidParameterError(
            f"parameter '{name}' ({values[name]} s) must be a multiple of dt_s ({dt_ns * 1e-9} s)"
        )
    return period


def _named(exc: ValueError, fields_to_parameters: dict[str, str]) -> InvalidParameterError:
    """The core's ValueError (which names a SimConfig / InitialState field) as a parameter error."""
    text = str(exc)
    for field_name, parameter in fields_to_parameters.items():
        if field_name in text:
            return InvalidParameterError(f"parameter '{parameter}': {text}")
    return InvalidParameterError(f"simulator parameters: {text}")


_FIELD_PARAMETERS = {
    "radii_m": "initial_radii_m",
    "position_m": "initial_position_m",
    "velocity_m_s": "initial_velocity_m_s",
    "angular_velocity_rad_s": "initial_angular_velocity_rad_s",
    "orientation_wxyz": "initial_orientation_euler_deg",
    "dt_s": "dt_s",
    "contact_stiffness_n_m": "contact_stiffness_n_m",
    "contact_damping_n_s_m": "contact_damping_n_s_m",
    "friction_coefficient": "friction_coefficient",
    "friction_damping_n_s_m": "friction_damping_n_s_m",
    "contact_substeps": "contact_substeps",
    "thrust_stroke_m": "thrust_stroke_m",
    "compliant_legs": "compliant_legs",
    "leg_stiffness_n_m": "leg_stiffness_n_m",
    "leg_damping_n_s_m": "leg_damping_n_s_m",
    "leg_tangential_damping_n_s_m": "leg_tangential_damping_n_s_m",
    "leg_force_max_n": "leg_force_max_n",
    "command_extrapolation_s": "command_extrapolation_s",
    "knot_blend_s": "knot_blend_s",
    "gravity_m_s2": "gravity",
}


class SimulatorNode(Node):
    """Steps the simulator in lockstep with the controllers or in real time."""

    def __init__(self, **kwargs) -> None:
        super().__init__(NODE_NAME, **kwargs)
        try:
            self._sim, values = self._build_simulator()
        except InvalidParameterError:
            self.destroy_node()
            raise
        self._mode = str(values["mode"])
        self._rate_factor = float(values["rate_factor"])
        self._timeout_s = float(values["lockstep_timeout_s"])
        self._startup_wait_s = float(values["startup_wait_s"])
        self._startup_nodes = tuple(values["startup_wait_for_nodes"])
        self._startup_topics = tuple(values["startup_wait_for_publishers"])
        self._startup_settle_s = float(values["startup_settle_s"])
        self._ready_since: float | None = None
        self._startup_subscribers = tuple(values["startup_wait_for_subscribers"])
        dt_ns = self._sim.config.dt_ns
        self._dt_ns = dt_ns
        self._duration_ns = round(float(values["duration_s"]) * 1e9)
        self._control_ns = _period_ns(values, "control_period_s", dt_ns)
        self._markers_ns = _period_ns(values, "markers_period_s", dt_ns)
        self._diagnostics_ns = _period_ns(values, "diagnostics_period_s", dt_ns)
        self._progress_ns = max(dt_ns, round(float(values["progress_period_s"]) * 1e9))

        self.finished = Future()
        self._started = False
        self._first_answer_since: float | None = None  # [s] real time: waiting for tick 0
        self._start_wall = time.monotonic()
        self._run_wall_start: float | None = None
        self._run_start_unix_s = 0.0  # [s] wall clock (epoch) of the first step
        self._published_t_ns: int | None = None
        self._peak_hemi_g = 0.0  # [G] largest hemi specific force of any published state
        self.lockstep = LockstepWait(LOCKSTEP_TOPICS, self._timeout_s)
        self._has_publisher = PublisherPresence(self)
        self._stamps = StampGate(MAX_COMMAND_LEAD_NS)
        self._applied_joint_stamp = 0  # [ns] stamp of the joint command point in effect
        self._queue = CommandQueue()  # joint commands stamped ahead, applied at their stamps
        self._late_joint_commands = 0  # real time: arrived after their stamp
        self._backlog_drops = 0  # real time: times the simulator fell behind the wall clock
        self._behind_s = 0.0  # [s] simulated time it was behind, summed over the drops
        self._slack_events = 0
        self._tension_min_n = math.inf  # [N] lowest tether tension of any step so far
        self._latency = InputLatency()  # commands: simulated time at arrival - stamp
        self._was_slack = False
        self._slack_warned_at = -math.inf  # [s] wall time of the last slack warning
        self._last_state: SimState | None = None
        self._publish_failures = 0

        qos = qos_for
        self._clock_pub = self.create_publisher(ClockMsg, names.CLOCK, qos(names.CLOCK))
        self._joint_pub = self.create_publisher(
            JointState, names.JOINT_STATES, qos(names.JOINT_STATES)
        )
        self._inertia_pub = self.create_publisher(Vector3Stamped, names.INERTIA, qos(names.INERTIA))
        self._odom_pub = self.create_publisher(Odometry, names.ODOM, qos(names.ODOM))
        self._wrench_pubs = tuple(
            self.create_publisher(WrenchStamped, topic, qos(topic))
            for topic in (CONTACT_WRENCH_A, CONTACT_WRENCH_B)
        )
        self._imu_pub = self.create_publisher(Imu, names.IMU, qos(names.IMU))
        self._markers_pub = self.create_publisher(MarkerArray, names.MARKERS, qos(names.MARKERS))
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, names.DIAGNOSTICS, qos(names.DIAGNOSTICS)
        )
        self.create_subscription(
            JointState, names.JOINT_COMMANDS, self._on_joint_commands, qos(names.JOINT_COMMANDS)
        )
        self.create_subscription(
            WrenchStamped, names.JUMP_COMMAND, self._on_jump_command, qos(names.JUMP_COMMAND)
        )
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        if self._mode == "lockstep":
            self._timer = self.create_timer(LOCKSTEP_POLL_S, self._advance, clock=steady)
        else:
            period = max(
                self._sim.config.dt_s / self._rate_factor, 0.001
            )  # [s] catch-up does the rest
            self._timer = self.create_timer(period, self._on_real_time_timer, clock=steady)
        self._pacer = RealTimePacer(self._rate_factor, self._dt_ns)
        self._pacer.restart(time.monotonic(), self._sim.time_ns)
        self.get_logger().info(
            f"simulator ready: {self._mode}"
            + (f" x{self._rate_factor:g}" if self._mode == "real_time" else "")
            + f", dt {self._sim.config.dt_s * 1e3:g} ms, gravity "
            f"{self._sim.config.gravity_m_s2:.4g} m/s^2, ground contact "
            f"{'on' if self._sim.config.ground_contact else 'off'}, duration "
            + (f"{self._duration_ns * 1e-9:g} s" if self._duration_ns else "unlimited")
        )

    # --- parameters ------------------------------------------------------------------
    @property
    def time_ns(self) -> int:
        """Simulated time of the last step [ns]."""
        return self._sim.time_ns

    def _declare_gravity(self) -> float:
        """``gravity``: a preset name (zero, moon, mars, earth) or a number [m/s^2]."""
        descriptor = ParameterDescriptor(
            name="gravity",
            description="gravity: zero, moon, mars, earth, or a value in m/s^2 (string or number)"
            + READ_ONLY_NOTE,
            dynamic_typing=True,
            read_only=True,
        )
        try:
            self.declare_parameter("gravity", "zero", descriptor)
        except ParameterException as exc:
            raise InvalidParameterError(f"parameter 'gravity': {exc}") from exc
        value = self.get_parameter("gravity").value
        if isinstance(value, bool) or not isinstance(value, str | int | float):
            raise InvalidParameterError(
                f"parameter 'gravity': expected a name or a number, got {value!r}"
            )
        try:
            return gravity_from_name(value)
        except ValueError as exc:
            raise InvalidParameterError(f"parameter 'gravity': {exc}") from exc

    def _build_simulator(self) -> tuple[Simulator, dict]:
        values = declare_parameters(self, PARAMETERS)
        gravity = self._declare_gravity()
        try:
            config = SimConfig(
                dt_s=float(values["dt_s"]),
                gravity_m_s2=gravity,
                ground_contact=bool(values["ground_contact"]),
                contact_stiffness_n_m=float(values["contact_stiffness_n_m"]),
                contact_damping_n_s_m=float(values["contact_damping_n_s_m"]),
                friction_coefficient=float(values["friction_coefficient"]),
                friction_damping_n_s_m=float(values["friction_damping_n_s_m"]),
                contact_substeps=int(values["contact_substeps"]),
                thrust_stroke_m=float(values["thrust_stroke_m"]),
                compliant_legs=bool(values["compliant_legs"]),
                leg_stiffness_n_m=float(values["leg_stiffness_n_m"]),
                leg_damping_n_s_m=float(values["leg_damping_n_s_m"]),
                leg_tangential_damping_n_s_m=float(values["leg_tangential_damping_n_s_m"]),
                leg_force_max_n=float(values["leg_force_max_n"]),
                command_extrapolation_s=float(values["command_extrapolation_s"]),
                knot_blend_s=float(values["knot_blend_s"]),
            )
            xyzw = Rotation.from_euler(
                "xyz", values["initial_orientation_euler_deg"], degrees=True
            ).as_quat()
            initial = InitialState(
                position_m=values["initial_position_m"],
                velocity_m_s=values["initial_velocity_m_s"],
                orientation_wxyz=np.roll(xyzw, 1),
                angular_velocity_rad_s=values["initial_angular_velocity_rad_s"],
                radii_m=values["initial_radii_m"],
            )
            return Simulator(RobotModel(), config, initial), values
        except ValueError as exc:
            raise _named(exc, _FIELD_PARAMETERS) from exc

    # --- commands ----------------------------------------------------------------------
    def _checked_trajectory_stamp(self, msg) -> int | None:
        """Real time: the stamp of a joint command point if it may be used, else None."""
        now = self._sim.time_ns
        try:
            stamp = checked_stamp_from_msg(msg.header.stamp)
            check_trajectory_stamp(stamp, self._applied_joint_stamp, now, MAX_TRAJECTORY_LEAD_NS)
        except ValueError as exc:  # MessageValidationError too
            warn_throttled(
                self,
                "joint_commands",
                f"rejected {names.JOINT_COMMANDS} at simulated t = {now * 1e-9:.3f} s: {exc}; "
                "dropped, the trajectory in force stays",
            )
            return None
        self._latency.record("joint_commands", stamp, now)
        return stamp

    def _checked_stamp(self, topic: str, key: str, msg) -> int | None:
        """The command's stamp [ns] if it may be used, else None (warned and counted).

        Rejected: negative or malformed, earlier than the last command of ``topic``,
        or later than the simulated time.
        """
        try:
            stamp = checked_stamp_from_msg(msg.header.stamp)
            self._stamps.check(topic, stamp, self._sim.time_ns)
        except MessageValidationError as exc:
            warn_throttled(
                self,
                key,
                f"rejected {topic} at simulated t = {self._sim.time_ns * 1e-9:.3f} s: {exc}; "
                "dropped, the last good command stays in force",
            )
            return None
        self._stamps.accept(topic, stamp)
        self._latency.record(key, stamp, self._sim.time_ns)
        return stamp

    def _on_joint_commands(self, msg: JointState) -> None:
        if self._mode == "real_time":
            stamp = self._checked_trajectory_stamp(msg)
        else:
            stamp = self._checked_stamp(names.JOINT_COMMANDS, "joint_commands", msg)
        if stamp is None:
            return
        try:
            sample = joint_state_from_msg(msg)
            now = self._sim.time_ns
            if stamp > now:  # real time: a trajectory point ahead, followed at its stamp
                validate_joint_command(
                    self._sim.joint_limits, sample.position, sample.velocity, names.JOINT_NAMES
                )
                self._queue.push(stamp, (sample.position, sample.velocity))
            else:
                self._late_joint_commands += stamp < now
                self._queue.drop_from(stamp)  # a later plan: the points queued are void
                self._sim.command_joints(sample.position, sample.velocity, stamp_ns=stamp)
                self._applied_joint_stamp = stamp
        except ValueError as exc:  # MessageValidationError is a ValueError
            warn_throttled(
                self, "joint_commands", f"rejected joint command at {stamp * 1e-9:.3f} s: {exc}"
            )
        self._command_arrived(names.JOINT_COMMANDS, stamp)

    def _on_jump_command(self, msg: WrenchStamped) -> None:
        stamp = self._checked_stamp(names.JUMP_COMMAND, "jump_command", msg)
        if stamp is None:
            return
        try:
            sample = wrench_from_msg(msg)
            if sample.frame_id != names.WORLD_FRAME:
                raise MessageValidationError(
                    f"header.frame_id: expected '{names.WORLD_FRAME}', got {sample.frame_id!r}"
                )
            check_jump_wrench(sample.force_n, sample.torque_nm)
            self._sim.command_jump_force(
                sample.force_n, pushing_hemi(self._last_state, sample.force_n, sample.torque_nm)
            )
        except ValueError as exc:
            warn_throttled(
                self, "jump_command", f"rejected jump command at {stamp * 1e-9:.3f} s: {exc}"
            )
        self._command_arrived(names.JUMP_COMMAND, stamp)

    def _command_arrived(self, topic: str, stamp: int) -> None:
        self.lockstep.arrived(topic, stamp)
        if self._mode == "lockstep" and self._started and stamp == self._sim.time_ns:
            self._advance()

    # --- stepping ----------------------------------------------------------------------
    def _ready_to_start(self) -> bool:
        """Stepping starts once the graph is connected (or ``startup_wait_s`` ran out)."""
        waited = time.monotonic() - self._start_wall
        missing = [
            t for t in LOCKSTEP_TOPICS if self._mode == "lockstep" and self.count_publishers(t) == 0
        ]
        missing += [t for t in self._startup_topics if self.count_publishers(t) == 0]
        unheard = [t for t in STATE_TOPICS if self.count_subscribers(t) == 0]
        present = set(self.get_node_names())
        absent = [n for n in self._startup_nodes if n not in present]
        unsubscribed = [
            f"{n} on {t}"
            for t in STATE_TOPICS
            for n in self._startup_subscribers
            if n not in {i.node_name for i in self.get_subscriptions_info_by_topic(t)}
        ]
        # The graph cache learns of a subscription before DDS has matched it with our
        # writer: also wait until every state publisher has matched every subscriber.
        unmatched = [
            pub.topic_name
            for pub in self._state_publishers()
            if pub.get_subscription_count() < self.count_subscribers(pub.topic_name)
        ]
        waiting = missing or unheard or absent or unsubscribed or unmatched
        if waiting and waited < self._startup_wait_s:
            self._ready_since = None
            return False
        if not waiting:
            now = time.monotonic()
            self._ready_since = self._ready_since if self._ready_since is not None else now
            if now - self._ready_since < self._startup_settle_s:
                return False
        if waiting:
            self.get_logger().warning(
                f"starting after {waited:.1f} s without "
                + ", ".join(
                    [f"a publisher on {t}" for t in missing]
                    + [f"a subscriber on {t}" for t in unheard]
                    + [f"node {n}" for n in absent]
                    + [f"subscriber {x}" for x in unsubscribed]
                    + [f"every DDS match on {t}" for t in unmatched]
                )
                + ": topics without a publisher are not waited for"
            )
        self._run_wall_start = time.monotonic()
        self._run_start_unix_s = time.time()
        self.get_logger().info(f"t = {self._sim.time_ns * 1e-9:.2f} s: stepping starts")
        return True

    def _state_publishers(self) -> list:
        """The publishers of ``STATE_TOPICS`` and /clock."""
        return [p for p in self.publishers if p.topic_name in (*STATE_TOPICS, names.CLOCK)]

    def _advance(self) -> None:
        """Lockstep driver: publish, wait for the tick's commands, step; never blocks."""
        if self.finished.done():
            return
        if not self._started:
            if not self._ready_to_start():
                return
            self._started = True
        budget_end = time.monotonic() + BATCH_WALL_S
        while not self.finished.done():
            t = self._sim.time_ns
            if self._published_t_ns != t:
                self._publish_state(t)
                if self._end_reached(t):
                    return
            if t % self._control_ns == 0 and not self._tick_answered(t):
                return
            self._step()
            if time.monotonic() > budget_end:
                return

    def _tick_answered(self, t: int) -> bool:
        waiting = self.lockstep.waiting_for(t, self._has_publisher)
        step, waited = self.lockstep.may_step(waiting, time.monotonic())
        if waited is not None:
            self.get_logger().warning(
                f"lockstep: no message stamped t = {t * 1e-9:.3f} s on {', '.join(waiting)} "
                f"after {waited:.1f} s (lockstep_timeout_s); stepping on the last "
                f"good commands ({self.lockstep.timeouts} timeouts so far)"
            )
        return step

    def _on_real_time_timer(self) -> None:
        """Real-time driver: as many steps as the wall clock (x rate_factor) asks for."""
        if self.finished.done():
            return
        now = time.monotonic()
        if not self._started:
            if not self._ready_to_start():
                return
            self._started = True
            self._first_answer_since = now
            self._publish_state(self._sim.time_ns)
            return
        if self._first_answer_since is not None:
            # The wall clock starts once the controllers answered the first state (as a
            # robot starts once its computer is up): a launch thrust stamped 0 then acts
            # at 0, not a latency later. At most lockstep_timeout_s is waited.
            t = self._sim.time_ns
            waiting = self.lockstep.waiting_for(t, self._has_publisher)
            if waiting and now - self._first_answer_since < self.lockstep.timeout_s:
                return
            if waiting:
                self.get_logger().warning(
                    f"real time: no answer to the first state on {', '.join(waiting)} after "
                    f"{now - self._first_answer_since:.1f} s; the clock starts without it"
                )
            self._first_answer_since = None
            self._pacer.restart(now, t)
            return
        steps, dropped = self._pacer.steps_due(now, self._sim.time_ns)
        for _ in range(steps):
            if self.finished.done():
                return
            self._step()
            self._publish_state(self._sim.time_ns)
            self._end_reached(self._sim.time_ns)
        if dropped and not self.finished.done():
            behind_s = (self._pacer.due_ns(now) - self._sim.time_ns) * 1e-9
            self._backlog_drops += 1
            self._behind_s += behind_s
            self.get_logger().warning(
                f"real time: {behind_s:.3f} s behind at rate_factor {self._rate_factor:g}; "
                f"pacing from here (every step is still taken; {self._backlog_drops} times "
                f"behind, {self._behind_s:.3f} s in all)",
                throttle_duration_sec=5.0,
            )
            self._pacer.restart(now, self._sim.time_ns)

    def _step(self) -> None:
        """One simulator step, after applying the queued command points now due."""
        if self._queue:
            due = self._queue.due(self._sim.time_ns)
            if due is not None:
                stamp, (position, velocity) = due
                self._sim.command_joints(position, velocity, stamp_ns=stamp)
                self._applied_joint_stamp = stamp
            upcoming = self._queue.peek()
            if upcoming is not None:
                self._sim.preview_next_point(upcoming[0], upcoming[1][1])
        self._sim.step()

    def _end_reached(self, t: int) -> bool:
        if not self._duration_ns or t < self._duration_ns:
            return False
        self._timer.cancel()
        self._publish_diagnostics(t, final=True)
        state = self._last_state
        wall = time.monotonic() - (self._run_wall_start or self._start_wall)
        summary = (
            f"t = {t * 1e-9:.2f} s: simulation finished (duration_s reached) after {wall:.1f} s "
            f"wall (real-time factor {t * 1e-9 / max(wall, 1e-9):.1f})"
        )
        if state is not None:
            summary += (
                f"; energy {state.kinetic_energy_j:.6g} J, |H| "
                f"{np.linalg.norm(state.angular_momentum_world):.6g} kg m^2/s, tension "
                f"{state.tether_tension_n:.4g} N, {self._slack_events} slack events, "
                f"{self.lockstep.timeouts} lockstep timeouts, rejected commands "
                f"{rejection_counts(self) or 'none'}"
            )
        self.get_logger().info(summary)
        self.finished.set_result(True)
        return True

    # --- outputs ------------------------------------------------------------------------
    def _publish_state(self, t: int) -> None:
        state = self._sim.state()
        self._published_t_ns = t
        self._peak_hemi_g = max(self._peak_hemi_g, float(np.max(state.hemi_acceleration_g)))
        if not state.is_finite():
            self._publish_failures += 1
            self.get_logger().error(
                f"t = {t * 1e-9:.3f} s: non-finite simulator state, not published",
                throttle_duration_sec=2.0,
            )
            return
        try:
            msgs = (
                (self._clock_pub, clock_to_msg(t)),
                (
                    self._joint_pub,
                    joint_state_to_msg(t, state.joint_position, state.joint_velocity),
                ),
                (
                    self._inertia_pub,
                    vector3_to_msg(t, state.principal_inertia_kg_m2, names.BASE_FRAME),
                ),
                (
                    self._odom_pub,
                    odom_to_msg(
                        t,
                        state.position_m,
                        state.orientation_wxyz,
                        state.velocity_m_s,
                        state.angular_velocity_rad_s,
                    ),
                ),
                *(
                    (
                        self._wrench_pubs[h],
                        wrench_to_msg(
                            t,
                            state.contact_force_n[h],
                            state.contact_torque_n_m[h],
                            names.WORLD_FRAME,
                        ),
                    )
                    for h in (0, 1)
                ),
                (
                    self._imu_pub,
                    imu_to_msg(
                        t,
                        state.orientation_wxyz,
                        state.angular_velocity_rad_s,
                        state.linear_acceleration_m_s2,
                    ),
                ),
            )
        except MessageValidationError as exc:
            self._publish_failures += 1
            self.get_logger().error(
                f"t = {t * 1e-9:.3f} s: state not published: {exc}", throttle_duration_sec=2.0
            )
            return
        self._last_state = state
        for publisher, msg in msgs:
            publisher.publish(msg)
        self._tension_min_n = min(self._tension_min_n, state.tether_tension_n)
        if state.tether_slack and not self._was_slack:
            self._slack_events += 1
            # throttled here: rclpy's throttle looks up the caller's source line first
            now = time.monotonic()
            if now - self._slack_warned_at >= SLACK_WARNING_PERIOD_S:
                self._slack_warned_at = now
                self.get_logger().warning(
                    f"t = {t * 1e-9:.3f} s: tether slack (tension {state.tether_tension_n:.3g} N)"
                )
        self._was_slack = state.tether_slack
        if t % self._markers_ns == 0:
            self._markers_pub.publish(_markers(t, state))
        if t % self._diagnostics_ns == 0:
            self._publish_diagnostics(t)
        if t % self._progress_ns == 0 and t > 0:
            wall = time.monotonic() - (self._run_wall_start or self._start_wall)
            self.get_logger().info(
                f"t = {t * 1e-9:.2f} s (real-time factor {t * 1e-9 / max(wall, 1e-9):.1f})"
            )

    def _publish_diagnostics(self, t: int, final: bool = False) -> None:
        state = self._last_state
        if state is None:
            return
        rejected = rejection_counts(self)
        h = state.angular_momentum_world
        level = 0
        message = "finished" if final else "running"
        if state.tether_slack:
            level, message = 1, "tether slack"
        if self.lockstep.timeouts:
            message += f", {self.lockstep.timeouts} lockstep timeouts"
        values = {
            "kinetic_energy_j": state.kinetic_energy_j,
            "rotational_energy_j": state.rotational_energy_j,
            "angular_momentum_world_x_kg_m2_s": float(h[0]),
            "angular_momentum_world_y_kg_m2_s": float(h[1]),
            "angular_momentum_world_z_kg_m2_s": float(h[2]),
            "angular_momentum_norm_kg_m2_s": float(np.linalg.norm(h)),
            "tether_tension_n": state.tether_tension_n,
            "tether_slack": bool(state.tether_slack),
            "slack_events": self._slack_events,
            "tether_tension_min_n": self._tension_min_n,
            "hemi_a_in_contact": bool(state.in_contact[0]),
            "hemi_b_in_contact": bool(state.in_contact[1]),
            "hemi_a_contact_normal_force_n": float(state.contact_force_n[0, 2]),
            "hemi_b_contact_normal_force_n": float(state.contact_force_n[1, 2]),
            "hemi_a_acceleration_g": float(state.hemi_acceleration_g[0]),
            "hemi_b_acceleration_g": float(state.hemi_acceleration_g[1]),
            "hemi_peak_acceleration_g": self._peak_hemi_g,
            "actuator_power_w": state.actuator_power_w,
            "actuator_work_j": state.actuator_work_j,
            "rejected_joint_commands": rejected.get("joint_commands", 0),
            "rejected_jump_commands": rejected.get("jump_command", 0),
            "lockstep_timeouts": self.lockstep.timeouts,
            **self._latency.values(),
            "late_joint_commands": self._late_joint_commands,
            "queued_joint_commands": len(self._queue),
            "real_time_backlog_drops": self._backlog_drops,
            "real_time_behind_s": self._behind_s,
            "unpublished_states": self._publish_failures,
            "finished": final,
        }
        if self._run_wall_start is not None:  # wall times (not deterministic)
            values["run_start_unix_s"] = self._run_start_unix_s
            values["flight_wall_time_s"] = time.monotonic() - self._run_wall_start
        status = DiagnosticStatusSample(f"{NODE_NAME}: physics", level, message, values)
        try:
            self._diagnostics_pub.publish(diagnostics_to_msg(t, [status]))
        except MessageValidationError as exc:
            self.get_logger().error(f"diagnostics not published: {exc}", throttle_duration_sec=2.0)


def _point(p) -> Point:
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def _markers(t_ns: int, state: SimState) -> MarkerArray:
    """10 mass spheres, the tether and limb lines, and the scene's arrows (body axes,
    angular momentum, contact forces; :mod:`splitter_sim.core.scene`), world frame."""
    stamp = stamp_to_msg(t_ns)
    positions = state.mass_positions_world_m
    out = MarkerArray()
    for i, p in enumerate(positions):
        m = Marker()
        m.header.stamp = stamp
        m.header.frame_id = names.WORLD_FRAME
        m.ns = "splitter_masses"
        m.id = i
        m.type = Marker.SPHERE
        m.action = Marker.ADD
        m.pose.position = _point(p)
        m.pose.orientation.w = 1.0
        size = 0.25 if i in (0, 5) else 0.15  # [m] bodies larger than limb tips
        m.scale.x = m.scale.y = m.scale.z = size
        m.color.r, m.color.g, m.color.b, m.color.a = (
            (0.9, 0.4, 0.1, 1.0) if i < 5 else (0.1, 0.5, 0.9, 1.0)
        )
        out.markers.append(m)
    tether = Marker()
    tether.header.stamp = stamp
    tether.header.frame_id = names.WORLD_FRAME
    tether.ns = "splitter_tether"
    tether.id = 0
    tether.type = Marker.LINE_STRIP
    tether.action = Marker.ADD
    tether.pose.orientation.w = 1.0
    tether.scale.x = 0.02  # [m] line width
    tether.color.r = tether.color.g = tether.color.b = 0.8
    tether.color.a = 1.0
    tether.points = [_point(positions[0]), _point(positions[5])]
    out.markers.append(tether)
    limbs = Marker()
    limbs.header.stamp = stamp
    limbs.header.frame_id = names.WORLD_FRAME
    limbs.ns = "splitter_limbs"
    limbs.id = 0
    limbs.type = Marker.LINE_LIST
    limbs.action = Marker.ADD
    limbs.pose.orientation.w = 1.0
    limbs.scale.x = 0.03  # [m] line width
    limbs.color.r, limbs.color.g, limbs.color.b, limbs.color.a = 0.3, 0.3, 0.3, 1.0
    for body in (0, 5):
        for tip in range(body + 1, body + 5):
            limbs.points += [_point(positions[body]), _point(positions[tip])]
    out.markers.append(limbs)
    arrows = scene_arrows(
        state.position_m,
        state.orientation_wxyz,
        state.principal_inertia_kg_m2,
        state.angular_velocity_rad_s,
        mass_positions_world=positions,
        contact_forces_n=state.contact_force_n,
    )
    for i, arrow in enumerate(arrows):
        m = Marker()
        m.header.stamp = stamp
        m.header.frame_id = names.WORLD_FRAME
        m.ns = "splitter_arrows"
        m.id = i
        m.text = arrow.name
        m.type = Marker.ARROW
        m.action = Marker.ADD
        m.pose.orientation.w = 1.0
        m.points = [_point(arrow.start), _point(arrow.end)]
        m.scale.x, m.scale.y, m.scale.z = 0.03, 0.06, 0.1  # [m] shaft, head width, head length
        m.color.r, m.color.g, m.color.b, m.color.a = arrow.color
        out.markers.append(m)
    return out


def main(args: list[str] | None = None) -> int:
    """Run until duration_s (if set), Ctrl-C or shutdown; an invalid parameter exits with 1."""
    return run_node(
        lambda stop: SimulatorNode(),
        NODE_NAME,
        args,
        spin=lambda node, stop: spin_until_stopped(node, stop, finished=node.finished.done),
    )


if __name__ == "__main__":
    raise SystemExit(main())
