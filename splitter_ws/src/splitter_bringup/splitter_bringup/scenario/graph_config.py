"""The node graph of a scenario: which nodes run, with which parameters.

ROS-free. The launcher writes these parameters to YAML files (one process per
node); the in-process graph tests pass the very same dictionaries as parameter
overrides, so both ways run the same graph.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from splitter_bag.core.node_parameters import parameter_file_text
from splitter_bringup.scenario.definition import Scenario
from splitter_ik.core.joint_health import JointHealthConfig
from splitter_model.faults import fault_parameters
from splitter_mpc.core.estimator import EstimatorConfig
from splitter_mpc.core.gait import jump_plan_parameters
from splitter_mpc.core.solvers import LOCKSTEP_MAX_TIME_S
from splitter_msgs_py import names
from splitter_msgs_py.core.parameter_fields import parameter_fields


@dataclass(frozen=True)
class NodeLaunch:
    """One node of the graph."""

    name: str  # ROS node name (also the process name in logs)
    entry: str  # "module:function" started by splitter_bringup.run.node_runner
    node_class: str  # "module:Class" for in-process graphs
    parameters: Mapping[str, Any] = field(default_factory=dict)
    remappings: Mapping[str, str] = field(default_factory=dict)  # topic -> the one read

    def remapping_args(self) -> list[str]:
        """``-r from:=to`` for each remapping (ROS arguments)."""
        return [arg for old, new in self.remappings.items() for arg in ("-r", f"{old}:={new}")]


# Topics the recorder takes by default: the whole contract of DESIGN.md section 4.
RECORDED_TOPICS = tuple(names.TOPIC_TYPES)


def _floats(values) -> list[float]:
    return [float(v) for v in values]


RECORDER_NODE = "recorder"
CONTROLLER_NODES = ("inertial_morphing_mpc", "ik_tether_allocator", "gait_phase_manager")
STARTUP_WAIT_S = 120.0  # [s] wall: the MPC may compile its solver on a first start
# [s] wall: lets the nodes' endpoints match each other (e.g. MPC -> recorder) once all
# are in the graph; the simulator only sees its own matches
STARTUP_SETTLE_S = 0.5
# [s] real time: a joint command's velocity is followed this long past its stamp while
# the next point is late (lockstep sends one every control period: the default 20 ms)
REAL_TIME_COMMAND_EXTRAPOLATION_S = 0.25
# [s] real time: the joint trajectory's corners, queued ahead, are rounded over one
# control period (the servos then see a reference with continuous velocity)
REAL_TIME_KNOT_BLEND_S = 0.01


ESTIMATOR_NODE = "flight_estimator"
# With robot errors the MPC and the allocator read the flight estimator's rate and inertia
ESTIMATE_REMAPPINGS = {names.IMU: names.ESTIMATE_IMU, names.INERTIA: names.ESTIMATE_INERTIA}


def robot_aware_mpc_parameters(scenario: Scenario) -> dict:
    """The MPC's parameters for a robot with errors: estimated masses, its servos' lag."""
    return {
        "estimated_masses": True,
        "actuator_lag_s": float(scenario.robot_errors.actuator_lag_s),
        "command_latency_s": float(scenario.robot_errors.command_latency_s),
    }


def flies_on_estimates(scenario: Scenario) -> bool:
    """Whether the scenario's robot has errors: then the controllers fly on the estimator."""
    return scenario.robot_errors.present


def simulator_parameters(
    scenario: Scenario, real_time: bool, rate_factor: float, recorder: str | None = None
) -> dict:
    """Simulator node parameters of a scenario.

    The simulator starts stepping once the controllers are in the graph and the
    recorder (if any) subscribes to every state topic, so a run is recorded whole.
    """
    return {
        "use_sim_time": False,
        "startup_wait_s": STARTUP_WAIT_S,
        "startup_wait_for_nodes": [
            *CONTROLLER_NODES,
            *([ESTIMATOR_NODE] if flies_on_estimates(scenario) else []),
        ],
        # the MPC creates its publisher once its solver is built (a first start compiles)
        "startup_wait_for_publishers": [names.INERTIA_SETPOINT],
        "startup_wait_for_subscribers": [recorder] if recorder else [],
        "startup_settle_s": STARTUP_SETTLE_S,
        "mode": "real_time" if real_time else "lockstep",
        "rate_factor": float(rate_factor),
        **(
            {
                "command_extrapolation_s": REAL_TIME_COMMAND_EXTRAPOLATION_S,
                "knot_blend_s": REAL_TIME_KNOT_BLEND_S,
            }
            if real_time
            else {}
        ),
        "duration_s": float(scenario.duration_s),
        "dt_s": float(scenario.sim_dt_s),
        "gravity": str(scenario.gravity_m_s2),
        "ground_contact": bool(scenario.ground_contact),
        "compliant_legs": bool(scenario.compliant_legs),
        "leg_cone_half_angle_deg": float(scenario.leg_cone_half_angle_deg),
        "leg_posture_stiffness_n_m": float(scenario.leg_posture_stiffness_n_m),
        "leg_ride_height_m": float(scenario.leg_ride_height_m),
        **ground_parameters(scenario),
        **{name: list(values) for name, values in fault_parameters(scenario.faults).items()},
        "friction_coefficient": float(scenario.friction_coefficient),
        "initial_position_m": _floats(scenario.initial_position_m),
        "initial_velocity_m_s": _floats(scenario.initial_velocity_m_s),
        "initial_orientation_euler_deg": _floats(scenario.initial_orientation_euler_deg),
        "initial_angular_velocity_rad_s": _floats(scenario.initial_angular_velocity_rad_s),
        "initial_radii_m": _floats(scenario.initial_radii_m),
        **robot_error_parameters(scenario),
    }


