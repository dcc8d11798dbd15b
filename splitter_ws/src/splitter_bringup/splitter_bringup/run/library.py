"""The library closed loop: a scenario run without ROS, in the graph's lockstep order.

The per-tick cores the nodes drive, driven here in the order of the lockstep
protocol (docs/ARCHITECTURE.md), so that this loop and the node graph agree by
construction, not by care: each node converts messages to and from the same
object's calls. For each simulator step at time ``t`` (5 ms):

1. the simulator's state at ``t`` (``SimulatorTick.state``: what the simulator node
   publishes: imu, inertia, odom, contact wrenches, joint_states);
2. on a control tick (``t % 10 ms == 0``):
   a. gait phase manager: ``GaitTick.on_state`` with odom, the contact forces, the
      tether length and the measured principal inertia; its phase, attitude
      reference and answer go to ``MpcTick`` as the latched topics and the jump
      command would; its jump wrench to ``SimulatorTick.command_jump``;
   b. MPC: ``MpcTick.on_state(t, w, q, I)`` -> setpoint stamped t;
   c. allocator: ``AllocatorTick.lockstep_tick(t, I, w, setpoint)`` -> joint
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
from dataclasses import dataclass, replace

import numpy as np

from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.scenario.definition import Scenario
from splitter_bringup.scenario.graph_config import gait_parameters
from splitter_ik.core.allocator_tick import AllocatorTick, AllocatorTickSettings
from splitter_model.actuators import TETHER_INDEX, CommandLag
from splitter_model.kinematics import radii_from_joint_positions
from splitter_model.model import RobotModel
from splitter_mpc.core.controller import ControllerConfig, MorphingController
from splitter_mpc.core.estimator import EstimatorConfig, FlightEstimator
from splitter_mpc.core.gait_tick import BodyState, GaitTick, gait_settings_from_parameters
from splitter_mpc.core.mpc import MpcSettings, settings_for_weights
from splitter_mpc.core.mpc_tick import MpcTick
from splitter_mpc.core.ocp import MpcWeights
from splitter_mpc.core.solvers import LOCKSTEP_MAX_TIME_S, SolverOptions
from splitter_sim.core.settings import SimulatorSettings, initial_state_from_euler
from splitter_sim.core.simulator import SimConfig, Simulator
from splitter_sim.core.tick import SimulatorTick

_LOG = logging.getLogger(__name__)
NS_PER_S = 1_000_000_000
CONTROL_PERIOD_NS = 10_000_000  # [ns] the control tick (docs/ARCHITECTURE.md)

ProgressCallback = Callable[[float], None]  # called with the fraction done, in [0, 1]


@dataclass(frozen=True)
class Perturbation:
    """How the plant and its sensors differ from what the controller assumes (robustness runs).

    * ``plant_model``: the robot the simulator flies (e.g. other masses); the MPC and
      the allocator keep the nominal ``model`` of :func:`run_closed_loop`.
    * ``gyro_noise_rad_s``, ``gyro_bias_rad_s``: the rate gyro of ``/splitter/imu``, what
      the MPC and the allocator read, reports the true body rate plus this constant
      bias plus white Gaussian noise of this standard deviation per axis and reading
      (one reading per control tick, drawn from ``seed``). The gait phase manager
      reads odometry and the orientation stays exact.
    * ``actuator_lag_s``: every joint and tether command reaches the simulator's servos
      through a first-order lag of this time constant (position and velocity alike,
      on top of the servos' rate and acceleration limits): the shape follows late.
    """

    plant_model: RobotModel | None = None
    gyro_noise_rad_s: float = 0.0  # [rad/s] standard deviation per axis and reading
    gyro_bias_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [rad/s] body frame
    actuator_lag_s: float = 0.0  # [s] time constant, 0: none
    seed: int = 0  # of the gyro noise
    # [s] the lag the robot's allocator leads its commands through (its actuator model);
    # None: the true one (the robot knows its servos)
    actuator_lag_model_s: float | None = None

    @property
    def modelled_actuator_lag_s(self) -> float:
        """[s] the lag time constant the controllers assume."""
        if self.actuator_lag_model_s is None:
            return self.actuator_lag_s
        return self.actuator_lag_model_s

    def __post_init__(self) -> None:
        for name in ("gyro_noise_rad_s", "actuator_lag_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"Perturbation.{name} must be finite and >= 0, got {value!r}")
        bias = np.asarray(self.gyro_bias_rad_s, dtype=float)
        if bias.shape != (3,) or not np.all(np.isfinite(bias)):
            raise ValueError(f"Perturbation.gyro_bias_rad_s: 3 finite numbers, got {bias}")


class _Perturbed:
    """The gyro reading and the lagged joint commands of a :class:`Perturbation`."""

    def __init__(self, perturbation: Perturbation, control_period_s: float) -> None:
        self._p = perturbation
        self._bias = np.asarray(perturbation.gyro_bias_rad_s, dtype=float)
        self._rng = np.random.default_rng(perturbation.seed)
        self._lag = CommandLag(perturbation.actuator_lag_s, control_period_s)

    def gyro(self, w_rad_s: np.ndarray) -> np.ndarray:
        """The rate gyro's reading of the true body rate ``w_rad_s`` [rad/s]."""
        w = np.asarray(w_rad_s, dtype=float) + self._bias
        if self._p.gyro_noise_rad_s > 0.0:
            w = w + self._rng.normal(0.0, self._p.gyro_noise_rad_s, 3)
        return w

    def command(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joint command (position, velocity) the servos receive, lagged."""
        position, velocity = self._lag.apply(q, qd)
        return position, velocity


def received_quaternion(q_wxyz, hops: int = 2) -> np.ndarray:
    """``q`` as a node receives it: normalised as ``conversions.unit_quaternion`` does, per hop."""
    q = np.asarray(q_wxyz, dtype=float)
    for _ in range(2 * hops):
        q = q / float(np.linalg.norm(q))
    return q


def simulator_for(scenario: Scenario, model: RobotModel | None = None) -> Simulator:
    """The simulator set up as ``scenario`` describes (initial state, step, gravity, ground)."""
    initial = initial_state_from_euler(
        scenario.initial_position_m,
        scenario.initial_velocity_m_s,
        scenario.initial_orientation_euler_deg,
        scenario.initial_angular_velocity_rad_s,
        scenario.initial_radii_m,
    )
    config = SimConfig(
        dt_s=float(scenario.sim_dt_s),
        gravity_m_s2=float(scenario.gravity_m_s2),
        ground_contact=bool(scenario.ground_contact),
        compliant_legs=bool(scenario.compliant_legs),
    )
    return Simulator(model or RobotModel(), config, initial)


def controller_config(scenario: Scenario, mpc: MpcSettings | None = None) -> ControllerConfig:
    """The MPC configuration of a scenario: the node's parameters, as a core object.

    The scenario fixes the formulation (objective, horizon, prediction step,
    integrator, the step the weights are given for);
    ``mpc`` brings the solver, its options and the hardware margins.
    """
    c = scenario.controller
    weights = MpcWeights(q_w=c.q_w, r=c.r, q_t=c.q_t, q_q=c.q_q, q_tq=c.q_tq, objective=c.objective)
    if mpc is None:
        mpc = MpcSettings(options=SolverOptions(max_time_s=LOCKSTEP_MAX_TIME_S))
    formulation = replace(
        mpc,
        horizon=c.horizon,
        dt_s=c.dt_s,
        integrator=c.integrator,
        weights_step_s=c.weights_step_s,
    )
    mpc = settings_for_weights(formulation, weights)
    return ControllerConfig(
        enabled=c.enabled,
        weights=weights,
        mpc=mpc,
        recovery_spin_rad_s=c.recovery_spin_rad_s,
        recovery_momentum_ratio_max=(
            math.inf if c.recovery_momentum_ratio_max is None else c.recovery_momentum_ratio_max
        ),
    )


def run_closed_loop(
    scenario: Scenario,
    progress: ProgressCallback | None = None,
    *,
    model: RobotModel | None = None,
    controller: MorphingController | None = None,
    mpc: MpcSettings | None = None,
    fail_solves_at_s: tuple[float, ...] = (),
    duration_s: float | None = None,
    perturbation: Perturbation | None = None,
    estimation: EstimatorConfig | None = None,
) -> RunSeries:
    """Run ``scenario`` (its chosen variant) to its end; every simulator step recorded.

    ``controller`` replaces the scenario's MPC (for benchmarks); ``mpc`` sets the
    solver options of the default one. ``fail_solves_at_s`` injects a solver
    failure at the re-plans at those times (tests of the failure handling).
    ``duration_s`` shortens the run. ``perturbation`` makes the plant, its gyro and
    its actuators differ from what the controller assumes (:class:`Perturbation`);
    the series records the true state.
    """
    model = model or RobotModel()
    if controller is None:
        with MorphingController(model, controller_config(scenario, mpc)) as own:
            return run_closed_loop(
                scenario,
                progress,
                model=model,
                controller=own,
                fail_solves_at_s=fail_solves_at_s,
                duration_s=duration_s,
                perturbation=perturbation,
                estimation=estimation,
            )
    plant = None if perturbation is None else perturbation.plant_model
    sim = SimulatorTick(
        simulator_for(scenario, plant or model),
        SimulatorSettings(control_period_s=CONTROL_PERIOD_NS / NS_PER_S),
    )
    perturbed = (
        None if perturbation is None else _Perturbed(perturbation, CONTROL_PERIOD_NS / NS_PER_S)
    )
    gait = GaitTick(*gait_settings_from_parameters(gait_parameters(scenario)))
    mpc_tick = MpcTick(controller)
    allocator = AllocatorTick(  # starts, as its node, from the first measured inertia
        model,
        settings=AllocatorTickSettings(
            actuator_lag_s=0.0 if perturbation is None else perturbation.modelled_actuator_lag_s
        ),
    )
    estimator = None if estimation is None else FlightEstimator(model, estimation)
    fail_ns = {round(t * NS_PER_S) for t in fail_solves_at_s}
    duration = scenario.duration_s if duration_s is None else min(duration_s, scenario.duration_s)
    dt_ns = sim.sim.config.dt_ns
    n_steps = round(duration * NS_PER_S / dt_ns)
    if CONTROL_PERIOD_NS % dt_ns != 0:
        raise ValueError(f"sim step {dt_ns} ns does not divide the control tick")

    rec: dict[str, list] = {k: [] for k in _RECORDED}
    rec_est: list = []
    phases: list[str] = []
    setpoint = np.asarray(sim.state().principal_inertia_kg_m2, dtype=float)
    phase_name = ""
    counts = {"failures": 0, "deadline_misses": 0}  # cumulative, as on /diagnostics
    started = time.monotonic()
    report_every = max(1, n_steps // 20)
    for step in range(n_steps + 1):
        state = sim.state()
        t = state.t_ns
        solve = {"time_ms": np.nan, "iterations": np.nan, "ok": np.nan, "cost": np.nan}
        if t % CONTROL_PERIOD_NS == 0 and step < n_steps:
            q_measured = received_quaternion(state.orientation_wxyz, hops=1)  # odom, imu
            gyro = (  # the rate of the imu message
                state.angular_velocity_rad_s
                if perturbed is None
                else perturbed.gyro(state.angular_velocity_rad_s)
            )
            inertia_used = state.principal_inertia_kg_m2
            if estimator is not None:
                radii_measured = radii_from_joint_positions(model, state.joint_position)
                in_flight = not (
                    bool(np.any(state.in_contact)) or bool(np.any(state.thrust_force_n))
                )
                if not estimator.started:
                    estimator.start(t, gyro, radii_measured, q_measured)
                estimate = estimator.update(t, gyro, radii_measured, in_flight=in_flight)
                gyro = estimate.angular_velocity_rad_s
                inertia_used = estimate.principal_inertia_kg_m2
                estimated = estimator.estimated_model()
                controller.set_mass_model(estimated)
                allocator.set_mass_model(estimated)
                rec_est.append((t, estimate))
            body = BodyState(
                state.position_m, state.velocity_m_s, q_measured, state.angular_velocity_rad_s
            )
            answer = gait.on_state(
                t,
                body,
                state.contact_force_n,
                float(state.joint_position[TETHER_INDEX]),
                principal_inertia_kg_m2=inertia_used,  # /splitter/inertia
            )
            if answer.error:
                raise ValueError(f"gait phase manager at t = {t * 1e-9:.3f} s: {answer.error}")
            out = answer.output
            phase_name = out.phase.value
            mpc_tick.set_phase(phase_name)
            if out.reference is not None:
                ref = out.reference
                q_ref = received_quaternion(ref.q_ref_wxyz, hops=1)  # pose message
                mpc_tick.set_reference(ref.stamp_ns, ref.w_ref_rad_s, q_ref)
            mpc_tick.gait_answered(t)
            sim.command_jump(t, out.jump_force_n, out.jump_torque_nm)
            if t in fail_ns:
                controller.inject_solver_failures(1)
            planned = mpc_tick.on_state(t, gyro, q_measured, inertia_used)
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
            commanded = allocator.lockstep_tick(t, inertia_used, gyro, setpoint)
            for allocation in commanded.commands:  # one per tick in lockstep
                position, velocity = allocation.joint_position, allocation.joint_velocity
                if perturbed is not None:
                    position, velocity = perturbed.command(position, velocity)
                sim.command_joints(t, position, velocity)
        _record(rec, state, setpoint, solve, counts)
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
    if rec_est:
        series.extras["estimate_t_s"] = np.array([t * 1e-9 for t, _ in rec_est])
        series.extras["estimate_gyro_bias_rad_s"] = np.array(
            [e.gyro_bias_rad_s for _, e in rec_est]
        )
        series.extras["estimate_mass_ratios"] = np.array([e.mass_ratios for _, e in rec_est])
        series.extras["estimate_rate_rad_s"] = np.array(
            [e.angular_velocity_rad_s for _, e in rec_est]
        )
        series.extras["estimate_inertia_kg_m2"] = np.array(
            [e.principal_inertia_kg_m2 for _, e in rec_est]
        )
    return series


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
)


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
        },
    )


def with_variant(scenario: Scenario, **controller_changes) -> Scenario:
    """A copy of ``scenario`` with controller fields replaced (tests, benchmarks)."""
    return replace(scenario, controller=replace(scenario.controller, **controller_changes))
