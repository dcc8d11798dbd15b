"""Joint fault detection from joint states against commands (never from the injection).

A servo that works follows its command: with a command latency ``d`` and an
actuator lag ``tau`` it starts moving as soon as a command differs from where it
is, and it stays within the range of its recent commands (the lag is a weighted
mean of past commands; older than ``envelope_window_s`` they weigh e^-6 at the
50 ms lag). Two symptoms of a joint that does not, each from measured positions
and the commands the allocator sent:

* **stuck** (a locked joint, or a limp one resting at its range's end): over the
  last ``stuck_window_s`` the joint has not moved (within ``still``: an encoder's
  resolution), while every command at least ``command_delay_s`` old (latency) was
  farther than ``stuck_error`` from where it was, and no nearer at the end of the
  window than at its start. A working servo closes any such error at once, so it
  never shows this (a joint that reached its range end ahead of its command waits
  there while the command comes to it: the error shrinks);
* **drifting** (a limp joint creeping): the command has stood still (within
  ``still``) since some time between ``envelope_window_s`` and ``stuck_window_s`` ago,
  and the joint is now farther than ``stuck_error`` from it and farther by more than
  ``still`` than it was then. A servo, whatever its lag, only closes the error to a
  command that stands still. Its symptom is "not following";
* **off the servo models** (a limp joint coasting along its command): the joint moved
  farther than ``residual_margin`` outside where servos of the configured lag and
  latency (:class:`ServoModel`, at the ends of ``servo_tolerance``) would be, and on
  since it went out. Its symptom is "not following";
* **not following** (a limp joint swinging, a runaway): the joint is farther than
  ``envelope_margin`` outside the range of the commands of the last
  ``envelope_window_s`` (from a whole window of commands on).

The three "not following" tests count once one has held for half ``stuck_window_s``
without a break (one stray joint state is not a fault).

A joint found stuck that later moves by more than ``envelope_margin`` from where
it was found (its commands then hold it there) is limp after all: its symptom
becomes "not following" (the fault is the same, its handling differs).

A joint locked while its command stays put shows nothing: there is nothing to
see until it is asked to move. A detection is latched (a broken joint does not
heal in flight). Thresholds are per unit: limb joints [rad], the tether [m].

ROS-free, numpy only.
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.joints import JOINT_NAMES, N_JOINTS, TETHER_INDEX
from splitter_msgs_py.core.parameter_fields import parameter_field

_Joints = NDArray[np.float64]  # one value per joint (N_JOINTS)

STUCK = "stuck"
NOT_FOLLOWING = "not_following"
SYMPTOMS = (STUCK, NOT_FOLLOWING)


@dataclass(frozen=True)
class JointHealthConfig:
    """Thresholds of :class:`JointHealthMonitor`; limbs [rad], the tether [m]."""

    stuck_window_s: float = parameter_field(
        0.06,
        "a stuck joint has not moved for this long while commanded away [s]",
        bounds=(0.01, 1.0),
    )
    command_delay_s: float = parameter_field(
        0.025,
        "commands younger than this are not yet expected at the joint (latency) [s]",
        bounds=(0.0, 0.5),
    )
    still_rad: float = parameter_field(
        5e-4,
        "a limb joint moving less than this has not moved (encoder resolution) [rad]",
        bounds=(1e-9, 0.1),
    )
    still_m: float = parameter_field(
        2e-4, "the tether moving less than this has not moved [m]", bounds=(1e-9, 0.1)
    )
    stuck_error_rad: float = parameter_field(
        2.5e-3, "a limb joint's command this far away asks it to move [rad]", bounds=(1e-6, 1.0)
    )
    stuck_error_m: float = parameter_field(
        1e-3, "the tether's command this far away asks it to move [m]", bounds=(1e-6, 1.0)
    )
    command_extrapolation_s: float = parameter_field(
        0.02,
        "a command is a trajectory point: followed at its velocity this long past its "
        "stamp (the servos' contract) [s]",
        bounds=(0.0, 1.0),
    )
    envelope_window_s: float = parameter_field(
        0.3,
        "a working joint stays within the range of this long's commands [s]",
        bounds=(0.05, 5.0),
    )
    # Healthy joints stay within 2.5e-4 rad of their commands' range in the shipped
    # scenarios with 50 ms lag and 20 ms latency (lunar_jumping_robot_errors): 80x margin.
    envelope_margin_rad: float = parameter_field(
        0.02,
        "a limb joint this far outside its commands does not follow them [rad]",
        bounds=(1e-4, 1.0),
    )
    # A healthy reel overshot a reel-in's stop by 11 mm (campaign draw seed 1802160804): the
    # reel's commands may brake harder than its 5 m/s^2; a locked reel shows as stuck anyway.
    envelope_margin_m: float = parameter_field(
        0.05,
        "the tether this far outside its commands does not follow them [m]",
        bounds=(1e-4, 1.0),
    )

    # The servos' lag and latency (their datasheet: Scenario.robot_errors sets them, as it
    # sets the controller's); 0: servos that follow their commands at once.
    servo_lag_s: float = parameter_field(
        0.0, "the servos' first-order lag (time constant) [s]", bounds=(0.0, 1.0)
    )
    servo_latency_s: float = parameter_field(
        0.0, "the servos' command latency [s]", bounds=(0.0, 0.5)
    )
    servo_tolerance: float = parameter_field(
        0.25,
        "the servos' lag and latency are known within this fraction [-]",
        bounds=(0.0, 0.9),
    )
    # Healthy limb joints stay within 0.9 mrad of the servo models without lag or latency
    # (60 nominal tumbles: the servos' acceleration limit at velocity steps), within 8.7
    # mrad with 50 ms lag and 20 ms latency (30 tumbles with robot errors: the servos trail
    # their lagged targets at their acceleration limit); graph_config sets 0.03 then.
    residual_margin_rad: float = parameter_field(
        0.01,
        "a moving limb joint this far outside where the servo models are does not "
        "follow its commands [rad]",
        bounds=(1e-4, 1.0),
    )
    residual_margin_m: float = parameter_field(
        0.05,
        "a moving tether this far outside where the servo models are does not follow "
        "its commands [m]",
        bounds=(1e-4, 1.0),
    )

    def __post_init__(self) -> None:
        for still, asked in (("still_rad", "stuck_error_rad"), ("still_m", "stuck_error_m")):
            if not getattr(self, still) < getattr(self, asked):
                raise ValueError(
                    f"'{still}' ({getattr(self, still):g}) must be below '{asked}' "
                    f"({getattr(self, asked):g}): a joint asked to move must be able to "
                    "show it has not"
                )

    def per_joint(self, limb: float, tether: float) -> NDArray[np.float64]:
        """A threshold per joint (25): ``limb`` for the limb joints, ``tether`` for the tether."""
        out = np.full(N_JOINTS, float(limb))
        out[TETHER_INDEX] = float(tether)
        return out


@dataclass(frozen=True)
class Detection:
    """A joint found faulty: which, what it showed, when [ns]."""

    joint: int
    symptom: str
    t_ns: int

    @property
    def joint_name(self) -> str:
        return JOINT_NAMES[self.joint]


class ServoModel:
    """Where a servo with a command latency and a first-order lag would be.

    As the simulated robot's (:class:`splitter_model.actuators.CommandLag`, the
    latency of ``splitter_sim.core.tick``): each command reaches the servo
    ``latency_s`` after its stamp, through the lag on its position and velocity
    (the first passes through), and is followed at its velocity from its stamp for up
    to the extrapolation time.
    """

    def __init__(self, lag_s: float, latency_s: float) -> None:
        self.lag_s = float(lag_s)  # [s]
        self.latency_ns = round(latency_s * 1e9)  # [ns]
        self._pending: deque[tuple[int, NDArray[np.float64], NDArray[np.float64]]] = deque()
        self._followed: tuple[int, NDArray[np.float64], NDArray[np.float64]] | None = None
        self._before: tuple[int, NDArray[np.float64], NDArray[np.float64]] | None = None

    def on_command(
        self, t_ns: int, position: NDArray[np.float64], velocity: NDArray[np.float64]
    ) -> None:
        """A command stamped ``t_ns``: position and velocity (25 each)."""
        pending = self._pending
        while pending and pending[-1][0] >= t_ns:  # a repeated stamp replaces
            pending.pop()
        pending.append((t_ns, position, velocity))

    def targets(
        self, t_ns: int, extrapolation_s: float, start: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The servo's target at ``t_ns`` and the one before it (25 each): a servo that
        follows its targets at a limited acceleration is between the two (``start``:
        where it holds before any command)."""
        pending = self._pending
        while pending and pending[0][0] + self.latency_ns <= t_ns:
            stamp, q, v = pending.popleft()
            last = self._followed
            self._before = last
            if last is None or self.lag_s <= 0.0:
                self._followed = (stamp, q, v)
            else:
                gain = -math.expm1(-max(stamp - last[0], 0) * 1e-9 / self.lag_s)
                self._followed = (
                    stamp,
                    last[1] + gain * (q - last[1]),
                    last[2] + gain * (v - last[2]),
                )
        now = _followed_at(self._followed, t_ns, extrapolation_s, start)
        return now, _followed_at(self._before, t_ns, extrapolation_s, now)


