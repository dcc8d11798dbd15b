"""gait_phase_manager node in-process: lockstep answers, phases, references, bad input."""

from __future__ import annotations

import math
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, TwistStamped, Vector3Stamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from splitter_mpc.core.gait import (
    gait_config_from_parameters,
    momentum_aligned_attitude,
    rotation_matrix,
)
from splitter_mpc.gait_phase_manager_node import GaitPhaseManagerNode, main
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    diagnostics_from_msg,
    joint_state_to_msg,
    odom_to_msg,
    pose_from_msg,
    stamp_from_msg,
    twist_from_msg,
    vector3_to_msg,
    wrench_from_msg,
    wrench_to_msg,
)
from splitter_msgs_py.parameters import InvalidParameterError
from splitter_msgs_py.qos import LATCHED_QOS, qos_for
from splitter_msgs_py.testing import spin_until, spun_together

MS = 1_000_000  # [ns]
TETHER_M = 2.8  # [m] distance between the hemi bodies: r_x = 1.4 m
PITCH_RAD = math.radians(10.0)  # constant attitude of the synthetic body
Q_BODY = np.array([math.cos(PITCH_RAD / 2), 0.0, math.sin(PITCH_RAD / 2), 0.0])
FORCE_N = (40.0, 0.0, 40.0)
INERTIA_KG_M2 = (0.48, 141.36, 141.36)  # [kg m^2] principal moments at the paper's radii
CONFIG_FILE = Path(__file__).resolve().parents[1] / "config" / "gait_phase_manager.yaml"

PLAN = [
    Parameter("jump_times_s", value=[0.0, 0.5]),
    Parameter("jump_forces_n", value=[*FORCE_N, *FORCE_N]),
    Parameter("jump_durations_s", value=[0.1, 0.1]),
    Parameter("jump_hemis", value=["b", "auto"]),
    Parameter("landed_dwell_s", value=0.1),
    Parameter("w_ref_rad_s", value=[0.0, 1.0, 0.0]),
]


def scripted_state(t_ms: int) -> tuple[tuple[float, float], tuple[float, float, float]]:
    """(normal forces on hemi a, b [N]; COM velocity [m/s]) of a scripted two-jump run.

    Stance on both hemis until 50 ms, flight, hemi a touches down at 300 ms and
    stays (jump 2 at 500 ms pushes through it), flight from 550 ms, touchdown on
    both at 800 ms and at rest from 850 ms.
    """
    if t_ms < 50:
        return (20.0, 20.0), (0.0, 0.0, 0.0)
    if t_ms < 300:
        return (0.0, 0.0), (1.0, 0.0, 0.5)
    if t_ms < 550:
        return (20.0, 0.0), (0.2, 0.0, 0.0)
    if t_ms < 800:
        return (0.0, 0.0), (1.2, 0.0, 0.3)
    if t_ms < 850:
        return (15.0, 15.0), (0.3, 0.0, 0.0)
    return (15.0, 15.0), (0.0, 0.0, 0.0)


