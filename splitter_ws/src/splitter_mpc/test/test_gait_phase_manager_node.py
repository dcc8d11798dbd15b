"""gait_phase_manager node in-process: lockstep answers, phases, references, bad input.

A scripted simulator publishes what the robot measures (IMU, rangefinders, leg load
cells, joint states, inertia) for a consistent two-jump run: its accelerometer and
rangefinders are those of one trajectory, so the gait's estimate of the body's
velocity and height (integrated from rest, corrected by the ranges, zeroed at rest)
is the scripted one.
"""

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
from rclpy.parameter import Parameter
from sensor_msgs.msg import Imu, JointState, Range
from std_msgs.msg import String

from splitter_model.sensors import (
    RANGE_FIELD_OF_VIEW_RAD,
    RANGE_MAX_M,
    RANGE_MIN_M,
    downward_range_m,
)
from splitter_mpc.core.gait import (
    gait_config_from_parameters,
    momentum_aligned_attitude,
    rotation_matrix,
)
from splitter_mpc.gait_phase_manager_node import GaitPhaseManagerNode, main
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    diagnostics_from_msg,
    imu_to_msg,
    joint_state_to_msg,
    pose_from_msg,
    range_to_msg,
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
TICK_MS = 10  # control period [ms]
G_M_S2 = 1.62  # [m/s^2] the moon's gravity (world -z), known to the gait
TETHER_M = 2.8  # [m] distance between the hemi bodies: r_x = 1.4 m
PITCH_RAD = math.radians(10.0)  # constant attitude of the synthetic body
Q_BODY = np.array([math.cos(PITCH_RAD / 2), 0.0, math.sin(PITCH_RAD / 2), 0.0])
ROT_BODY = rotation_matrix(Q_BODY)  # world <- base
FORCE_N = (40.0, 0.0, 40.0)
INERTIA_KG_M2 = (0.48, 141.36, 141.36)  # [kg m^2] principal moments at the paper's radii
CONFIG_FILE = Path(__file__).resolve().parents[1] / "config" / "gait_phase_manager.yaml"
INPUT_TYPES = {
    names.IMU: Imu,
    names.RANGE_A: Range,
    names.RANGE_B: Range,
    names.LEG_FORCE_A: WrenchStamped,
    names.LEG_FORCE_B: WrenchStamped,
    names.JOINT_STATES: JointState,
    names.INERTIA: Vector3Stamped,
}

PLAN = [
    Parameter("jump_times_s", value=[0.0, 0.5]),
    Parameter("jump_forces_n", value=[*FORCE_N, *FORCE_N]),
    Parameter("jump_durations_s", value=[0.1, 0.1]),
    Parameter("jump_hemis", value=["b", "auto"]),
    Parameter("landed_dwell_s", value=0.1),
    # the synthetic body stands pitched 10 deg: no downhill scaling of the plan's pushes
    Parameter("jump_level_slope_deg", value=90.0),
    Parameter("w_ref_rad_s", value=[0.0, 1.0, 0.0]),
    Parameter("gravity_m_s2", value=G_M_S2),
]

# The scripted run, per 10 ms tick: the legs' push on hemi a, b [N] and the centre of
# mass's acceleration, world [m/s^2]. The velocity and height integrate it as the gait's
# estimator does (trapezoid over each tick), from rest at 0.45 m.
THRUST_ACCEL = (5.4, 0.0, 6.48)  # [m/s^2] legs pushing: 50 ms of it, vx 0.27, vz 0.3159 m/s
FRICTION_ACCEL = (-3.0, 0.0, 0.0)  # [m/s^2] sliding after the last touchdown