def _followed_at(
    followed: tuple[int, NDArray[np.float64], NDArray[np.float64]] | None,
    t_ns: int,
    extrapolation_s: float,
    default: NDArray[np.float64],
) -> NDArray[np.float64]:
    if followed is None:
        return default
    stamp, q, v = followed
    return q + v * min(max(t_ns - stamp, 0) * 1e-9, extrapolation_s)


class JointHealthMonitor:
    """Watches the commands sent and the joint states measured; reports faulty joints.

    Call :meth:`on_command` with every joint command (its stamp and positions) and
    :meth:`on_measurement` with every joint state; the latter returns the joints
    newly found faulty. ``enabled`` False: it watches and reports nothing (the
    handling switched off, for comparison).
    """

    def __init__(self, config: JointHealthConfig | None = None, enabled: bool = True) -> None:
        self.config = config or JointHealthConfig()
        self.enabled = bool(enabled)
        c = self.config
        self._still = c.per_joint(c.still_rad, c.still_m)
        self._stuck_error = c.per_joint(c.stuck_error_rad, c.stuck_error_m)
        self._margin = c.per_joint(c.envelope_margin_rad, c.envelope_margin_m)
        self._residual_margin = c.per_joint(c.residual_margin_rad, c.residual_margin_m)
        # the servos as configured, at the ends of their tolerance
        self._servos = [
            ServoModel(lag_s, latency_s)
            for lag_s, latency_s in sorted(
                {
                    (c.servo_lag_s * lag, c.servo_latency_s * latency)
                    for lag in (1.0 - c.servo_tolerance, 1.0 + c.servo_tolerance)
                    for latency in (1.0 - c.servo_tolerance, 1.0 + c.servo_tolerance)
                }
            )
        ]
        # (stamp, position, velocity) of the commands sent
        # (stamp [ns], position, velocity, low, high): low/high bound the command and
        # where its velocity takes it within command_extrapolation_s (kept, not recomputed
        # at every measurement)
        self._commands: deque[tuple[int, _Joints, _Joints, _Joints, _Joints]] = deque()
        self._measured: deque[tuple[int, NDArray[np.float64]]] = deque()
        self._detections: dict[int, Detection] = {}
        self._found_at: dict[int, float] = {}  # where each stuck joint was found
        self._off_at = np.full(N_JOINTS, np.nan)  # where each joint went off the servo models
        # since when each joint has shown "not following" without a break (-1: it has not)
        self._wandering_since_ns = np.full(N_JOINTS, -1, dtype=np.int64)

    @property
    def detections(self) -> tuple[Detection, ...]:
        """Every joint found faulty so far, in the order found."""
        return tuple(self._detections.values())

    @property
    def symptoms(self) -> dict[int, str]:
        """The symptom of every joint found faulty (a stuck one that moved since: not following)."""
        return {j: d.symptom for j, d in self._detections.items()}

    @property
    def faulty_joints(self) -> frozenset[int]:
        """Indices (``JOINT_NAMES`` order) of the joints found faulty."""
        return frozenset(self._detections)

    def on_command(self, t_ns: int, position: ArrayLike, velocity: ArrayLike | None = None) -> None:
        """A joint command stamped ``t_ns`` [ns]: positions (25) and velocities (25)."""
        q = np.asarray(position, dtype=float).reshape(N_JOINTS)
        v = np.zeros(N_JOINTS) if velocity is None else np.asarray(velocity, dtype=float)
        commands = self._commands
        while commands and commands[-1][0] >= t_ns:  # a repeated stamp replaces
            commands.pop()
        q, v = q.copy(), v.reshape(N_JOINTS).copy()  # never changed once kept
        ahead = q + v * self.config.command_extrapolation_s
        low, high = (np.minimum(q, ahead), np.maximum(q, ahead)) if v.any() else (q, q)
        commands.append((int(t_ns), q, v, low, high))
        for servo in self._servos if self.enabled else ():
            servo.on_command(int(t_ns), commands[-1][1], commands[-1][2])
        horizon = int(t_ns) - self._keep_ns()
        while len(commands) > 1 and commands[1][0] <= horizon:
            commands.popleft()

    def _keep_ns(self) -> int:
        c = self.config
        longest = max(c.envelope_window_s, c.stuck_window_s + c.command_delay_s)
        return round((longest + c.command_delay_s) * 1e9)

    def on_measurement(self, t_ns: int, position: ArrayLike) -> list[Detection]:
        """Joint positions (25) measured at ``t_ns`` [ns]; the joints newly found faulty."""
        q = np.asarray(position, dtype=float).reshape(N_JOINTS)
        if not np.all(np.isfinite(q)):
            raise ValueError("joint positions must be finite")
        measured = self._measured
        measured.append((int(t_ns), q.copy()))
        horizon = int(t_ns) - self._keep_ns()
        while len(measured) > 1 and measured[1][0] <= horizon:
            measured.popleft()
        if not self.enabled or not self._commands:
            return []
        found = np.zeros(N_JOINTS, dtype=bool)
        symptom = np.full(N_JOINTS, "", dtype=object)
        stuck = self._stuck(int(t_ns), q)
        found |= stuck
        symptom[stuck] = STUCK
        wandering = (
            self._outside_commands(int(t_ns), q)
            | self._off_model(int(t_ns), q)
            | self._drifting(int(t_ns), q)
        ) & ~found
        # for half a stuck window without a break: one stray sample (a glitch, a joint
        # state from elsewhere) is not a fault
        since = self._wandering_since_ns
        since[wandering & (since < 0)] = int(t_ns)
        since[~wandering] = -1
        wandering &= int(t_ns) - since >= round(self.config.stuck_window_s * 0.5e9)
        found |= wandering
        symptom[wandering] = NOT_FOLLOWING
        new = []
        for j in np.flatnonzero(found).tolist():
            if j not in self._detections:
                detection = Detection(j, str(symptom[j]), int(t_ns))
                self._detections[j] = detection
                self._found_at[j] = float(q[j])
                new.append(detection)
        for j, detection in list(self._detections.items()):
            if detection.symptom == STUCK and abs(q[j] - self._found_at[j]) > self._margin[j]:
                self._detections[j] = Detection(j, NOT_FOLLOWING, detection.t_ns)
        return new

    def _command_at(self, t_ns: int) -> NDArray[np.float64] | None:
        """Where the command in force at ``t_ns`` (the last stamped at or before it) is then."""
        commands = self._commands
        k = bisect.bisect_right(commands, t_ns, key=lambda c: c[0]) - 1
        if k < 0:
            return None
        stamp, q, v, _, _ = commands[k]
        return q + v * min((t_ns - stamp) * 1e-9, self.config.command_extrapolation_s)

    def _stuck(self, t_ns: int, q: NDArray[np.float64]) -> NDArray[np.bool_]:
        c = self.config
        start = t_ns - round(c.stuck_window_s * 1e9)
        samples = [(t, m) for t, m in self._measured if t >= start]
        if not samples or samples[0][0] > start + round(0.25 * c.stuck_window_s * 1e9):
            return np.zeros(N_JOINTS, dtype=bool)  # not yet a window of measurements
        delay_ns = round(c.command_delay_s * 1e9)
        none = np.zeros(N_JOINTS, dtype=bool)
        latest = self._command_at(t_ns - delay_ns)
        if latest is None:
            return none
        suspects = np.abs(latest - q) > self._stuck_error  # asked to move now
        if suspects.any():
            measured = np.stack([m for _, m in samples])
            suspects &= np.all(np.abs(measured - q) <= self._still, axis=0)  # and still
        if not suspects.any():
            return none
        first_error = None
        for t, m in samples:
            command = self._command_at(t - delay_ns)
            if command is None:
                return none
            error = np.abs(command - m)
            suspects &= error > self._stuck_error
            first_error = error if first_error is None else first_error
        # a command coming to where the joint waits (a joint that got to its range end
        # ahead of it) does not ask it to move: the error must not have shrunk
        return suspects & (error >= first_error)

    def _off_model(self, t_ns: int, q: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Joints that moved where no servo of the configured lag and latency would go.

        A joint is off the servo models (:class:`ServoModel`, at the ends of the
        tolerance) when it is farther than ``residual_margin`` outside their range; it
        does not follow its commands once it has also moved by more than ``still`` since
        it went off (a joint locked while moving stops there: the stuck test's).
        """
        if not self._commands:
            return np.zeros(N_JOINTS, dtype=bool)
        reach = self.config.command_extrapolation_s
        predicted = np.concatenate([servo.targets(t_ns, reach, q) for servo in self._servos])
        low, high = predicted.min(axis=0), predicted.max(axis=0)
        off = (q < low - self._residual_margin) | (q > high + self._residual_margin)
        went_off = off & np.isnan(self._off_at)
        self._off_at[went_off] = q[went_off]
        self._off_at[~off] = np.nan
        return off & (np.abs(q - self._off_at) > self._still)

    def _drifting(self, t_ns: int, q: NDArray[np.float64]) -> NDArray[np.bool_]:
        """Joints moving away from a command that stands still (a limp joint creeping).

        For a start ``s`` between ``envelope_window_s`` and ``stuck_window_s`` ago: every
        command in force since ``s - command_delay_s`` stayed within ``still`` of the
        others, the joint is farther than ``stuck_error`` from it now, and farther by more
        than ``still`` than it was at ``s``. A servo, whatever its lag, only closes the
        error to a command that stands still.
        """
        c = self.config
        none = np.zeros(N_JOINTS, dtype=bool)
        target = self._command_at(t_ns)
        if target is None:
            return none
        error_now = np.abs(target - q)
        suspects = error_now > self._stuck_error
        if not suspects.any():
            return none
        latest_start = t_ns - round(c.stuck_window_s * 1e9)
        earliest_start = t_ns - round(c.envelope_window_s * 1e9)
        starts = [(t, m) for t, m in self._measured if earliest_start <= t <= latest_start]
        delay_ns = round(c.command_delay_s * 1e9)
        commands = self._commands
        k = len(commands) - 1
        low, high = target.copy(), target.copy()  # the range of the commands since s - delay
        drifting = np.zeros(N_JOINTS, dtype=bool)
        for s_ns, m in reversed(starts):
            since = s_ns - delay_ns
            while k >= 0 and commands[k][0] > since:
                _, _, _, c_low, c_high = commands[k]
                low, high = np.minimum(low, c_low), np.maximum(high, c_high)
                k -= 1
            before = self._command_at(since)
            if before is None:
                break
            low, high = np.minimum(low, before), np.maximum(high, before)
            still_command = (high - low) <= self._still
            if not (still_command & suspects).any():
                break  # older starts only widen the range
            drifting |= still_command & (error_now > np.abs(target - m) + self._still)
        return suspects & drifting

    def _outside_commands(self, t_ns: int, q: NDArray[np.float64]) -> NDArray[np.bool_]:
        c = self.config
        start = t_ns - round(c.envelope_window_s * 1e9)
        commands = self._commands
        if not commands or commands[0][0] > start:
            return np.zeros(N_JOINTS, dtype=bool)  # less than a window of commands yet
        first = bisect.bisect_left(commands, start, key=lambda command: command[0])
        recent = list(itertools.islice(commands, first, None))
        lows = [command[3] for command in recent]
        highs = [command[4] for command in recent]
        before = self._command_at(start)
        if before is not None:
            lows.append(before)
            highs.append(before)
        low, high = np.min(lows, axis=0), np.max(highs, axis=0)
        return (q < low - self._margin) | (q > high + self._margin)