def ground_parameters(scenario: Scenario) -> dict:
    """The ground's parameters (simulator, gait manager): ``splitter_model.terrain``."""
    terrain = scenario.terrain
    return {
        "ground_slope_deg": float(terrain.slope_deg),
        "ground_slope_azimuth_deg": float(terrain.slope_azimuth_deg),
        "ground_steps_m": list(terrain.steps_flat()),
    }


def robot_error_parameters(scenario: Scenario) -> dict:
    """The simulator's parameters of the scenario's robot errors (``RobotErrors``' fields)."""
    e = scenario.robot_errors
    values: dict = {}
    for f in fields(e):
        value = getattr(e, f.name)
        values[f.name] = _floats(value) if isinstance(value, tuple) else value
    return values


def estimator_parameters(scenario: Scenario) -> dict:
    """The flight estimator's parameters of the scenario (``EstimatorConfig``'s fields)."""
    values: dict = {}
    for name, _default, _spec in parameter_fields(EstimatorConfig):
        value = getattr(scenario.estimator, name)
        values[name] = _floats(value) if isinstance(value, tuple) else value
    return values


def mpc_parameters(scenario: Scenario, real_time: bool = False) -> dict:
    """Inertial-morphing MPC node parameters of a scenario.

    In real time the node keeps its own wall-time deadline (a late plan is dropped) and
    a restarting solver worker counts against it; in lockstep the simulator waits for
    the MPC, so a slow solve is waited for up to :data:`LOCKSTEP_MAX_TIME_S` and a
    restart outside the deadline (the same solves miss whatever the load).
    """
    c = scenario.controller
    extra = (
        {"wait_for_solver_start": False, "plan_from_setpoints": True}
        if real_time
        else {"max_solve_time_s": LOCKSTEP_MAX_TIME_S, "wait_for_solver_start": True}
    )
    return {
        **extra,
        "use_sim_time": True,
        "enabled": bool(c.enabled),
        "q_w": _floats(c.q_w),
        "r": _floats(c.r),
        "q_t": _floats(c.q_t),
        "q_q": float(c.q_q),
        "q_tq": float(c.q_tq),
        "objective": c.objective,
        "horizon": int(c.horizon),
        "dt_s": float(c.dt_s),
        "integrator": c.integrator,
        "weights_step_s": 0.0 if c.weights_step_s is None else float(c.weights_step_s),
        "recovery_spin_rad_s": float(c.recovery_spin_rad_s),
        "recovery_momentum_ratio_max": (
            1.0e9 if c.recovery_momentum_ratio_max is None else float(c.recovery_momentum_ratio_max)
        ),
        "fault_effort_scale": float(c.fault_effort_scale),
        "solver": c.solver,
    }


def gait_parameters(scenario: Scenario) -> dict:
    """Gait phase manager parameters: the jump plan and the attitude reference."""
    c = scenario.controller
    return {
        "use_sim_time": True,
        "w_ref_rad_s": _floats(c.w_ref_rad_s),
        "attitude_reference": c.attitude_reference,
        "landing_spin_up_rad_s": float(c.landing_spin_up_rad_s),
        "landing_spin_up_settle_s": float(c.landing_spin_up_settle_s),
        "gravity_m_s2": float(scenario.gravity_m_s2),  # the planet the robot is on
        **jump_plan_parameters(scenario.jumps),
    }


def allocator_parameters(scenario: Scenario, real_time: bool = False) -> dict:
    """IK / tether allocator parameters.

    In real time its commands are stamped ahead of their inputs by the latency it
    measures (the simulator follows them at their stamps); in lockstep each tick is
    answered with its own stamp.
    """
    health = joint_health_config(scenario, real_time)
    return {
        "use_sim_time": True,
        "initial_radii_m": _floats(scenario.initial_radii_m),
        "command_lead": bool(real_time),
        "fault_handling": bool(scenario.fault_handling),
        **{name: getattr(health, name) for name in HEALTH_FROM_SCENARIO},
    }


