"""``inertial_morphing_mpc`` node: the MPC of paper section VI on the node graph.

ROS plumbing over :class:`splitter_mpc.core.mpc_tick.MpcTick` and its
:class:`~splitter_mpc.core.controller.MorphingController` (the library loop drives
the same objects). Lockstep (docs/ARCHITECTURE.md): once it holds
``/splitter/imu`` and ``/splitter/inertia`` stamped with the same control tick
``t`` it re-plans (on the 100 ms grid, or without a plan) and publishes the
setpoint for ``t`` on ``/splitter/inertia_setpoint`` stamped ``t``. The first tick
waits for the attitude reference (``/splitter/attitude_reference`` and
``/splitter/attitude_reference_pose``, latched, published by the gait phase
manager on its first tick), and for the gait phase when a node publishes one, so
that the first plan does not depend on message order (a first tick answered before
the phase arrived would plan where LAUNCH holds the nominal shape).
``/splitter/gait_phase`` (latched) switches it off in LANDED.
``/splitter/joint_health`` (the allocator's, after a joint fault): the MPC plans within
the radius bounds that remain from its next solve on (``splitter_model.redundancy``).
When a gait phase manager is in the graph (it publishes
``/splitter/jump_command``), each tick ``t`` is answered only after the manager's
jump command stamped ``t``: the manager publishes a phase or reference change of
tick ``t`` before that command, so tick ``t`` plans with the phase and reference
of tick ``t`` whatever the message timing, in the library loop's order (gait,
then MPC). ``/diagnostics`` every 100 ms of simulated time: solve time,
iterations, status, cost. Bad messages are rejected with a throttled warning; the
node keeps its last good data. Parameters: the fields of the core's configuration
classes (:data:`splitter_mpc.core.mpc_tick.PARAMETER_CLASSES`); the weights and the
recovery supervisor are live (NLP parameters of the compiled solver).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import Imu
from std_msgs.msg import Bool, String

from splitter_model.model import RobotModel
from splitter_mpc.core.controller import MorphingController
from splitter_mpc.core.mpc_tick import (
    PARAMETER_CLASSES,
    PARAMETER_NAMES,
    MpcAnswer,
    MpcTick,
    checked_hemi_inertia,
    checked_masses,
    checked_rate,
    controller_config_from_parameters,
    tick_settings_from_parameters,
)
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    MessageValidationError,
    imu_from_msg,
    joint_health_from_msg,
    pose_from_msg,
    principal_inertia_from_msg,
    stamp_from_msg,
    twist_from_msg,
    vector3_from_msg,
    vector3_to_msg,
)
from splitter_msgs_py.node_pattern import admitted_stamp, default_sim_time, run_node, sim_clock_ns
from splitter_msgs_py.node_status import publish_status
from splitter_msgs_py.parameters import (
    InvalidParameterError,
    ParameterValue,
    declare_parameters,
    specs_from_config,
    warn_throttled,
)
from splitter_msgs_py.presence import PublisherPresence
from splitter_msgs_py.qos import LATCHED_QOS, qos_for
from splitter_msgs_py.signals import StopRequest

NODE_NAME = "inertial_morphing_mpc"
PARAMETERS = tuple(
    dataclasses.replace(spec, name=PARAMETER_NAMES.get(spec.name, spec.name))
    for config in PARAMETER_CLASSES
    for spec in specs_from_config(config)
)


def _frame(frame_id: str, expected: str) -> None:
    if frame_id != expected:
        raise MessageValidationError(f"header.frame_id: expected {expected!r}, got {frame_id!r}")


def _read_imu(msg: Imu) -> object:
    _frame(msg.header.frame_id, names.BASE_FRAME)
    sample = imu_from_msg(msg)
    return checked_rate("angular_velocity", sample.angular_velocity_rad_s), sample.orientation_wxyz


def _read_w_ref(msg: TwistStamped) -> object:
    _frame(msg.header.frame_id, names.BASE_FRAME)
    linear = msg.twist.linear
    if (linear.x, linear.y, linear.z) != (0.0, 0.0, 0.0):  # NaN compares unequal too
        raise MessageValidationError("twist.linear: a rate reference has none")
    return checked_rate("twist.angular", twist_from_msg(msg)[1])


def _read_q_ref(msg: PoseStamped) -> object:
    _frame(msg.header.frame_id, names.WORLD_FRAME)
    return pose_from_msg(msg)[1]


# topic: (message type, its QoS, the value the core takes from it)
INPUTS: dict[str, tuple[type, object, Callable[[object], object]]] = {
    names.IMU: (Imu, qos_for(names.IMU), _read_imu),
    names.INERTIA: (
        Vector3Stamped,
        qos_for(names.INERTIA),
        lambda msg: principal_inertia_from_msg(msg).vector,
    ),
    names.ATTITUDE_REFERENCE: (TwistStamped, LATCHED_QOS, _read_w_ref),
    names.ATTITUDE_REFERENCE_POSE: (PoseStamped, LATCHED_QOS, _read_q_ref),
    names.GAIT_PHASE: (String, LATCHED_QOS, lambda msg: msg.data),  # no stamp
    names.STANCE_SHAPE: (Bool, LATCHED_QOS, lambda msg: bool(msg.data)),  # no stamp
    names.JUMP_COMMAND: (WrenchStamped, qos_for(names.JUMP_COMMAND), lambda msg: None),
    names.ESTIMATE_MASSES: (
        Vector3Stamped,
        qos_for(names.ESTIMATE_MASSES),
        lambda msg: checked_masses(vector3_from_msg(msg).vector),
    ),
    names.ESTIMATE_HEMI_INERTIA: (
        Vector3Stamped,
        qos_for(names.ESTIMATE_HEMI_INERTIA),
        lambda msg: checked_hemi_inertia(vector3_from_msg(msg).vector),
    ),
}
ESTIMATED_MODEL = (names.ESTIMATE_MASSES, names.ESTIMATE_HEMI_INERTIA)


class InertialMorphingMpcNode(Node):
    """Answers each control tick's imu + inertia with an inertia setpoint."""

    def __init__(self, stop: StopRequest | None = None, **kwargs) -> None:
        super().__init__(NODE_NAME, **default_sim_time(kwargs))
        try:
            values = declare_parameters(self, PARAMETERS, on_live_change=self._apply_live)
            try:
                config = controller_config_from_parameters(values)
                settings = tick_settings_from_parameters(values)
            except ValueError as exc:
                raise InvalidParameterError(f"parameters: {exc}") from exc
        except InvalidParameterError:
            self.destroy_node()
            raise
        self.get_logger().info(
            f"building the MPC (solver {config.mpc.solver}, N = {config.mpc.horizon}, "
            f"dt = {config.mpc.dt_s} s); the first start compiles and caches its code"
        )
        controller = MorphingController(RobotModel(), config)
        if stop is not None and hasattr(controller.mpc.backend, "abandon"):
            # a stop signal ends a solve being waited for (the worker is killed)
            controller.mpc.backend.abandon = lambda: stop.requested
        try:
            self.tick = MpcTick(controller, settings, PublisherPresence(self))
        except ValueError as exc:
            controller.close()
            self.destroy_node()
            raise InvalidParameterError(f"parameters: {exc}") from exc
        self._setpoint_pub = self.create_publisher(
            Vector3Stamped, names.INERTIA_SETPOINT, qos_for(names.INERTIA_SETPOINT)
        )
        self._diagnostics_pub = self.create_publisher(
            DiagnosticArray, names.DIAGNOSTICS, qos_for(names.DIAGNOSTICS)
        )
        for topic, (msg_type, qos, _read) in INPUTS.items():
            if topic in ESTIMATED_MODEL and not settings.estimated_masses:
                continue
            self.create_subscription(
                msg_type, topic, lambda msg, topic=topic: self._on_input(topic, msg), qos
            )
        self.create_subscription(
            DiagnosticArray,
            names.JOINT_HEALTH,
            self._on_joint_health,
            qos_for(names.JOINT_HEALTH),
        )
        self.get_logger().info("ready")

    @property
    def controller(self) -> MorphingController:
        """The MPC scheduler the tick drives."""
        return self.tick.controller

    def _apply_live(self, values: Mapping[str, ParameterValue]) -> None:
        """A live parameter change: the controller's weights and scheduler settings."""
        config = controller_config_from_parameters(values)
        self.tick.reconfigure(config, tick_settings_from_parameters(values))

    def destroy_node(self) -> None:
        """Stop the solver worker with the node."""
        tick = getattr(self, "tick", None)
        if tick is not None:
            tick.controller.close()
        super().destroy_node()

    # --- inputs --------------------------------------------------------------------------
    def _reject(self, key: str, exc: Exception | str) -> None:
        warn_throttled(self, key, f"rejected {key}: {exc}; keeping the last good data")

    def _clock_ns(self) -> int | None:
        return sim_clock_ns(self)

    def _on_joint_health(self, msg: DiagnosticArray) -> None:
        """The radius bounds a joint fault left, planned within from the next solve."""
        try:
            health = joint_health_from_msg(msg)
        except MessageValidationError as exc:
            warn_throttled(self, "joint_health", f"rejected {names.JOINT_HEALTH}: {exc}")
            return
        if self.controller.mpc.radius_bounds_m is None:
            self.get_logger().warning(
                f"joints {', '.join(health.symptoms)} faulty: planning within radii "
                f"{health.radius_min_m.round(4).tolist()} .. "
                f"{health.radius_max_m.round(4).tolist()} m"
            )
        stamp = stamp_from_msg(msg.header.stamp)
        self.controller.set_radius_bounds(health.radius_min_m, health.radius_max_m, stamp)

    def _on_input(self, topic: str, msg: object) -> None:
        """The message read and checked, then its stamp admitted, then given to the tick."""
        try:
            value = INPUTS[topic][2](msg)
        except MessageValidationError as exc:
            self._reject(topic, exc)
            return
        t_ns = None
        if topic not in (names.GAIT_PHASE, names.STANCE_SHAPE):
            t_ns = admitted_stamp(
                self,
                self.tick.stamps,
                topic,
                msg,
                clock_ns=self._clock_ns,
                not_before_ns=self.tick.last_answered if topic in self.tick.tick_inputs else None,
                consequence="keeping the last good data",
            )
            if t_ns is None:
                return
        try:
            answer = self.tick.add(topic, t_ns, value, self._clock_ns)
        except ValueError as exc:  # an unknown phase, a reference the controller refuses
            self._reject(topic, exc)
            return
        self._publish(answer)

    # --- the answer ----------------------------------------------------------------------
    def _publish(self, answer: MpcAnswer | None) -> None:
        if answer is None:
            return
        if answer.setpoint_kg_m2 is None:
            self._reject("state", answer.error)
            return
        msg = vector3_to_msg(answer.t_ns, answer.setpoint_kg_m2, names.BASE_FRAME)
        self._setpoint_pub.publish(msg)
        if answer.diagnostics is not None:
            publish_status(
                self,
                self._diagnostics_pub,
                answer.t_ns,
                f"{NODE_NAME}: inertia setpoint",
                answer.diagnostics,
            )


def main(args: list[str] | None = None) -> int:
    """Run the node until Ctrl-C or shutdown; an invalid parameter stops it with exit code 1."""
    return run_node(lambda stop: InertialMorphingMpcNode(stop=stop), NODE_NAME, args)


if __name__ == "__main__":
    raise SystemExit(main())
