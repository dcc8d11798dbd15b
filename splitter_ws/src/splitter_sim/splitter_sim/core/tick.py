"""The simulator between two steps: commands in, one step, what to publish out (ROS-free).

:class:`SimulatorTick` owns one :class:`~splitter_sim.core.simulator.Simulator` and
every decision the ``simulator`` node makes around it (docs/ARCHITECTURE.md,
"Lockstep protocol"); the node only turns messages into these calls and the
results into messages, and the library loop (``splitter_bringup.run.library``)
drives the same object:

* stamp rules (:class:`CommandStamps`): a command answers a state the simulator
  published, so it may not be stamped later than the simulated time, nor earlier
  than the last one of its topic. Real time, a joint command is a point of a
  trajectory: it may be stamped up to ``MAX_TRAJECTORY_LEAD_NS`` ahead (it waits
  in the :class:`~splitter_sim.core.stepping.CommandQueue` for its stamp) and may
  re-plan the points queued, but not the one already in effect;
* :meth:`SimulatorTick.command_joints` / :meth:`SimulatorTick.command_jump`:
  the contents checked (joint names, ranges, speeds; the jump wrench's frame and
  bounds) and applied; a command refused for its contents answers its lockstep
  tick (the simulator steps on the last good command) only while the commanding
  node is its topic's one publisher (the node's call,
  :func:`~splitter_msgs_py.core.stamps.refusal_answers_tick`);
* lockstep (:class:`~splitter_sim.core.stepping.LockstepWait`): on a control tick
  the simulator steps once every command topic with a publisher answered it;
* accounting: latency and late commands, tether slack events and the lowest
  tension, the peak hemi acceleration, states not published, real-time backlog;
  :meth:`SimulatorTick.diagnostics` is the ``/diagnostics`` status as plain data;
* :meth:`SimulatorTick.published` says what else is due at a published step: the
  :class:`~splitter_sim.core.scene.Scene` (markers grid), diagnostics, progress;
* the simulated robot's errors (``SimulatorSettings.robot_errors``,
  :class:`~splitter_sim.core.robot_errors.RobotErrors`): every joint command
  reaches the simulator's servos through their
  :class:`~splitter_model.actuators.CommandLag` (one lag step per command, the
  control period), and :meth:`SimulatorTick.gyro_reading` is what the IMU's rate
  gyro reads (bias and noise); the masses are the simulator's own
  (:meth:`SimulatorSettings.simulator` builds it with them).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.actuators import CommandLag
from splitter_model.rotations import quaternion_to_matrix
from splitter_model.sensors import RANGE_MAX_M, RANGE_MIN_M, terrain_range_m
from splitter_msgs_py import names
from splitter_msgs_py.core.latency import InputLatency
from splitter_msgs_py.core.stamps import ClockNs, MessageValidationError, StampGate, clock_value
from splitter_sim.core.actuators import validate_joint_command
from splitter_sim.core.robot_errors import Gyro, RobotErrors, SensorNoise
from splitter_sim.core.scene import Ground, Scene, scene_of_state
from splitter_sim.core.settings import SimulatorSettings
from splitter_sim.core.simulator import HEMI_BODY_INDEX, SimState, Simulator
from splitter_sim.core.stepping import (
    CommandQueue,
    LockstepWait,
    RealTimePacer,
    check_jump_wrench,
    check_trajectory_stamp,
    jump_thrust,
)

LOCKSTEP_TOPICS = (names.JOINT_COMMANDS, names.JUMP_COMMAND)
JOINT_KEY = "joint_commands"  # rejection / latency key of the joint commands
JUMP_KEY = "jump_command"  # likewise of the jump commands
LATENCY_KEYS = {names.JOINT_COMMANDS: JOINT_KEY, names.JUMP_COMMAND: JUMP_KEY}
# [ns] commands may not be stamped later than the simulated time: they answer states
MAX_COMMAND_LEAD_NS = 0
# [ns] real time: a joint command may be stamped this far ahead (a trajectory point
# planned over the latency; it waits for its stamp); further ahead it is corrupt
MAX_TRAJECTORY_LEAD_NS = 2_000_000_000


class CommandStamps(StampGate):
    """The simulator's stamp rules for its commands (module docstring).

    :class:`StampGate`'s rules without lead, except on ``trajectory_topics``
    (real-time joint commands): not before ``not_before_ns`` (the point in
    effect), at most ``MAX_TRAJECTORY_LEAD_NS`` ahead of the simulated time.
    """

    def __init__(self, trajectory_topics: Sequence[str] = ()) -> None:
        super().__init__(MAX_COMMAND_LEAD_NS)
        self.trajectory_topics = tuple(trajectory_topics)
        self.latency = InputLatency()  # of the admitted commands: arrival - stamp

    def admit(
        self, topic: str, t_ns: int, clock_ns: ClockNs = None, not_before_ns: int | None = None
    ) -> int:
        now = clock_value(clock_ns)
        if topic not in self.trajectory_topics:
            t_ns = super().admit(topic, t_ns, now, not_before_ns)
        elif now is None:
            raise MessageValidationError("header.stamp: no simulated time to compare it with")
        else:
            check_trajectory_stamp(int(t_ns), not_before_ns or 0, now, MAX_TRAJECTORY_LEAD_NS)
        self.latency.record(LATENCY_KEYS.get(topic, topic), t_ns, now)
        return int(t_ns)


@dataclass
class StartGate:
    """When stepping starts: once nothing is missing for ``settle_s``, or after ``wait_s``."""

    wait_s: float  # [s] wall: longest wait for what is missing
    settle_s: float  # [s] wall: how long nothing may be missing first
    since_s: float  # [s] wall time the wait began
    _ready_since: float | None = None

    def may_start(self, now_s: float, missing: Sequence[str]) -> bool:
        """Whether to start at ``now_s`` with ``missing`` (descriptions) still absent."""
        if missing:
            self._ready_since = None
            return now_s - self.since_s >= self.wait_s
        if self._ready_since is None:
            self._ready_since = now_s
        return now_s - self._ready_since >= self.settle_s


@dataclass(frozen=True)
class SensorReadings:
    """What the robot's sensors read of one state (:meth:`SimulatorTick.readings`)."""

    gyro_rad_s: NDArray[np.float64]  # (3,) body, with bias and noise
    gyro_noise_rad_s: float  # [rad/s] the gyro's noise std (its datasheet)
    joint_effort: NDArray[np.float64]  # (25,) limbs [N m], tether [N]
    ranges_m: NDArray[np.float64]  # (2,) the hemis' rangefinders [m], float32 as sent
    leg_forces_n: NDArray[np.float64]  # (2, 3) the hemis' leg load cells, base [N]
    # (3,) the IMU's accelerometer: the specific force at the COM, base [m/s^2]
    specific_force_m_s2: NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))
    accelerometer_noise_m_s2: float = 0.0  # [m/s^2] its noise std (its datasheet)


