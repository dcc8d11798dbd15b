"""The single source of topic names, frame ids and joint names (DESIGN.md section 4).

ROS-free: importing this module never imports rclpy, so cores, tests and tools
can use the names without a ROS installation.
"""

from __future__ import annotations

from typing import Final

from splitter_model import joints as _joints

# --- topics (DESIGN.md section 4; do not rename) -----------------------------
CLOCK: Final = "/clock"
IMU: Final = "/splitter/imu"
ODOM: Final = "/splitter/odom"
INERTIA: Final = "/splitter/inertia"
JOINT_STATES: Final = "/splitter/joint_states"
INERTIA_SETPOINT: Final = "/splitter/inertia_setpoint"
JOINT_COMMANDS: Final = "/splitter/joint_commands"
GAIT_PHASE: Final = "/splitter/gait_phase"
# True while the limbs are legs: on the ground, or the predicted touchdown within the lead.
STANCE_SHAPE: Final = "/splitter/gait/stance_shape"
ATTITUDE_REFERENCE: Final = "/splitter/attitude_reference"
JUMP_COMMAND: Final = "/splitter/jump_command"
MARKERS: Final = "/splitter/markers"
DIAGNOSTICS: Final = "/diagnostics"

# Topics the project adds (extensions of DESIGN.md section 4).
# Reference attitude: geometry_msgs/PoseStamped (orientation) beside ATTITUDE_REFERENCE,
# which carries the reference angular velocity as geometry_msgs/TwistStamped.
ATTITUDE_REFERENCE_POSE: Final = "/splitter/attitude_reference_pose"
# Ground contact wrench on each hemi (world frame), geometry_msgs/WrenchStamped.
CONTACT_WRENCH_A: Final = "/splitter/hemi_a/contact_wrench"
CONTACT_WRENCH_B: Final = "/splitter/hemi_b/contact_wrench"
CONTACT_WRENCHES: Final = (CONTACT_WRENCH_A, CONTACT_WRENCH_B)
# The scene's lumped masses (world frame, index order of splitter_sim.core.scene),
# geometry_msgs/PoseArray on the markers grid: with odom, inertia, imu and the contact
# wrenches, the whole scene as data (splitter_sim.messages).
SCENE_MASSES: Final = "/splitter/scene/masses"
# The gait's own sensors (splitter_model.sensors), per hemi: its downward rangefinder
# (sensor_msgs/Range, frame hemi_a / hemi_b, ray along base -z) and its legs' load cell
# (geometry_msgs/WrenchStamped, force in the base frame; the legs' push only).
RANGE_A: Final = "/splitter/hemi_a/range"
RANGE_B: Final = "/splitter/hemi_b/range"
RANGES: Final = (RANGE_A, RANGE_B)
LEG_FORCE_A: Final = "/splitter/hemi_a/leg_force"
LEG_FORCE_B: Final = "/splitter/hemi_b/leg_force"
LEG_FORCES: Final = (LEG_FORCE_A, LEG_FORCE_B)
# Ground truth (DESIGN.md section 3, "What controllers may read"): the simulator's exact
# state for bags and metrics; no controller subscribes to it. TRUTH_IMU: the exact body
# rate and attitude (IMU carries what the robot's gyro reads: with the scenario's bias
# and noise); TRUTH_INERTIA: the exact principal moments (base frame).
TRUTH_IMU: Final = "/splitter/truth/imu"
TRUTH_INERTIA: Final = "/splitter/truth/inertia"
TRUTH_TOPICS: Final = (TRUTH_IMU, TRUTH_INERTIA)
# Faults (splitter_model.faults): a joint or the reel made to fail (key: the joint's name,
# value: locked or limp), into the simulator at any time; the faults the simulator has
# (ground truth, on change); the faulty joints the allocator found from the joint states,
# with the radius bounds that remain (every control tick while there are any).
FAULT_INJECTION: Final = "/splitter/fault_injection"
TRUTH_JOINT_FAULTS: Final = "/splitter/truth/joint_faults"
JOINT_HEALTH: Final = "/splitter/joint_health"
# The flight estimator's answers (splitter_mpc.flight_estimator_node), each control tick:
# the rate and attitude (Imu, with the rate's covariance), the estimated model's
# principal moments, its masses (m_x, m_y, m_z [kg]), the gyro bias [rad/s] and each hemi
# body's own principal moments [kg m^2] (zero while the estimator takes them for points).
ESTIMATE_IMU: Final = "/splitter/estimate/imu"
ESTIMATE_INERTIA: Final = "/splitter/estimate/inertia"
ESTIMATE_MASSES: Final = "/splitter/estimate/masses"
ESTIMATE_GYRO_BIAS: Final = "/splitter/estimate/gyro_bias"
ESTIMATE_HEMI_INERTIA: Final = "/splitter/estimate/hemi_inertia"
ESTIMATE_TOPICS: Final = (
    ESTIMATE_IMU,
    ESTIMATE_INERTIA,
    ESTIMATE_MASSES,
    ESTIMATE_GYRO_BIAS,
    ESTIMATE_HEMI_INERTIA,
)

