"""The gait phase manager's control tick, ROS-free: inputs, their checks, joining, the answer.

The ``gait_phase_manager`` node converts messages into the plain inputs below and
publishes what :class:`GaitTick` answers; the library closed loop drives the same
object with the simulator's state (:meth:`GaitTick.on_state`). Per control tick
``t`` (a multiple of ``control_period_s``):

* inputs, filed under their stamp's tick by a
  :class:`~splitter_mpc.core.tick_inputs.TickAssembler`: only what the robot
  measures (DESIGN.md section 3): the IMU (:class:`ImuReading`: attitude, gyro,
  accelerometer), each hemi's rangefinder [m] and leg load cell [N] (base frame),
  the tether length [m] of ``/splitter/joint_states`` and, for the
  ``momentum_aligned`` attitude reference only, the principal moments the
  controllers use; the body's height and velocity are estimated from them
  (:class:`~splitter_mpc.core.gait_sensing.BodyMotionEstimator`), a hemi is in
  stance when its legs push harder than ``stance_force_threshold_n``;
* stamp rules: :attr:`GaitTick.stamps` (a :class:`StampGate` the node applies to
  every message before it is read);
* plausibility (:meth:`GaitTick.checked`): beyond the limits below a value is
  corrupt (or the simulation diverged); it is filed as rejected (None) and its tick
  is answered from the last good value of that topic, so lockstep never stalls;
* the answer (:class:`GaitAnswer`): the machine's output, or None (zero thrust)
  before any good input or when the machine refuses its inputs; the diagnostics
  content on the ``diagnostics_period_s`` grid.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from splitter_model.sensors import RANGE_MAX_M
from splitter_mpc.core.gait import (
    GaitConfig,
    GaitOutput,
    GaitPhaseMachine,
    gait_config_from_parameters,
    seconds_to_ns,
)
from splitter_mpc.core.gait_sensing import (
    BodyMotionEstimator,
    BodySensingConfig,
    ImuReading,
    leg_stance_force_n,
)
from splitter_mpc.core.tick_inputs import TickAssembler, TickEvents
from splitter_msgs_py import names
from splitter_msgs_py.core.latency import InputLatency
from splitter_msgs_py.core.parameter_fields import PERIOD_S, parameter_field, parameter_fields
from splitter_msgs_py.core.stamps import (
    MAX_STAMP_LEAD_NS,
    ClockNs,
    MessageValidationError,
    StampGate,
    clock_value,
)

TICK_INPUTS = (names.IMU, *names.RANGES, *names.LEG_FORCES, names.JOINT_STATES)
# and /splitter/inertia when the attitude reference needs it (GaitConfig.needs_principal_inertia)
MAX_BODY_RATE_RAD_S = 1.0e3  # [rad/s] per gyro component (spin ~1 rad/s)
MAX_SPECIFIC_FORCE_M_S2 = 1.0e4  # [m/s^2] per accelerometer component (landings: ~10 G)
MAX_LEG_FORCE_N = 1.0e7  # [N] per leg load component (weight ~ 30 N on the moon)
MAX_TETHER_LENGTH_M = 100.0  # [m] tether joint position (the reel holds 6 m)


@dataclass(frozen=True)
class GaitNodeSettings:
    """The node's parameters besides :class:`GaitConfig`'s: the jump plan as flat arrays
    (an empty or absent one: no jump) and the tick and diagnostics periods."""

    jump_times_s: tuple[float, ...] = parameter_field(
        (), "planned jump times: earliest thrust start [s]"
    )
    jump_forces_n: tuple[float, ...] = parameter_field(
        (), "planned thrust forces, world frame, 3 values per jump (x, y, z) [N]"
    )
    jump_durations_s: tuple[float, ...] = parameter_field(
        (), "planned thrust durations, one per jump [s]"
    )
    jump_hemis: tuple[str, ...] = parameter_field(
        (), "pushing hemi per planned jump: 'a', 'b', 'auto' or 'both'", item_type=str
    )
    jump_forces_b_n: tuple[float, ...] = parameter_field(
        (),
        "hemi b's thrust per planned jump, world frame, 3 values per jump, for hemi 'both' "
        "(jump_forces_n is then hemi a's); empty: none [N]",
    )
    jump_couples_n: tuple[float, ...] = parameter_field(
        (),
        "each hemi's push across the tether in the horizontal plane per planned jump (a "
        "spin about the vertical whatever the heading; hemi 'both' or 'auto'), one per "
        "jump; empty: none [N]",
    )
    control_period_s: float = parameter_field(
        0.01, "control tick period: ticks answered are the multiples of it [s]", bounds=(0.001, 1.0)
    )
    diagnostics_period_s: float = parameter_field(
        0.1,
        "diagnostics period in simulated time, a multiple of control_period_s [s]",
        bounds=PERIOD_S,
    )

    def __post_init__(self) -> None:
        if self.control_period_ns <= 0 or self.diagnostics_period_ns % self.control_period_ns:
            raise ValueError(
                f"diagnostics_period_s: ({self.diagnostics_period_s} s) must be a multiple of "
                f"control_period_s ({self.control_period_s} s)"
            )

    @property
    def control_period_ns(self) -> int:
        return seconds_to_ns(self.control_period_s)

    @property
    def diagnostics_period_ns(self) -> int:
        return seconds_to_ns(self.diagnostics_period_s)


def gait_settings_from_parameters(
    values: Mapping[str, object],
) -> tuple[GaitConfig, GaitNodeSettings, BodySensingConfig]:
    """The machine's configuration, the node's settings and the body-motion estimator's
    from its parameter values.

    Missing values take the defaults; ``ValueError`` names the parameter (``"name: reason"``).
    """

    def fields_of(config_type: type) -> dict:
        return {
            name: tuple(values[name]) if isinstance(default, tuple) else values[name]  # type: ignore[arg-type]
            for name, default, _info in parameter_fields(config_type)
            if name in values
        }

    settings = GaitNodeSettings(**fields_of(GaitNodeSettings))
    sensing = BodySensingConfig(**fields_of(BodySensingConfig))
    return gait_config_from_parameters(values), settings, sensing


@dataclass(frozen=True)
class GaitAnswer:
    """What the node publishes for tick ``t_ns``: ``output`` None is zero thrust."""

    t_ns: int
    output: GaitOutput | None
    no_good_input: bool = False  # some input never had a good value yet
    error: str = ""  # the machine refused the (validated) inputs: a bug, reported
    diagnostics: tuple[int, str, dict[str, float | int | str | bool]] | None = None
    stance_shape_changed: bool = False  # publish output.stance_shape (first output, changes)


def _check_bound(field_name: str, values: ArrayLike, limit: float, unit: str) -> None:
    if max(abs(v) for v in np.asarray(values, dtype=float).reshape(-1).tolist()) > limit:
        raise MessageValidationError(
            f"{field_name}: {np.asarray(values).tolist()} beyond +-{limit:g} {unit}"
        )


class GaitTick:
    """The gait phase manager's per-tick logic around :class:`GaitPhaseMachine`."""

    def __init__(
        self,
        config: GaitConfig,
        settings: GaitNodeSettings | None = None,
        sensing: BodySensingConfig | None = None,
    ) -> None:
        self.settings = settings or GaitNodeSettings()
        self.machine = GaitPhaseMachine(config, (sensing or BodySensingConfig()).gravity_m_s2)
        self.body = BodyMotionEstimator(sensing)
        optional = (names.INERTIA,) if config.needs_principal_inertia else ()
        self.ticks = TickAssembler(self.settings.control_period_ns, TICK_INPUTS + optional)
        self.stamps = StampGate(MAX_STAMP_LEAD_NS)
        self.latency = InputLatency()  # a tick's state: simulated clock when used - stamp
        self.ticks_answered = 0
        self.stale_ticks = 0  # ticks answered with a rejected input
        self.last_output: GaitOutput | None = None
        self.last_change: tuple[int, str] = (0, "")  # (stamp [ns], reason) of the last change
        self._stance_shape: bool | None = None  # last published stance-shape flag

    @property
    def config(self) -> GaitConfig:
        return self.machine.config

    # --- inputs ----------------------------------------------------------------------------
    @staticmethod
    def checked(topic: str, value: object) -> object:
        """``value`` of ``topic`` if plausible; ``MessageValidationError`` naming the field."""
        if topic == names.IMU:
            imu: ImuReading = value  # type: ignore[assignment]
            rate = imu.angular_velocity_rad_s
            _check_bound("angular_velocity", rate, MAX_BODY_RATE_RAD_S, "rad/s")
            _check_bound(
                "linear_acceleration", imu.specific_force_m_s2, MAX_SPECIFIC_FORCE_M_S2, "m/s^2"
            )
        elif topic in names.LEG_FORCES:
            _check_bound("wrench.force", value, MAX_LEG_FORCE_N, "N")  # type: ignore[arg-type]
        elif topic in names.RANGES:
            distance = float(value)  # type: ignore[arg-type]
            if math.isnan(distance) or (math.isfinite(distance) and distance < 0.0):
                raise MessageValidationError(f"range: {distance} is not a distance")
            if math.isfinite(distance) and distance > RANGE_MAX_M:  # the sensor says +inf then
                raise MessageValidationError(
                    f"range: {distance} m beyond the rangefinder's {RANGE_MAX_M:g} m"
                )
        elif topic == names.JOINT_STATES:
            tether = float(value)  # type: ignore[arg-type]
            if not 0.0 < tether <= MAX_TETHER_LENGTH_M:
                raise MessageValidationError(
                    f"position: tether length {tether} m is not in (0, {MAX_TETHER_LENGTH_M:g}] m"
                )
        return value

    def add(
        self, topic: str, t_ns: int, value: object | None, clock_ns: ClockNs = None
    ) -> tuple[TickEvents, GaitAnswer | None]:
        """File ``value`` (checked; None: rejected) of ``topic`` stamped ``t_ns``.

        Returns what filing did (ticks dropped or skipped) and the answer of the tick
        it completed, if any.
        """
        events = self.ticks.add(topic, t_ns, value)
        if events.completed is None:
            return events, None
        t_done, inputs = events.completed
        return events, self._answer(t_done, inputs, clock_ns)

    def on_sensors(
        self,
        t_ns: int,
        imu: ImuReading,
        ranges_m: ArrayLike,
        leg_forces_n: ArrayLike,
        tether_m: float,
        *,
        principal_inertia_kg_m2: ArrayLike | None = None,
        clock_ns: ClockNs = None,
    ) -> GaitAnswer:
        """Tick ``t_ns`` from plain values (the library loop): every input filed at once.

        ``ranges_m``: the rangefinders of hemi a and b [m]; ``leg_forces_n``: (2, 3) their
        leg load cells, base frame [N].
        """
        forces = np.asarray(leg_forces_n, dtype=float)
        ranges = [float(r) for r in np.asarray(ranges_m, dtype=float)]
        values = {
            names.IMU: imu,
            names.RANGE_A: ranges[0],
            names.RANGE_B: ranges[1],
            names.LEG_FORCE_A: forces[0],
            names.LEG_FORCE_B: forces[1],
            names.JOINT_STATES: float(tether_m),
            names.INERTIA: principal_inertia_kg_m2,
        }
        answer = None
        for topic in self.ticks.inputs:
            try:
                value = self.checked(topic, values[topic])
            except MessageValidationError:
                value = None
            _, answer = self.add(topic, t_ns, value, clock_ns)
        if answer is None:
            raise ValueError(f"tick {t_ns} ns was not answered (off the grid or already answered)")
        return answer

    # --- the tick --------------------------------------------------------------------------
    def _answer(self, t_ns: int, inputs: dict[str, object | None], clock_ns: ClockNs) -> GaitAnswer:
        self.ticks_answered += 1
        self.latency.record("state", t_ns, clock_value(clock_ns))
        if any(sample is None for sample in inputs.values()):
            self.stale_ticks += 1
        samples = self.ticks.samples(inputs)  # a rejected input: its topic's last good one
        imu, range_a, range_b, leg_a, leg_b, tether = (samples[topic] for topic in TICK_INPUTS)
        inertia = samples.get(names.INERTIA)
        output, error = None, ""
        no_good_input = any(sample is None for sample in samples.values())
        if not no_good_input:
            try:
                imu_reading: ImuReading = imu  # type: ignore[assignment]
                push = (leg_stance_force_n(leg_a), leg_stance_force_n(leg_b))  # type: ignore[arg-type]
                threshold = self.config.stance_force_threshold_n
                motion = self.body.update(
                    t_ns,
                    imu_reading,
                    (range_a, range_b),  # type: ignore[arg-type]
                    (push[0] > threshold, push[1] > threshold),
                    0.5 * float(tether),  # type: ignore[arg-type]
                )
                output = self.machine.update(
                    t_ns,
                    motion.position_m,
                    motion.velocity_m_s,
                    imu_reading.orientation_wxyz,
                    imu_reading.angular_velocity_rad_s,
                    0.5 * float(tether),  # type: ignore[arg-type]
                    push,
                    None if inertia is None else inertia,
                )
            except ValueError as exc:  # inputs are validated: a bug, reported, zero thrust
                error = str(exc)
        stance_changed = False
        if output is not None:
            self.last_output = output
            if output.phase_changed:
                self.last_change = (t_ns, output.reason)
            stance_changed = output.stance_shape != self._stance_shape
            self._stance_shape = output.stance_shape
        diagnostics = None
        if t_ns % self.settings.diagnostics_period_ns == 0:
            diagnostics = self.diagnostics()
        return GaitAnswer(t_ns, output, no_good_input, error, diagnostics, stance_changed)

    def diagnostics(self) -> tuple[int, str, dict[str, float | int | str | bool]]:
        """(level, message, values) of the gait phase status, for ``/diagnostics``."""
        output = self.last_output
        values: dict[str, float | int | str | bool] = {
            "ticks_answered": self.ticks_answered,
            "ticks_with_rejected_input": self.stale_ticks,
            **self.latency.values(),
        }
        if output is None:
            return 1, "no good input yet", values
        values.update(
            {
                "phase": output.phase.value,
                "time_in_phase_s": output.time_in_phase_ns * 1e-9,
                "jumps_done": output.jumps_done,
                "jumps_planned": output.jumps_planned,
                "stance_a": output.stance[0],
                "stance_b": output.stance[1],
                "thrusting": output.thrusting,
                "pushing_hemi": output.pushing_hemi or "",
                "jump_waiting_for_stance": output.jump_waiting,
                "on_ground": output.on_ground,
                "last_change_s": self.last_change[0] * 1e-9,
                "last_change_reason": self.last_change[1],
                "hemi_a_height_m": output.hemi_height_m[0],
                "hemi_b_height_m": output.hemi_height_m[1],
                "jump_force_z_n": float(output.jump_force_n[2]),
                "jump_speed_scale": output.jump_speed_scale,
                "touchdown_in_s": min(output.touchdown_in_s, 1e9),
                "stance_shape": output.stance_shape,
            }
        )
        message = output.phase.value
        if output.jump_waiting:
            message += " (jump due, waiting for its hemi to be in stance)"
        return (1 if output.jump_waiting else 0), message, values