# the fault detector's parameters a scenario sets (the rest keep the node's defaults)
HEALTH_FROM_SCENARIO = ("servo_lag_s", "servo_latency_s", "residual_margin_rad")
RESIDUAL_MARGIN_EXACT_RAD = 0.01  # [rad] servos without lag or latency, in lockstep
RESIDUAL_MARGIN_LAGGED_RAD = 0.03  # [rad] servos with lag or latency
RESIDUAL_MARGIN_REAL_TIME_RAD = 1.0  # [rad] real time: off


def joint_health_config(scenario: Scenario, real_time: bool = False) -> JointHealthConfig:
    """The fault detector of a scenario's allocator: told the servos' lag and latency
    (the robot errors' datasheet, as the controller is), with the residual margin their
    prediction allows (``JointHealthConfig.residual_margin_rad``)."""
    errors = scenario.robot_errors
    exact = errors.actuator_lag_s == 0.0 and errors.command_latency_s == 0.0
    if real_time:
        margin = RESIDUAL_MARGIN_REAL_TIME_RAD
    else:
        margin = RESIDUAL_MARGIN_EXACT_RAD if exact else RESIDUAL_MARGIN_LAGGED_RAD
    return JointHealthConfig(
        servo_lag_s=float(errors.actuator_lag_s),
        servo_latency_s=float(errors.command_latency_s),
        residual_margin_rad=margin,
    )


def recorder_parameters(bag_dir: Path, topics: tuple[str, ...] = RECORDED_TOPICS) -> dict:
    """Recorder parameters: the bag directory and the topics."""
    return {"use_sim_time": True, "output": str(bag_dir), "topics": list(topics)}


def graph_nodes(
    scenario: Scenario,
    real_time: bool = False,
    rate_factor: float = 1.0,
    bag_dir: Path | None = None,
) -> list[NodeLaunch]:
    """The nodes of a scenario run, in start order (the recorder first, the simulator last)."""
    nodes = []
    if bag_dir is not None:
        nodes.append(
            NodeLaunch(
                RECORDER_NODE,
                "splitter_bag.recorder_node:main",
                "splitter_bag.recorder_node:RecorderNode",
                recorder_parameters(bag_dir),
            )
        )
    estimated = flies_on_estimates(scenario)
    if estimated:
        nodes.append(
            NodeLaunch(
                ESTIMATOR_NODE,
                "splitter_mpc.flight_estimator_node:main",
                "splitter_mpc.flight_estimator_node:FlightEstimatorNode",
                {"use_sim_time": True, **estimator_parameters(scenario)},
            )
        )
    remaps = ESTIMATE_REMAPPINGS if estimated else {}
    nodes += [
        NodeLaunch(
            "inertial_morphing_mpc",
            "splitter_mpc.inertial_morphing_mpc_node:main",
            "splitter_mpc.inertial_morphing_mpc_node:InertialMorphingMpcNode",
            {
                **mpc_parameters(scenario, real_time),
                **(robot_aware_mpc_parameters(scenario) if estimated else {}),
            },
            remaps,
        ),
        NodeLaunch(
            "ik_tether_allocator",
            "splitter_ik.ik_tether_allocator_node:main",
            "splitter_ik.ik_tether_allocator_node:IkTetherAllocatorNode",
            allocator_parameters(scenario, real_time),
            remaps,
        ),
        NodeLaunch(
            "gait_phase_manager",
            "splitter_mpc.gait_phase_manager_node:main",
            "splitter_mpc.gait_phase_manager_node:GaitPhaseManagerNode",
            gait_parameters(scenario),
            {names.INERTIA: names.ESTIMATE_INERTIA} if estimated else {},
        ),
        NodeLaunch(
            "simulator",
            "splitter_sim.simulator_node:main",
            "splitter_sim.simulator_node:SimulatorNode",
            simulator_parameters(
                scenario, real_time, rate_factor, "recorder" if bag_dir is not None else None
            ),
        ),
    ]
    return nodes


def with_parameter_attachments(nodes: list[NodeLaunch]) -> list[NodeLaunch]:
    """``nodes`` with the recorder told to store every other node's parameter file.

    The recorder writes them into the bag as MCAP attachments ``params/<node>.yaml``
    (:mod:`splitter_bag.core.node_parameters`), the same text as the run folder's
    ``params/<node>.yaml``: a bag copied alone still says how its nodes ran. Call it
    on the final list (after any change to a node's parameters).
    """
    files = [parameter_file_text(n.name, n.parameters) for n in nodes if n.name != RECORDER_NODE]
    return [
        replace(n, parameters={**n.parameters, "node_parameters": files})
        if n.name == RECORDER_NODE
        else n
        for n in nodes
    ]


def write_parameter_file(node: NodeLaunch, folder: Path) -> Path:
    """Write ``node``'s parameters as a ROS 2 parameter file; its path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{node.name}.yaml"
    path.write_text(parameter_file_text(node.name, node.parameters), encoding="utf-8")
    return path