class FakeSimulator:
    """Publishes the gait manager's inputs stamped t and records what it answers."""

    def __init__(self, context) -> None:
        self.node = rclpy.create_node("fake_simulator", context=context)
        self.odom = self.node.create_publisher(Odometry, names.ODOM, qos_for(names.ODOM))
        self.contacts = [
            self.node.create_publisher(WrenchStamped, topic, qos_for(topic))
            for topic in names.CONTACT_WRENCHES
        ]
        self.joints = self.node.create_publisher(
            JointState, names.JOINT_STATES, qos_for(names.JOINT_STATES)
        )
        self.inertia = self.node.create_publisher(
            Vector3Stamped, names.INERTIA, qos_for(names.INERTIA)
        )
        self.jump_commands: list[WrenchStamped] = []
        self.phases: list[str] = []
        self.w_refs: list[TwistStamped] = []
        self.q_refs: list[PoseStamped] = []
        self.diagnostics: list[DiagnosticArray] = []
        self.node.create_subscription(
            WrenchStamped,
            names.JUMP_COMMAND,
            self.jump_commands.append,
            qos_for(names.JUMP_COMMAND),
        )
        self.node.create_subscription(
            String, names.GAIT_PHASE, lambda m: self.phases.append(m.data), LATCHED_QOS
        )
        self.node.create_subscription(
            TwistStamped, names.ATTITUDE_REFERENCE, self.w_refs.append, LATCHED_QOS
        )
        self.node.create_subscription(
            PoseStamped, names.ATTITUDE_REFERENCE_POSE, self.q_refs.append, LATCHED_QOS
        )
        self.node.create_subscription(
            DiagnosticArray, names.DIAGNOSTICS, self.diagnostics.append, qos_for(names.DIAGNOSTICS)
        )

    def publish_state(
        self,
        t_ns: int,
        odom: Odometry | None = None,
        inertia: Vector3Stamped | None = None,
    ) -> None:
        normal, velocity = scripted_state(t_ns // MS)
        self.inertia.publish(inertia or vector3_to_msg(t_ns, INERTIA_KG_M2, names.BASE_FRAME))
        joints = np.zeros(names.N_JOINTS)
        joints[names.JOINT_INDEX[names.TETHER_JOINT]] = TETHER_M
        self.joints.publish(joint_state_to_msg(t_ns, joints))
        for publisher, fz in zip(self.contacts, normal, strict=True):
            publisher.publish(
                wrench_to_msg(t_ns, (0.0, 0.0, fz), (0.0, 0.0, 0.0), names.WORLD_FRAME)
            )
        if odom is None:
            odom = odom_to_msg(t_ns, (0.1 * t_ns / 1e9, 0.0, 0.45), Q_BODY, velocity, (0, 0, 0))
        self.odom.publish(odom)


@contextmanager
def gait_graph(ros_context, overrides=PLAN):
    """The gait manager (``overrides``), a scripted simulator and one executor for both."""
    manager = GaitPhaseManagerNode(context=ros_context, parameter_overrides=overrides)
    sim = FakeSimulator(ros_context)
    with spun_together(ros_context, manager, sim.node) as executor:
        yield manager, sim, executor


@pytest.fixture
def graph(ros_context):
    with gait_graph(ros_context) as nodes:
        yield nodes


def run_ticks(sim: FakeSimulator, executor, ticks_ms, bad_odom_at_ms: int | None = None) -> None:
    """Lockstep: publish a tick's inputs and wait for its jump command, like the simulator."""
    for t_ms in ticks_ms:
        t_ns = t_ms * MS
        odom = None
        if t_ms == bad_odom_at_ms:
            odom = odom_to_msg(t_ns, (0.0, 0.0, 0.45), Q_BODY, (0, 0, 0), (0, 0, 0))
            odom.pose.pose.position.z = math.nan
        sim.publish_state(t_ns, odom)
        if t_ms % 10 == 0:
            spin_until(
                executor,
                lambda t_ns=t_ns: any(
                    stamp_from_msg(m.header.stamp) == t_ns for m in sim.jump_commands
                ),
            )
        else:
            for _ in range(5):
                executor.spin_once(timeout_sec=0.001)


def test_node_answers_every_tick_and_sequences_the_phases(graph) -> None:
    _manager, sim, executor = graph
    run_ticks(sim, executor, range(0, 1005, 5), bad_odom_at_ms=300)
    spin_until(executor, lambda: len(sim.diagnostics) >= 11 and sim.phases[-1:] == ["LANDED"])

    stamps = [stamp_from_msg(m.header.stamp) // MS for m in sim.jump_commands]
    assert stamps == list(range(0, 1010, 10))  # one command per 10 ms tick, none off-grid
    commands = {stamp_from_msg(m.header.stamp) // MS: wrench_from_msg(m) for m in sim.jump_commands}
    assert all(c.frame_id == names.WORLD_FRAME for c in commands.values())
    thrust_ms = [t for t, c in commands.items() if np.any(c.force_n)]
    assert thrust_ms == list(range(0, 100, 10)) + list(range(500, 600, 10))

    # Thrust through hemi b, then (auto) hemi a, the only one in stance at 500 ms:
    # torque = (p_hemi - p_com) x F with p_hemi - p_com = R(q) (s r_x, 0, 0), r_x = 1.4 m.
    for t_ms, sign in ((0, -1.0), (500, 1.0)):
        lever = rotation_matrix(Q_BODY) @ np.array([sign * TETHER_M / 2, 0.0, 0.0])
        np.testing.assert_allclose(commands[t_ms].force_n, FORCE_N)
        np.testing.assert_allclose(commands[t_ms].torque_nm, np.cross(lever, FORCE_N), atol=1e-12)
    assert commands[0].torque_nm[1] > 0.0  # hemi b pushing up spins the body about +y

    # Debounced: lift-off 150 ms after the last stance (200 ms, 700 ms), touchdown after
    # 50 ms of stance (350 ms, 850 ms); LANDED after 100 ms at rest on both hemis.
    assert sim.phases == ["LAUNCH", "IN_FLIGHT", "JUMP", "IN_FLIGHT", "LANDING", "LANDED"]

    # References: flight reference at the first tick, landing reference at touchdown.
    assert [stamp_from_msg(m.header.stamp) // MS for m in sim.w_refs] == [0, 850]
    np.testing.assert_allclose(twist_from_msg(sim.w_refs[0])[1], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(twist_from_msg(sim.w_refs[1])[1], [0.0, 0.0, 0.0])
    for pose in sim.q_refs:
        np.testing.assert_allclose(pose_from_msg(pose)[1], Q_BODY, atol=1e-12)

    # The NaN odom at 300 ms was rejected, its tick still answered, and it shows.
    last = diagnostics_from_msg(sim.diagnostics[-1])[0]
    assert last.name == "gait_phase_manager: gait phase"
    assert last.values["rejected_messages"] == 1.0
    assert last.values["ticks_with_rejected_input"] == 1.0
    assert last.values["jumps_done"] == 2.0
    assert last.values["phase"] == "LANDED"
    diag_stamps = [stamp_from_msg(m.header.stamp) // MS for m in sim.diagnostics]
    assert diag_stamps == list(range(0, 1010, 100))
    for message in sim.jump_commands:
        sample = wrench_from_msg(message)  # raises on NaN
        assert np.all(np.isfinite(sample.torque_nm))


def test_phase_and_references_are_latched_for_late_joiners(graph, ros_context) -> None:
    _manager, sim, executor = graph
    run_ticks(sim, executor, range(0, 210, 10))  # LAUNCH, then IN_FLIGHT at 200 ms
    late = rclpy.create_node("late_joiner", context=ros_context)
    phases: list[str] = []
    poses: list[PoseStamped] = []
    late.create_subscription(String, names.GAIT_PHASE, lambda m: phases.append(m.data), LATCHED_QOS)
    late.create_subscription(PoseStamped, names.ATTITUDE_REFERENCE_POSE, poses.append, LATCHED_QOS)
    executor.add_node(late)
    try:
        spin_until(executor, lambda: bool(phases) and bool(poses))
        assert phases == ["IN_FLIGHT"]  # the current phase only (depth 1)
        assert stamp_from_msg(poses[0].header.stamp) == 0
    finally:
        executor.remove_node(late)
        late.destroy_node()


@pytest.mark.parametrize(
    ("attitude_reference", "needs_inertia"),
    [("integrate_w_ref", False), ("initial", False), ("momentum_aligned", True)],
)
def test_a_tick_waits_for_all_its_inputs(
    ros_context, attitude_reference: str, needs_inertia: bool
) -> None:
    """Odom, both contacts and joints always; /splitter/inertia only when the mode needs it."""
    overrides = [*PLAN, Parameter("attitude_reference", value=attitude_reference)]
    with gait_graph(ros_context, overrides) as (_manager, sim, executor):
        joints = np.zeros(names.N_JOINTS)
        joints[names.JOINT_INDEX[names.TETHER_JOINT]] = TETHER_M
        sim.odom.publish(odom_to_msg(0, (0, 0, 0.45), Q_BODY, (0, 0, 0), (0, 0, 0)))
        sim.joints.publish(joint_state_to_msg(0, joints))
        sim.contacts[0].publish(wrench_to_msg(0, (0, 0, 20.0), (0, 0, 0), names.WORLD_FRAME))
        for _ in range(30):
            executor.spin_once(timeout_sec=0.005)
        assert sim.jump_commands == []  # hemi b's contact wrench is missing
        sim.contacts[1].publish(wrench_to_msg(0, (0, 0, 20.0), (0, 0, 0), names.WORLD_FRAME))
        if needs_inertia:
            for _ in range(30):
                executor.spin_once(timeout_sec=0.005)
            assert sim.jump_commands == []  # the inertia for t = 0 is missing
            sim.inertia.publish(vector3_to_msg(0, INERTIA_KG_M2, names.BASE_FRAME))
        spin_until(executor, lambda: len(sim.jump_commands) == 1)
        assert stamp_from_msg(sim.jump_commands[0].header.stamp) == 0


def test_momentum_aligned_pose_and_a_bad_inertia_message(ros_context) -> None:
    """The published pose is the core's momentum-aligned attitude of the first tick's state;
    a corrupt /splitter/inertia is rejected, its tick answered from the last good one."""
    overrides = [*PLAN, Parameter("attitude_reference", value="momentum_aligned")]
    with gait_graph(ros_context, overrides) as (_manager, sim, executor):
        rate = (0.5, -0.5, 0.5)  # [rad/s] body: I w is 135 deg from +y
        for t_ms in range(0, 110, 10):
            t_ns = t_ms * MS
            odom = odom_to_msg(t_ns, (0.0, 0.0, 0.45), Q_BODY, (0, 0, 0), rate)
            inertia = None
            if t_ms == 20:
                inertia = vector3_to_msg(t_ns, (0.48, -1.0, 141.36), names.BASE_FRAME)
            sim.publish_state(t_ns, odom, inertia)
            spin_until(
                executor,
                lambda t_ns=t_ns: any(
                    stamp_from_msg(m.header.stamp) == t_ns for m in sim.jump_commands
                ),
            )
        spin_until(executor, lambda: bool(sim.q_refs) and len(sim.diagnostics) >= 2)
        assert [stamp_from_msg(m.header.stamp) for m in sim.jump_commands] == [
            t * MS for t in range(0, 110, 10)
        ]
        assert sim.q_refs[0].header.frame_id == names.WORLD_FRAME
        _, q_ref, _ = pose_from_msg(sim.q_refs[0])
        expected = momentum_aligned_attitude(Q_BODY, rate, INERTIA_KG_M2, (0.0, 1.0, 0.0))
        np.testing.assert_allclose(q_ref, expected, atol=1e-15)
        h = rotation_matrix(Q_BODY) @ (np.array(INERTIA_KG_M2) * rate)
        np.testing.assert_allclose(rotation_matrix(q_ref)[:, 1], h / np.linalg.norm(h), atol=1e-12)
        last = diagnostics_from_msg(sim.diagnostics[-1])[0]
        assert stamp_from_msg(sim.diagnostics[-1].header.stamp) == 100 * MS
        assert last.values["rejected_messages"] == 1.0  # the 20 ms inertia ...
        assert last.values["ticks_with_rejected_input"] == 1.0  # ... its tick still answered


@pytest.mark.parametrize(
    ("override", "name"),
    [
        (Parameter("stance_force_threshold_n", value=-1.0), "stance_force_threshold_n"),
        (Parameter("jump_hemis", value=["b", "c"]), "jump_hemis"),
        (Parameter("jump_forces_n", value=[40.0, 0.0]), "jump_forces_n"),
        (Parameter("jump_times_s", value=[0.0, 0.05]), "jump_times_s"),
        (Parameter("attitude_reference", value="spin"), "attitude_reference"),
        (Parameter("diagnostics_period_s", value=0.015), "diagnostics_period_s"),
        (Parameter("jump_hemis", value=[1.0, 2.0]), "jump_hemis"),
    ],
)
def test_invalid_parameter_stops_start_up_naming_it(ros_context, override, name) -> None:
    overrides = [p for p in PLAN if p.name != override.name] + [override]
    with pytest.raises(InvalidParameterError, match=f"'{name}'"):
        GaitPhaseManagerNode(context=ros_context, parameter_overrides=overrides)


def test_main_exits_non_zero_on_an_invalid_parameter() -> None:
    assert main(["gait_phase_manager", "--ros-args", "-p", "landed_dwell_s:=-1.0"]) == 1
    assert not rclpy.ok()


@pytest.mark.parametrize("with_plan", [False, True])
def test_shipped_params_file_starts_the_node(tmp_path, with_plan: bool) -> None:
    """The shipped YAML (empty plan: no jump) and a launcher-style plan both load."""
    data = yaml.safe_load(CONFIG_FILE.read_text(encoding="utf-8"))
    params = data["gait_phase_manager"]["ros__parameters"]
    if with_plan:
        params.update(
            jump_times_s=[0.0, 5.0],
            jump_forces_n=[40.0, 0.0, 40.0, 40.0, 0.0, 40.0],
            jump_durations_s=[0.6, 0.6],
            jump_hemis=["b", "auto"],
            use_sim_time=True,
        )
    params_file = tmp_path / "params.yaml"
    params_file.write_text(yaml.safe_dump(data), encoding="utf-8")
    context = rclpy.Context()
    # The domain comes from ROS_DOMAIN_ID, set for the test run by the root conftest.py.
    rclpy.init(context=context, args=["--ros-args", "--params-file", str(params_file)])
    try:
        node = GaitPhaseManagerNode(context=context)
        try:
            # The library closed loop builds its machine from the same mapping.
            assert node.config == gait_config_from_parameters(params)
            jumps = node.config.jumps
            assert len(jumps) == (2 if with_plan else 0)
            if with_plan:
                assert [j.hemi for j in jumps] == ["b", "auto"]
                assert node.get_parameter("use_sim_time").value is True
        finally:
            node.destroy_node()
    finally:
        context.try_shutdown()