# Fully qualified ROS type names, as rosbag2 writes them.
TOPIC_TYPES: Final[dict[str, str]] = {
    CLOCK: "rosgraph_msgs/msg/Clock",
    IMU: "sensor_msgs/msg/Imu",
    ODOM: "nav_msgs/msg/Odometry",
    INERTIA: "geometry_msgs/msg/Vector3Stamped",
    JOINT_STATES: "sensor_msgs/msg/JointState",
    INERTIA_SETPOINT: "geometry_msgs/msg/Vector3Stamped",
    JOINT_COMMANDS: "sensor_msgs/msg/JointState",
    GAIT_PHASE: "std_msgs/msg/String",
    STANCE_SHAPE: "std_msgs/msg/Bool",
    ATTITUDE_REFERENCE: "geometry_msgs/msg/TwistStamped",
    ATTITUDE_REFERENCE_POSE: "geometry_msgs/msg/PoseStamped",
    CONTACT_WRENCH_A: "geometry_msgs/msg/WrenchStamped",
    CONTACT_WRENCH_B: "geometry_msgs/msg/WrenchStamped",
    JUMP_COMMAND: "geometry_msgs/msg/WrenchStamped",
    MARKERS: "visualization_msgs/msg/MarkerArray",
    SCENE_MASSES: "geometry_msgs/msg/PoseArray",
    RANGE_A: "sensor_msgs/msg/Range",
    RANGE_B: "sensor_msgs/msg/Range",
    LEG_FORCE_A: "geometry_msgs/msg/WrenchStamped",
    LEG_FORCE_B: "geometry_msgs/msg/WrenchStamped",
    TRUTH_IMU: "sensor_msgs/msg/Imu",
    TRUTH_INERTIA: "geometry_msgs/msg/Vector3Stamped",
    FAULT_INJECTION: "diagnostic_msgs/msg/KeyValue",
    TRUTH_JOINT_FAULTS: "diagnostic_msgs/msg/DiagnosticArray",
    JOINT_HEALTH: "diagnostic_msgs/msg/DiagnosticArray",
    ESTIMATE_IMU: "sensor_msgs/msg/Imu",
    ESTIMATE_INERTIA: "geometry_msgs/msg/Vector3Stamped",
    ESTIMATE_MASSES: "geometry_msgs/msg/Vector3Stamped",
    ESTIMATE_GYRO_BIAS: "geometry_msgs/msg/Vector3Stamped",
    ESTIMATE_HEMI_INERTIA: "geometry_msgs/msg/Vector3Stamped",
    DIAGNOSTICS: "diagnostic_msgs/msg/DiagnosticArray",
}

# --- frames --------------------------------------------------------------------
WORLD_FRAME: Final = "world"  # z up, ground plane z = 0
BASE_FRAME: Final = "base"  # system body frame: origin at the centre of mass, x along the tether
HEMI_FRAMES: Final = ("hemi_a", "hemi_b")

# --- gait phases (paper section III.A, plus LANDED) -----------------------------
GAIT_PHASES: Final = ("LAUNCH", "IN_FLIGHT", "JUMP", "LANDING", "LANDED")

# --- joints ----------------------------------------------------------------------
# The robot model's, defined once (splitter_model.joints): joint names and order,
# limbs, hemis (hemi "a" at +x, "b" at -x) and each joint's index by name.
HEMIS: Final = _joints.HEMIS
HEMI_SIGNS: Final = _joints.HEMI_SIGNS
LIMB_AXES: Final = _joints.LIMB_AXES
LIMB_NAMES: Final = _joints.LIMB_NAMES
LIMB_JOINTS: Final = _joints.LIMB_JOINTS
TETHER_JOINT: Final = _joints.TETHER_JOINT
JOINT_NAMES: Final = _joints.JOINT_NAMES
JOINT_INDEX: Final = _joints.JOINT_INDEX
N_JOINTS: Final = _joints.N_JOINTS  # 8 limbs x 3 joints + tether = 25
