"""The library closed loop: a scenario run without ROS, in the graph's lockstep order.

The per-tick cores the nodes drive, driven here in the order of the lockstep
protocol (docs/ARCHITECTURE.md), so that this loop and the node graph agree by
construction, not by care: each node converts messages to and from the same
object's calls. For each simulator step at time ``t`` (5 ms):

1. the simulator's state at ``t`` (``SimulatorTick.state``, and ``SimulatorTick.readings``:
   what the robot's sensors read, as the simulator node publishes them);
2. on a control tick (``t % 10 ms == 0``):
   a. gait phase manager: ``GaitTick.on_sensors`` with the IMU, the rangefinders, the leg
      load cells, the tether length and the principal inertia; its phase, attitude
      reference and answer go to ``MpcTick`` as the latched topics and the jump
      command would; its jump wrench to ``SimulatorTick.command_jump``;
   b. MPC: ``MpcTick.on_state(t, w, q, I)`` -> setpoint stamped t;
   c. allocator: ``AllocatorTick.lockstep_tick(t, I, w, setpoint, f)`` -> joint
      commands stamped t, to ``SimulatorTick.command_joints``;
3. ``SimulatorTick.step`` to ``t + 5 ms`` (between ticks on the last commands).

Every step's state is recorded into a :class:`RunSeries`. ROS-free.

Messages carry float64 exactly, but every quaternion is normalised once when a
message is made and once when it is read (``splitter_msgs_py.conversions``):
the loop applies the same normalisations (:func:`received_quaternion`). Then this
loop and the process graph give the same spin_stabilization flight to the last bit
(measured). It matters: the closed loop amplifies 1e-16 input
differences to ~0.01 rad/s within 8 s (as does solving to 1e-8 instead of 1e-10).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.scenario.definition import Scenario
from splitter_bringup.scenario.graph_config import (
    flies_on_estimates,
    gait_parameters,
    joint_health_config,
)
from splitter_bringup.scenario.simulation import simulator_tick
from splitter_ik.core.allocator import Allocation
from splitter_ik.core.allocator_tick import AllocatorTick, AllocatorTickSettings
from splitter_model.actuators import TETHER_INDEX
from splitter_model.model import RobotModel
from splitter_mpc.core.controller import ControllerConfig, MorphingController
from splitter_mpc.core.estimator import EstimatorConfig, FlightEstimate
from splitter_mpc.core.estimator_tick import EstimatorTick, GyroSample, JointReading
from splitter_mpc.core.gait_sensing import ImuReading
from splitter_mpc.core.gait_tick import GaitTick, gait_settings_from_parameters
from splitter_mpc.core.mpc import InertialMorphingMpc, MpcSettings, settings_for_weights
from splitter_mpc.core.mpc_tick import MpcTick, MpcTickSettings
from splitter_mpc.core.ocp import MpcWeights
from splitter_mpc.core.solvers import LOCKSTEP_MAX_TIME_S, SolverOptions
from splitter_sim.core.actuators import COMMAND_EXTRAPOLATION_S
from splitter_sim.core.simulator import Simulator

_LOG = logging.getLogger(__name__)
NS_PER_S = 1_000_000_000
CONTROL_PERIOD_NS = 10_000_000  # [ns] the control tick (docs/ARCHITECTURE.md)

ProgressCallback = Callable[[float], None]  # called with the fraction done, in [0, 1]


def received_quaternion(q_wxyz, hops: int = 2) -> np.ndarray:
    """``q`` as a node receives it: normalised as ``conversions.unit_quaternion`` does, per hop."""
    q = np.asarray(q_wxyz, dtype=float)
    for _ in range(2 * hops):
        q = q / float(np.linalg.norm(q))
    return q


def simulator_for(scenario: Scenario, model: RobotModel | None = None) -> Simulator:
    """The simulator set up as ``scenario`` describes (initial state, step, gravity, ground,
    the robot's masses): the one :func:`~splitter_bringup.scenario.simulation.simulator_tick`
    drives."""
    return simulator_tick(scenario, model, CONTROL_PERIOD_NS / NS_PER_S).sim


def controller_config(
    scenario: Scenario, mpc: MpcSettings | None = None, *, knows_robot: bool | None = None
) -> ControllerConfig:
    """The MPC configuration of a scenario: the node's parameters, as a core object.

    The scenario fixes the formulation (objective, horizon, prediction step,
    integrator, the step the weights are given for);
    ``mpc`` brings the solver, its options and the hardware margins (None: the
    scenario's ``controller.solver`` with the lockstep deadline). With
    ``knows_robot`` (None: when the controllers fly on the estimator, as the graph's
    do) the MPC expects the robot's actuator lag.
    """
    c = scenario.controller
    weights = MpcWeights(q_w=c.q_w, r=c.r, q_t=c.q_t, q_q=c.q_q, q_tq=c.q_tq, objective=c.objective)
    if mpc is None:
        mpc = MpcSettings(solver=c.solver, options=SolverOptions(max_time_s=LOCKSTEP_MAX_TIME_S))
    formulation = replace(
        mpc,
        horizon=c.horizon,
        dt_s=c.dt_s,
        integrator=c.integrator,
        weights_step_s=c.weights_step_s,
    )
    mpc = settings_for_weights(formulation, weights)
    if knows_robot is None:
        knows_robot = flies_on_estimates(scenario)
    return ControllerConfig(
        actuator_lag_s=scenario.robot_errors.actuator_lag_s if knows_robot else 0.0,
        command_latency_s=scenario.robot_errors.command_latency_s if knows_robot else 0.0,
        enabled=c.enabled,
        weights=weights,
        mpc=mpc,
        recovery_spin_rad_s=c.recovery_spin_rad_s,
        recovery_momentum_ratio_max=(
            math.inf if c.recovery_momentum_ratio_max is None else c.recovery_momentum_ratio_max
        ),
        fault_effort_scale=c.fault_effort_scale,
    )


def library_controller(model: RobotModel, config: ControllerConfig) -> MorphingController:
    """The controller a library run flies with ``config``.

    A disabled one (an open-loop variant: nothing can enable it during a library
    run) never solves, so its MPC builds its back-end (the solver worker, ~1 s) only
    at a first solve, which does not come. Close it (or use it in ``with``).
    """
    mpc = InertialMorphingMpc(model, config.mpc, lazy_backend=not config.enabled)
    return MorphingController(model, config, mpc)


def run_closed_loop(
    scenario: Scenario,
    progress: ProgressCallback | None = None,
    *,
    model: RobotModel | None = None,
    controller: MorphingController | None = None,
    mpc: MpcSettings | None = None,
    fail_solves_at_s: tuple[float, ...] = (),
    duration_s: float | None = None,
    estimation: EstimatorConfig | None = None,
    estimator: bool | None = None,
) -> RunSeries:
    """Run ``scenario`` (its chosen variant) to its end; every simulator step recorded.

    ``controller`` replaces the scenario's MPC (for benchmarks); ``mpc`` sets the
    solver options of the default one. ``fail_solves_at_s`` injects a solver
    failure at the re-plans at those times (tests of the failure handling).
    ``duration_s`` shortens the run. The simulator flies the scenario's
    ``robot_errors`` (masses, gyro, actuator lag); the controllers then fly on the
    flight estimator (``estimation`` its parameters, default the scenario's) as the graph's do
    (:func:`~splitter_bringup.scenario.graph_config.flies_on_estimates`), unless
    ``estimator`` says otherwise (False: they read the gyro and the simulator's inertia
    as they are, and do not lead their commands through the lag). The allocator detects
    faulty joints and re-plans without them unless the scenario's ``fault_handling`` is
    false. The series records the true state, the simulator's faults (``joint_fault``,
    codes of ``splitter_model.faults``), the detections (``joint_detected``: 1 from the
    tick a joint is found faulty) and where the last joint command asks the joints to be
    (``joint_command``, :func:`commanded_position`).
    """
    model = model or RobotModel()
    estimated = flies_on_estimates(scenario) if estimator is None else bool(estimator)
    if controller is None:
        config = controller_config(scenario, mpc, knows_robot=estimated)
        with library_controller(model, config) as own:
            return run_closed_loop(
                scenario,
                progress,
                model=model,
                controller=own,
                fail_solves_at_s=fail_solves_at_s,
                duration_s=duration_s,
                estimation=estimation,
                estimator=estimator,
            )
    sim = simulator_tick(scenario, model, CONTROL_PERIOD_NS / NS_PER_S)
    gait = GaitTick(*gait_settings_from_parameters(gait_parameters(scenario)))
    mpc_tick = MpcTick(controller, MpcTickSettings(estimated_masses=estimated))
    # starts, as its node, from the first measured inertia
    allocator = AllocatorTick(
        model,
        settings=AllocatorTickSettings(fault_handling=scenario.fault_handling),
        health=joint_health_config(scenario),
    )
    estimation = scenario.estimator if estimation is None else estimation
    flight = EstimatorTick(model, estimation, CONTROL_PERIOD_NS) if estimated else None
    fail_ns = {round(t * NS_PER_S) for t in fail_solves_at_s}
    duration = scenario.duration_s if duration_s is None else min(duration_s, scenario.duration_s)
    dt_ns = sim.sim.config.dt_ns
    n_steps = round(duration * NS_PER_S / dt_ns)
    if CONTROL_PERIOD_NS % dt_ns != 0:
        raise ValueError(f"sim step {dt_ns} ns does not divide the control tick")

    rec: dict[str, list] = {k: [] for k in _RECORDED}
    estimates: list[FlightEstimate] = []
    phases: list[str] = []
    setpoint = np.asarray(sim.state().principal_inertia_kg_m2, dtype=float)
    phase_name = ""
    counts = {"failures": 0, "deadline_misses": 0}  # cumulative, as on /diagnostics
    started = time.monotonic()
    report_every = max(1, n_steps // 20)
    for step in range(n_steps + 1):
        state = sim.state()
        t = state.t_ns
        readings = sim.readings(state)  # what the robot's sensors read (once per step)
        gyro = readings.gyro_rad_s
        solve = {"time_ms": np.nan, "iterations": np.nan, "ok": np.nan, "cost": np.nan}
        allocator.joint_states(t, state.joint_position)  # every step, as its node hears them
        if allocator.remaining is not None:  # /splitter/joint_health, used after this tick
            remaining = allocator.remaining.reachable(model)
            controller.set_radius_bounds(remaining.radius_min_m, remaining.radius_max_m, t)
        if t % CONTROL_PERIOD_NS == 0 and step < n_steps:
            q_measured = received_quaternion(state.orientation_wxyz, hops=1)  # odom, imu
            rate, attitude, inertia = gyro, q_measured, state.principal_inertia_kg_m2
            masses = hemi = None
            if flight is not None:  # the controllers' imu and inertia: the estimator's
                joints = JointReading(
                    state.joint_position, state.joint_velocity, readings.joint_effort
                )
                estimate = flight.on_sensors(
                    t,
                    GyroSample(gyro, q_measured, readings.specific_force_m_s2),
                    joints,
                    readings.leg_forces_n,
                )
                estimates.append(estimate)
                rate = estimate.angular_velocity_rad_s
                attitude = received_quaternion(estimate.orientation_wxyz, hops=1)
                inertia, masses = estimate.principal_inertia_kg_m2, estimate.masses_kg
                hemi = estimate.hemi_inertia_kg_m2
            answer = gait.on_sensors(
                t,
                ImuReading(q_measured, gyro, readings.specific_force_m_s2),
                readings.ranges_m,
                readings.leg_forces_n,
                float(state.joint_position[TETHER_INDEX]),
                principal_inertia_kg_m2=inertia,  # /splitter/inertia (or the estimator's)
            )
            if answer.error:
                raise ValueError(f"gait phase manager at t = {t * 1e-9:.3f} s: {answer.error}")
            out = answer.output
            phase_name = out.phase.value
            mpc_tick.set_phase(phase_name)
            mpc_tick.set_stance_shape(out.stance_shape)
            if out.reference is not None:
                ref = out.reference
                q_ref = received_quaternion(ref.q_ref_wxyz, hops=1)  # pose message
                mpc_tick.set_reference(ref.stamp_ns, ref.w_ref_rad_s, q_ref)
            mpc_tick.gait_answered(t)
            sim.command_jump(t, out.jump_force_n, out.jump_torque_nm)
            if t in fail_ns:
                controller.inject_solver_failures(1)
            planned = mpc_tick.on_state(
                t, rate, attitude, inertia, masses_kg=masses, hemi_inertia_kg_m2=hemi
            )
            if planned is None or planned.setpoint_kg_m2 is None:
                raise ValueError(f"MPC tick at t = {t * 1e-9:.3f} s not answered: {planned}")
            setpoint = planned.setpoint_kg_m2
            status = controller.status
            if status.replanned:
                solve = {
                    "time_ms": status.solve_time_ms,
                    "iterations": status.iterations,
                    "ok": float(status.solve_ok),
                    "cost": status.cost,
                }
            counts = {"failures": status.failures, "deadline_misses": status.deadline_misses}
            commanded = allocator.lockstep_tick(
                t, inertia, rate, setpoint, readings.specific_force_m_s2
            )
            for allocation in commanded.commands:  # one per tick in lockstep
                sim.command_joints(t, allocation.joint_position, allocation.joint_velocity)
        _record(rec, state, setpoint, solve, counts)
        rec["joint_fault"].append(state.joint_fault)
        rec["joint_detected"].append(_detected(allocator.health.faulty_joints))
        last = allocator.last_allocation
        rec["joint_command"].append(
            state.joint_position if last is None else commanded_position(last, t)
        )
        phases.append(phase_name)
        if step < n_steps:
            sim.step()
        if progress is not None and (step % report_every == 0 or step == n_steps):
            progress(step / max(1, n_steps))
    _LOG.debug(
        "closed loop of %s/%s: %.1f s wall",
        scenario.name,
        scenario.variant,
        time.monotonic() - started,
    )
    series = _series(rec, phases, scenario.gravity_m_s2)
    if estimates:
        series.extras.update(estimate_extras(estimates))
    return series


def commanded_position(allocation: Allocation, t_ns: int) -> np.ndarray:
    """Where ``allocation``'s command asks the joints to be at ``t_ns`` [rad, m]: its
    position followed at its velocity for at most ``COMMAND_EXTRAPOLATION_S``, as the
    servos do (between two control ticks a moving joint is not behind its command)."""
    ahead_s = min(max(0.0, (t_ns - allocation.t_ns) / NS_PER_S), COMMAND_EXTRAPOLATION_S)
    return allocation.joint_position + allocation.joint_velocity * ahead_s


def estimate_extras(estimates: list[FlightEstimate]) -> dict[str, np.ndarray]:
    """The flight estimator's answers as series extras (one row per control tick)."""
    return {
        "estimate_t_s": np.array([e.t_ns / NS_PER_S for e in estimates]),
        "estimate_rate_rad_s": np.array([e.angular_velocity_rad_s for e in estimates]),
        "estimate_gyro_bias_rad_s": np.array([e.gyro_bias_rad_s for e in estimates]),
        "estimate_mass_ratios": np.array([e.mass_ratios for e in estimates]),
        "estimate_masses_kg": np.array([e.masses_kg for e in estimates]),
        "estimate_inertia_kg_m2": np.array([e.principal_inertia_kg_m2 for e in estimates]),
        "estimate_hemi_inertia_kg_m2": np.array([e.hemi_inertia_kg_m2 for e in estimates]),
    }


_RECORDED = (
    "t",
    "w",
    "q",
    "inertia",
    "setpoint",
    "radii",
    "position",
    "velocity",
    "joints",
    "hemi_g",
    "contact",
    "energy",
    "momentum",
    "tension",
    "power",
    "solve_time_ms",
    "solve_iterations",
    "solve_ok",
    "solve_cost",
    "failures",
    "deadline_misses",
    "joint_fault",
    "joint_detected",
    "joint_command",
)


def _detected(joints: frozenset[int]) -> np.ndarray:
    out = np.zeros(25)
    out[list(joints)] = 1.0
    return out


def _record(rec: dict[str, list], state, setpoint, solve: dict, counts: dict) -> None:
    rec["t"].append(state.t_ns / NS_PER_S)
    rec["w"].append(state.angular_velocity_rad_s)
    rec["q"].append(state.orientation_wxyz)
    rec["inertia"].append(state.principal_inertia_kg_m2)
    rec["setpoint"].append(np.asarray(setpoint, dtype=float).copy())
    rec["radii"].append(state.radii_m)
    rec["position"].append(state.position_m)
    rec["velocity"].append(state.velocity_m_s)
    rec["joints"].append(state.joint_position)
    rec["hemi_g"].append(state.hemi_acceleration_g)
    rec["contact"].append(state.contact_force_n)
    rec["energy"].append(state.rotational_energy_j)
    rec["momentum"].append(state.angular_momentum_world)
    rec["tension"].append(state.tether_tension_n)
    rec["power"].append(state.actuator_power_w)
    rec["solve_time_ms"].append(solve["time_ms"])
    rec["solve_iterations"].append(solve["iterations"])
    rec["solve_ok"].append(solve["ok"])
    rec["solve_cost"].append(solve["cost"])
    rec["failures"].append(counts["failures"])
    rec["deadline_misses"].append(counts["deadline_misses"])


def _series(rec: dict[str, list], phases: list[str], gravity: float) -> RunSeries:
    a = {k: np.asarray(v, dtype=float) for k, v in rec.items()}
    return RunSeries(
        t_s=a["t"],
        angular_velocity_rad_s=a["w"],
        orientation_wxyz=a["q"],
        principal_inertia_kg_m2=a["inertia"],
        inertia_setpoint_kg_m2=a["setpoint"],
        radii_m=a["radii"],
        position_m=a["position"],
        velocity_m_s=a["velocity"],
        joint_position=a["joints"],
        gravity_m_s2=gravity,
        gait_phase=phases,
        extras={
            "hemi_acceleration_g": a["hemi_g"],
            # what the simulator node reports on /diagnostics: the peak so far
            "hemi_peak_acceleration_g": np.maximum.accumulate(a["hemi_g"].max(axis=1)),
            "contact_force_n": a["contact"],  # (n, 2, 3) ground on hemi a, b, world [N]
            "rotational_energy_j": a["energy"],
            "angular_momentum_world": a["momentum"],
            "tether_tension_n": a["tension"],
            "actuator_power_w": a["power"],
            "mpc_solve_time_ms": a["solve_time_ms"],
            "mpc_iterations": a["solve_iterations"],
            "mpc_solve_ok": a["solve_ok"],
            "mpc_cost": a["solve_cost"],
            "mpc_failures": a["failures"],
            "mpc_deadline_misses": a["deadline_misses"],
            "joint_fault": a["joint_fault"],  # (n, 25) simulator's truth: 0 ok, 1 locked, 2 limp
            "joint_detected": a["joint_detected"],  # (n, 25) 1: the allocator found it faulty
            "joint_command": a["joint_command"],  # (n, 25) where the last command asks them
        },
    )


def with_variant(scenario: Scenario, **controller_changes) -> Scenario:
    """A copy of ``scenario`` with controller fields replaced (tests, benchmarks)."""
    return replace(scenario, controller=replace(scenario.controller, **controller_changes))