def scripted_push_and_accel(t_ms: int, velocity: np.ndarray) -> tuple[tuple, np.ndarray]:
    """(leg push on hemi a, b [N]; world acceleration [m/s^2]) at tick ``t_ms``.

    Stance on both hemis until 50 ms (hemi b's legs push the first jump), flight; hemi
    a touches down at 300 ms (the impact stops the body within the tick) and stays,
    its legs push the second jump from 500 ms, flight from 550 ms: the centre of mass
    rises until 745 ms, falls, and both hemis touch down at 800 ms, sliding (friction)
    until 890 ms, at rest after.
    """
    dt = TICK_MS * 1e-3
    free_fall = np.array([0.0, 0.0, -G_M_S2])
    if t_ms < 50:
        return (20.0, 60.0), np.array(THRUST_ACCEL)
    if t_ms < 300:
        return (0.0, 0.0), free_fall
    if t_ms == 300:  # the impact: the previous tick in free fall, the next at rest
        return (20.0, 0.0), np.array([-velocity[0] / dt, 0.0, G_M_S2 / 2 - velocity[2] / dt])
    if t_ms < 500:
        return (20.0, 0.0), np.zeros(3)
    if t_ms < 550:
        return (60.0, 0.0), np.array(THRUST_ACCEL)
    if t_ms < 800:
        return (0.0, 0.0), free_fall
    if t_ms < 890:  # the first tick stops the fall (as at 300 ms), friction the slide
        accel = np.array(FRICTION_ACCEL)
        if t_ms == 800:
            accel[2] = G_M_S2 / 2 - velocity[2] / dt
        return (15.0, 15.0), accel
    return (15.0, 15.0), np.zeros(3)


def scripted_run(end_ms: int = 1000) -> dict[int, tuple[tuple, np.ndarray, np.ndarray, float]]:
    """{tick [ms]: (leg push [N], world acceleration, velocity [m/s], height [m])}."""
    dt = TICK_MS * 1e-3
    velocity, height, previous = np.zeros(3), 0.45, None
    run = {}
    for t_ms in range(0, end_ms + TICK_MS, TICK_MS):
        push, accel = scripted_push_and_accel(t_ms, velocity)
        if previous is not None:
            mean = 0.5 * (accel + previous)
            height += dt * velocity[2] + 0.5 * dt * dt * mean[2]
            velocity = velocity + dt * mean
        previous = accel
        run[t_ms] = (push, accel, velocity, height)
    return run


RUN = scripted_run()


def hemi_heights_m(height_m: float) -> tuple[float, float]:
    """Hemi a (base +x), b (base -x) above the ground with the centre of mass at ``height_m``."""
    dz = TETHER_M / 2 * ROT_BODY[2, 0]
    return height_m + dz, height_m - dz