@dataclass(frozen=True)
class Published:
    """What a published step brings besides the state streams."""

    scene: Scene | None  # on the markers grid, else None
    diagnostics: bool  # on the diagnostics grid
    progress: bool  # on the progress-log grid
    slack_started: bool  # the tether went slack at this step


class SimulatorTick:
    """One simulator, its command queue, stamp rules, lockstep wait and accounting."""

    def __init__(self, sim: Simulator, settings: SimulatorSettings | None = None) -> None:
        """``sim`` should fly ``settings.robot_errors``' masses (``settings.simulator``)."""
        s = settings or SimulatorSettings()
        dt_ns = sim.config.dt_ns
        self.sim = sim
        self._terrain = sim.config.terrain
        self.settings = s
        self.real_time = s.mode == "real_time"
        self.control_ns = s.period_ns("control_period_s", dt_ns)
        self.markers_ns = s.period_ns("markers_period_s", dt_ns)
        self.diagnostics_ns = s.period_ns("diagnostics_period_s", dt_ns)
        self.progress_ns = max(dt_ns, round(s.progress_period_s * 1e9))
        self.duration_ns = round(s.duration_s * 1e9)  # 0: never ends
        self.ground = Ground(terrain=sim.config.terrain) if sim.config.ground_contact else None
        self.stamps = CommandStamps((names.JOINT_COMMANDS,) if self.real_time else ())
        self.lockstep = LockstepWait(LOCKSTEP_TOPICS, s.lockstep_timeout_s)
        self.queue = CommandQueue()  # joint commands stamped ahead, applied at their stamps
        self.pacer = RealTimePacer(s.rate_factor, dt_ns)
        self.applied_joint_stamp = 0  # [ns] stamp of the joint command point in effect
        self.late_joint_commands = 0  # real time: arrived after their stamp
        self.backlog_drops = 0  # real time: times the simulator fell behind the wall clock
        self.behind_s = 0.0  # [s] simulated time it was behind, summed over the drops
        self.slack_events = 0
        self.tension_min_n = math.inf  # [N] lowest tether tension of any published step
        self.peak_hemi_g = 0.0  # [G] largest hemi specific force of any state
        self.unpublished = 0  # states not published (non-finite or refused by a message)
        self.last_published: SimState | None = None
        self._was_slack = False
        self._state: SimState | None = None
        self.errors: RobotErrors = s.robot_errors
        lag_s = self.errors.actuator_lag_s  # [s] time constant
        self._lag = CommandLag(lag_s, self.control_ns * 1e-9) if lag_s > 0.0 else None
        self._latency_ns = round(self.errors.command_latency_s * 1e9)  # [ns]
        self._gyro = Gyro(self.errors)
        self._gyro_reading: tuple[int, NDArray[np.float64]] | None = None  # (t [ns], rate)
        e = self.errors
        self._sensors = {  # name: (noise, (t [ns], last reading) or None)
            "effort": [SensorNoise(e.joint_effort_noise, e.noise_seed, SensorNoise.EFFORT), None],
            "range": [SensorNoise(e.range_noise_m, e.noise_seed, SensorNoise.RANGE), None],
            "leg_force": [
                SensorNoise(e.leg_force_noise_n, e.noise_seed, SensorNoise.LEG_FORCE),
                None,
            ],
            "accelerometer": [
                SensorNoise(e.accelerometer_noise_m_s2, e.noise_seed, SensorNoise.ACCELEROMETER),
                None,
            ],
        }

    def describe(self) -> str:
        """Mode, step, gravity, ground and duration in one line (the node's start-up log)."""
        s, config = self.settings, self.sim.config
        return (
            f"{s.mode}{f' x{s.rate_factor:g}' if self.real_time else ''}, dt "
            f"{config.dt_s * 1e3:g} ms, gravity {config.gravity_m_s2:.4g} m/s^2, ground contact "
            f"{'on' if config.ground_contact else 'off'}, duration "
            + (f"{self.duration_ns * 1e-9:g} s" if self.duration_ns else "unlimited")
        )

    @property
    def latency(self) -> InputLatency:
        """Latency of the commands admitted by their stamps (simulated arrival - stamp)."""
        return self.stamps.latency

    @property
    def time_ns(self) -> int:
        """Simulated time [ns]."""
        return self.sim.time_ns

    # --- commands ---------------------------------------------------------------------
    def not_before_ns(self, topic: str) -> int | None:
        """The earliest stamp a command of ``topic`` may carry beyond the per-topic order."""
        return self.applied_joint_stamp if topic in self.stamps.trajectory_topics else None

    def admit(self, topic: str, stamp_ns: int) -> int:
        """``stamp_ns`` if a command of ``topic`` may carry it; MessageValidationError if not."""
        return self.stamps.admit(topic, stamp_ns, self.time_ns, self.not_before_ns(topic))

    def command_joints(
        self, stamp_ns: int, position: ArrayLike, velocity: ArrayLike | None = None
    ) -> None:
        """A joint command point stamped ``stamp_ns`` (admitted): applied, or queued if ahead.

        ValueError when its contents are refused (it answers no tick: the caller decides,
        :func:`~splitter_msgs_py.core.stamps.refusal_answers_tick`).
        """
        now = self.time_ns
        arrives = stamp_ns + self._latency_ns  # at the servos (robot_errors.command_latency_s)
        if arrives > now:  # a trajectory point ahead (or delayed), followed at its time
            validate_joint_command(self.sim.joint_limits, position, velocity, names.JOINT_NAMES)
            self.queue.push(arrives, (position, velocity))
        else:
            self.late_joint_commands += stamp_ns < now
            self.queue.drop_from(stamp_ns)  # a later plan: the points queued are void
            self._to_servos(stamp_ns, position, velocity)
            self.applied_joint_stamp = stamp_ns
        self.lockstep.arrived(names.JOINT_COMMANDS, stamp_ns)

    def _to_servos(self, stamp_ns: int, position: ArrayLike, velocity: ArrayLike | None) -> None:
        """A joint command point (checked first, so a refused one leaves the lag as it
        was) through the actuators' lag to the simulator's servos."""
        if self._lag is not None:
            q, qd = validate_joint_command(
                self.sim.joint_limits, position, velocity, names.JOINT_NAMES
            )
            position, velocity = self._lag.apply(q, qd)
        self.sim.command_joints(position, velocity, stamp_ns=stamp_ns)

    def command_jump(
        self,
        stamp_ns: int,
        force_n: ArrayLike,
        torque_nm: ArrayLike,
        frame_id: str = names.WORLD_FRAME,
    ) -> None:
        """A jump wrench stamped ``stamp_ns`` (admitted; world frame, torque about the COM).

        The torque names the pushing hemi, or both (:func:`jump_thrust`). ValueError when the
        wrench is refused (it answers no tick, as :meth:`command_joints`).
        """
        if frame_id != names.WORLD_FRAME:
            raise MessageValidationError(
                f"header.frame_id: expected '{names.WORLD_FRAME}', got {frame_id!r}"
            )
        check_jump_wrench(force_n, torque_nm)
        thrust = jump_thrust(self.state(), force_n, torque_nm)
        if thrust.per_hemi is None:
            self.sim.command_jump_force(force_n, thrust.hemi)
        else:
            self.sim.command_jump_forces(*thrust.per_hemi)
        self.lockstep.arrived(names.JUMP_COMMAND, stamp_ns)

    def answers_now(self, stamp_ns: int) -> bool:
        """Lockstep: a command stamped ``stamp_ns`` answers the tick the simulator is at."""
        return not self.real_time and stamp_ns == self.time_ns

    # --- stepping ---------------------------------------------------------------------
    def step(self) -> None:
        """One simulator step, after applying the queued command points now due."""
        if self.queue:
            due = self.queue.due(self.time_ns)
            if due is not None:
                stamp, (position, velocity) = due
                self._to_servos(stamp, position, velocity)
                self.applied_joint_stamp = stamp
            upcoming = self.queue.peek()
            if upcoming is not None:
                self.sim.preview_next_point(upcoming[0], upcoming[1][1])
        self.sim.step()
        self._state = None

    def state(self) -> SimState:
        """The state at the simulated time (computed once per step)."""
        if self._state is None:
            self._state = self.sim.state()
        return self._state

    def on_control_tick(self) -> bool:
        """The simulated time is a control tick (lockstep waits for its commands)."""
        return self.time_ns % self.control_ns == 0

    def waiting_for(self, has_publisher: Callable[[str], bool]) -> list[str]:
        """Lockstep command topics with a publisher that have not answered this tick."""
        return self.lockstep.waiting_for(self.time_ns, has_publisher)

    def finished(self) -> bool:
        """``duration_s`` (if set) is reached."""
        return bool(self.duration_ns) and self.time_ns >= self.duration_ns

    def clock_starts(self, waited_s: float, waiting: Sequence[str]) -> bool:
        """Real time: the wall clock starts once the first state is answered (``waiting``:
        the command topics with a publisher that have not) or ``lockstep_timeout_s`` passed.

        As a robot starts once its computer is up: a launch thrust stamped 0 then acts
        at 0, not a latency later.
        """
        return not waiting or waited_s >= self.lockstep.timeout_s

    def fell_behind(self, now_s: float) -> float:
        """Real time: the backlog beyond the catch-up is dropped; seconds behind [s]."""
        behind_s = (self.pacer.due_ns(now_s) - self.time_ns) * 1e-9
        self.backlog_drops += 1
        self.behind_s += behind_s
        self.pacer.restart(now_s, self.time_ns)
        return behind_s

    # --- outputs ----------------------------------------------------------------------
    def gyro_reading(self, state: SimState) -> NDArray[np.float64]:
        """What the IMU's rate gyro reads of ``state``'s true body rate [rad/s].

        One reading per simulated time: a second call for a state of the same time
        returns the same reading (the noise is drawn once). Without gyro errors, the
        true rate itself.
        """
        if self._gyro_reading is None or self._gyro_reading[0] != state.t_ns:
            self._gyro_reading = (state.t_ns, self._gyro.read(state.angular_velocity_rad_s))
        return self._gyro_reading[1]

    def _reading(self, sensor: str, state: SimState, truth) -> NDArray[np.float64]:
        """One reading of ``sensor`` per simulated time (the noise drawn once)."""
        slot = self._sensors[sensor]
        if slot[1] is None or slot[1][0] != state.t_ns:
            slot[1] = (state.t_ns, slot[0].read(truth()))
        return slot[1][1]

    def joint_effort_reading(self, state: SimState) -> NDArray[np.float64]:
        """What the joint effort sensors read of ``state``'s true efforts (limbs [N m], tether [N]).

        One reading per simulated time, as :meth:`gyro_reading`; without effort noise,
        the true efforts themselves.
        """
        return self._reading("effort", state, lambda: state.joint_effort)

    def range_reading(self, state: SimState) -> NDArray[np.float64]:
        """(2,) what the hemis' rangefinders read [m] (``splitter_model.sensors``).

        The noise is added to a return, never to "no return" (+-inf).
        """

        rot = quaternion_to_matrix(state.orientation_wxyz)
        terrain = self._terrain
        exact = np.array(
            [
                terrain_range_m(terrain, state.mass_positions_world_m[body], rot)
                for body in HEMI_BODY_INDEX
            ]
        )
        reading = self._reading("range", state, lambda: exact).copy()
        reading[~np.isfinite(exact)] = exact[~np.isfinite(exact)]
        reading[reading > RANGE_MAX_M] = np.inf  # what the sensor reports out of its range
        reading[reading < RANGE_MIN_M] = -np.inf
        return reading

    def leg_force_reading(self, state: SimState) -> NDArray[np.float64]:
        """(2, 3) what each hemi's leg load cell reads [N], base frame."""
        rot = quaternion_to_matrix(state.orientation_wxyz)
        return self._reading("leg_force", state, lambda: state.leg_force_n @ rot)

    def readings(self, state: SimState) -> SensorReadings:
        """Every sensor's reading of ``state`` (each once per simulated time)."""
        return SensorReadings(
            gyro_rad_s=self.gyro_reading(state),
            gyro_noise_rad_s=self.errors.gyro_noise_rad_s,
            joint_effort=self.joint_effort_reading(state),
            ranges_m=self.range_reading(state).astype(np.float32).astype(float),
            leg_forces_n=self.leg_force_reading(state),
            specific_force_m_s2=self._reading(
                "accelerometer", state, lambda: state.linear_acceleration_m_s2
            ),
            accelerometer_noise_m_s2=self.errors.accelerometer_noise_m_s2,
        )

    def publishable_state(self) -> SimState | None:
        """The state to publish now, None when it is not finite (counted)."""
        state = self.state()
        self.peak_hemi_g = max(self.peak_hemi_g, float(np.max(state.hemi_acceleration_g)))
        if not state.is_finite():
            self.unpublished += 1
            return None
        return state

    def published(self, state: SimState) -> Published:
        """Account ``state`` as published; what else is due at its time."""
        t = state.t_ns
        self.last_published = state
        self.tension_min_n = min(self.tension_min_n, state.tether_tension_n)
        slack_started = state.tether_slack and not self._was_slack
        self.slack_events += slack_started
        self._was_slack = state.tether_slack
        return Published(
            scene=scene_of_state(state, self.ground) if t % self.markers_ns == 0 else None,
            diagnostics=t % self.diagnostics_ns == 0,
            progress=t % self.progress_ns == 0 and t > 0,
            slack_started=bool(slack_started),
        )

    def diagnostics(
        self, final: bool, rejected: dict[str, int]
    ) -> tuple[int, str, dict[str, float | int | bool]] | None:
        """(level, message, values) of the physics status; None before a published state."""
        state = self.last_published
        if state is None:
            return None
        h = state.angular_momentum_world
        level, message = 0, "finished" if final else "running"
        if state.tether_slack:
            level, message = 1, "tether slack"
        if self.lockstep.timeouts:
            message += f", {self.lockstep.timeouts} lockstep timeouts"
        return (
            level,
            message,
            {
                "kinetic_energy_j": state.kinetic_energy_j,
                "rotational_energy_j": state.rotational_energy_j,
                "angular_momentum_world_x_kg_m2_s": float(h[0]),
                "angular_momentum_world_y_kg_m2_s": float(h[1]),
                "angular_momentum_world_z_kg_m2_s": float(h[2]),
                "angular_momentum_norm_kg_m2_s": float(np.linalg.norm(h)),
                "tether_tension_n": state.tether_tension_n,
                "tether_slack": bool(state.tether_slack),
                "slack_events": self.slack_events,
                "tether_tension_min_n": self.tension_min_n,
                "hemi_a_in_contact": bool(state.in_contact[0]),
                "hemi_b_in_contact": bool(state.in_contact[1]),
                "hemi_a_contact_normal_force_n": float(state.contact_force_n[0, 2]),
                "hemi_b_contact_normal_force_n": float(state.contact_force_n[1, 2]),
                "hemi_a_acceleration_g": float(state.hemi_acceleration_g[0]),
                "hemi_b_acceleration_g": float(state.hemi_acceleration_g[1]),
                "hemi_peak_acceleration_g": self.peak_hemi_g,
                "actuator_power_w": state.actuator_power_w,
                "actuator_work_j": state.actuator_work_j,
                "rejected_joint_commands": rejected.get(JOINT_KEY, 0),
                "rejected_jump_commands": rejected.get(JUMP_KEY, 0),
                "lockstep_timeouts": self.lockstep.timeouts,
                **self.latency.values(),
                "late_joint_commands": self.late_joint_commands,
                "queued_joint_commands": len(self.queue),
                "real_time_backlog_drops": self.backlog_drops,
                "real_time_behind_s": self.behind_s,
                "unpublished_states": self.unpublished,
                "finished": final,
            },
        )

    def summary(self, rejected: dict[str, int]) -> str:
        """The end-of-run figures of the last published state (for the log)."""
        state = self.last_published
        if state is None:
            return "no state published"
        return (
            f"energy {state.kinetic_energy_j:.6g} J, |H| "
            f"{np.linalg.norm(state.angular_momentum_world):.6g} kg m^2/s, tension "
            f"{state.tether_tension_n:.4g} N, {self.slack_events} slack events, "
            f"{self.lockstep.timeouts} lockstep timeouts, rejected commands {rejected or 'none'}"
        )