class FakeSimulator:
    """Publishes the gait manager's inputs stamped t and records what it answers."""

    def __init__(self, context) -> None:
        self.node = rclpy.create_node("fake_simulator", context=context)
        self.publishers = {
            topic: self.node.create_publisher(msg_type, topic, qos_for(topic))
            for topic, msg_type in INPUT_TYPES.items()
        }
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

    @staticmethod
    def messages(t_ns: int, rate=(0.0, 0.0, 0.0)) -> dict[str, object]:
        """The inputs stamped ``t_ns``: the scripted run's readings at its tick (an off-grid
        stamp repeats the tick before), the gyro reading ``rate``, the IMU last."""
        push, accel, _velocity, height = RUN[t_ns // MS // TICK_MS * TICK_MS]
        joints = np.zeros(names.N_JOINTS)
        joints[names.JOINT_INDEX[names.TETHER_JOINT]] = TETHER_M
        messages: dict[str, object] = {
            names.INERTIA: vector3_to_msg(t_ns, INERTIA_KG_M2, names.BASE_FRAME),
            names.JOINT_STATES: joint_state_to_msg(t_ns, joints),
        }
        for topic, frame, hemi_height in zip(
            names.RANGES, names.HEMI_FRAMES, hemi_heights_m(height), strict=True
        ):
            messages[topic] = range_to_msg(
                t_ns,
                downward_range_m(hemi_height, ROT_BODY),
                frame,
                min_range_m=RANGE_MIN_M,
                max_range_m=RANGE_MAX_M,
                field_of_view_rad=RANGE_FIELD_OF_VIEW_RAD,
            )
        for topic, legs_n in zip(names.LEG_FORCES, push, strict=True):
            force_base = ROT_BODY.T @ np.array([0.0, 0.0, legs_n])
            messages[topic] = wrench_to_msg(t_ns, force_base, (0.0, 0.0, 0.0), names.BASE_FRAME)
        specific_force_base = ROT_BODY.T @ (accel + np.array([0.0, 0.0, G_M_S2]))
        messages[names.IMU] = imu_to_msg(t_ns, Q_BODY, rate, specific_force_base)
        return messages

    def publish(self, messages: dict[str, object]) -> None:
        for topic, msg in messages.items():
            self.publishers[topic].publish(msg)

    def publish_state(self, t_ns: int, **replace: object) -> None:
        """The tick's inputs, with ``replace`` (topic: message) instead of the scripted ones."""
        self.publish({**self.messages(t_ns), **replace})


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


def bad_imu(t_ns: int) -> Imu:
    """The tick's IMU with a NaN accelerometer reading."""
    msg = FakeSimulator.messages(t_ns)[names.IMU]
    msg.linear_acceleration.z = math.nan
    return msg


def run_ticks(sim: FakeSimulator, executor, ticks_ms, bad_imu_at_ms: int | None = None) -> None:
    """Lockstep: publish a tick's inputs and wait for its jump command, like the simulator."""
    for t_ms in ticks_ms:
        t_ns = t_ms * MS
        if t_ms == bad_imu_at_ms:
            sim.publish_state(t_ns, **{names.IMU: bad_imu(t_ns)})
        else:
            sim.publish_state(t_ns)
        if t_ms % TICK_MS == 0:
            spin_until(
                executor,
                lambda t_ns=t_ns: any(
                    stamp_from_msg(m.header.stamp) == t_ns for m in sim.jump_commands
                ),
            )
        else:
            for _ in range(5):
                executor.spin_once(timeout_sec=0.001)


def test_the_scripted_run_is_the_one_described() -> None:
    """What the node test below relies on: the script's velocities (what the gait must
    estimate from the accelerometer) at the ticks that decide the phases."""
    velocity = {t_ms: v for t_ms, (_, _, v, _) in RUN.items()}
    assert velocity[200][2] > 0.0  # rising at the first lift-off (a jump left anyway)
    np.testing.assert_allclose(velocity[310], 0.0, atol=1e-12)  # stopped by the impact
    np.testing.assert_allclose(velocity[550], [0.27, 0.0, 0.3159], atol=1e-12)
    assert velocity[700][2] > 0.05  # rising at the lift-off after the last jump: IN_FLIGHT
    assert velocity[740][2] > 0.0 >= velocity[750][2]  # descending from 750 ms: LANDING
    assert np.linalg.norm(velocity[860]) > 0.06  # sliding ...
    assert 0.0 < np.linalg.norm(velocity[870]) < 0.049  # ... slow enough from 870 ms
    for t_ms in range(890, 1010, 10):
        np.testing.assert_allclose(velocity[t_ms], 0.0, atol=1e-12)
    assert min(min(hemi_heights_m(h)) for *_, h in RUN.values()) > RANGE_MIN_M


def test_node_answers_every_tick_and_sequences_the_phases(graph) -> None:
    _manager, sim, executor = graph
    run_ticks(sim, executor, range(0, 1005, 5), bad_imu_at_ms=150)
    spin_until(executor, lambda: len(sim.diagnostics) >= 11 and sim.phases[-1:] == ["LANDED"])

    stamps = [stamp_from_msg(m.header.stamp) // MS for m in sim.jump_commands]
    assert stamps == list(range(0, 1010, 10))  # one command per 10 ms tick, none off-grid
    commands = {stamp_from_msg(m.header.stamp) // MS: wrench_from_msg(m) for m in sim.jump_commands}
    assert all(c.frame_id == names.WORLD_FRAME for c in commands.values())
    thrust_ms = [t for t, c in commands.items() if np.any(c.force_n)]
    assert thrust_ms == list(range(0, 100, 10)) + list(range(500, 600, 10))

    # Thrust through hemi b, then (auto) hemi a, the only one whose legs push at 500 ms:
    # torque = (p_hemi - p_com) x F with p_hemi - p_com = R(q) (s r_x, 0, 0), r_x = 1.4 m.
    for t_ms, sign in ((0, -1.0), (500, 1.0)):
        lever = ROT_BODY @ np.array([sign * TETHER_M / 2, 0.0, 0.0])
        np.testing.assert_allclose(commands[t_ms].force_n, FORCE_N)
        np.testing.assert_allclose(commands[t_ms].torque_nm, np.cross(lever, FORCE_N), atol=1e-12)
    assert commands[0].torque_nm[1] > 0.0  # hemi b pushing up spins the body about +y

    # Stance from the leg load cells, debounced: lift-off 150 ms after the last stance
    # (200 ms, 700 ms: rising, so IN_FLIGHT), touchdown on hemi a after 50 ms of stance
    # (350 ms: JUMP). After the last jump, LANDING once the estimated vertical velocity
    # is <= 0 (750 ms), before the touchdown (800 ms); LANDED after 100 ms at rest on both
    # hemis, counted from the first tick slower than 0.05 m/s (870 ms), not from the
    # touchdown (850 ms): the accelerometer reads the slide.
    assert sim.phases == ["LAUNCH", "IN_FLIGHT", "JUMP", "IN_FLIGHT", "LANDING", "LANDED"]

    # References: flight reference at the first tick, landing reference on LANDING.
    assert [stamp_from_msg(m.header.stamp) // MS for m in sim.w_refs] == [0, 750]
    np.testing.assert_allclose(twist_from_msg(sim.w_refs[0])[1], [0.0, 1.0, 0.0])
    np.testing.assert_allclose(twist_from_msg(sim.w_refs[1])[1], [0.0, 0.0, 0.0])
    for pose in sim.q_refs:
        np.testing.assert_allclose(pose_from_msg(pose)[1], Q_BODY, atol=1e-12)

    statuses = {
        stamp_from_msg(m.header.stamp) // MS: diagnostics_from_msg(m)[0] for m in sim.diagnostics
    }
    assert list(statuses) == list(range(0, 1010, 100))
    landing = statuses[800].values
    assert landing["phase"] == "LANDING"
    assert landing["last_change_s"] == pytest.approx(0.75)
    assert landing["last_change_reason"] == "descending after the last jump: landing"
    # The NaN IMU at 150 ms was rejected, its tick still answered, and it shows.
    last = statuses[1000]
    assert last.name == "gait_phase_manager: gait phase"
    assert last.values["rejected_messages"] == 1.0
    assert last.values["ticks_with_rejected_input"] == 1.0
    assert last.values["jumps_done"] == 2.0
    assert last.values["phase"] == "LANDED"
    assert last.values["last_change_s"] == pytest.approx(0.97)
    assert last.values["last_change_reason"] == "at rest on both hemis"
    # The height comes from the rangefinders (the estimate starts at 0 m, unknown).
    expected_a, expected_b = hemi_heights_m(RUN[1000][3])
    assert last.values["hemi_a_height_m"] == pytest.approx(expected_a, abs=1e-4)
    assert last.values["hemi_b_height_m"] == pytest.approx(expected_b, abs=1e-4)
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
    """IMU, both rangefinders, both leg load cells and joints always; /splitter/inertia
    only when the mode needs it."""
    overrides = [*PLAN, Parameter("attitude_reference", value=attitude_reference)]
    with gait_graph(ros_context, overrides) as (_manager, sim, executor):
        messages = sim.messages(0)
        late = [names.RANGE_B, names.LEG_FORCE_B] + ([names.INERTIA] if needs_inertia else [])
        sim.publish({t: m for t, m in messages.items() if t not in late and t != names.INERTIA})
        for topic in late:
            for _ in range(30):
                executor.spin_once(timeout_sec=0.005)
            assert sim.jump_commands == [], f"answered without {topic}"
            sim.publish({topic: messages[topic]})
        spin_until(executor, lambda: len(sim.jump_commands) == 1)
        assert stamp_from_msg(sim.jump_commands[0].header.stamp) == 0


def test_momentum_aligned_pose_and_a_bad_inertia_message(ros_context) -> None:
    """The published pose is the core's momentum-aligned attitude of the first tick's
    IMU (attitude, gyro); a corrupt /splitter/inertia is rejected, its tick answered from
    the last good one."""
    overrides = [*PLAN, Parameter("attitude_reference", value="momentum_aligned")]
    with gait_graph(ros_context, overrides) as (_manager, sim, executor):
        rate = (0.5, -0.5, 0.5)  # [rad/s] body: I w is 135 deg from +y
        for t_ms in range(0, 110, 10):
            t_ns = t_ms * MS
            messages = sim.messages(t_ns, rate)
            if t_ms == 20:
                messages[names.INERTIA] = vector3_to_msg(
                    t_ns, (0.48, -1.0, 141.36), names.BASE_FRAME
                )
            sim.publish(messages)
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
        h = ROT_BODY @ (np.array(INERTIA_KG_M2) * rate)
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
