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
* **not following** (a limp joint swinging, a runaway): the joint is farther than
  ``envelope_margin`` outside the range of the commands of the last
  ``envelope_window_s``.

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
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.joints import JOINT_NAMES, N_JOINTS, TETHER_INDEX
from splitter_msgs_py.core.parameter_fields import parameter_field

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
        # (stamp, position, velocity) of the commands sent
        self._commands: deque[tuple[int, NDArray[np.float64], NDArray[np.float64]]] = deque()
        self._measured: deque[tuple[int, NDArray[np.float64]]] = deque()
        self._detections: dict[int, Detection] = {}
        self._found_at: dict[int, float] = {}  # where each stuck joint was found

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
        commands.append((int(t_ns), q.copy(), v.reshape(N_JOINTS).copy()))
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
        wandering = self._outside_commands(int(t_ns), q) & ~found
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
        stamp, q, v = commands[k]
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

    def _outside_commands(self, t_ns: int, q: NDArray[np.float64]) -> NDArray[np.bool_]:
        c = self.config
        start = t_ns - round(c.envelope_window_s * 1e9)
        reach = self.config.command_extrapolation_s
        recent = [(q, v) for stamp, q, v in self._commands if stamp >= start]
        window = [q for q, _ in recent] + [q + v * reach for q, v in recent if v.any()]
        before = self._command_at(start)
        if before is not None:
            window.append(before)
        if not window or self._commands[0][0] > start:
            return np.zeros(N_JOINTS, dtype=bool)  # less than a window of commands yet
        stacked = np.stack(window)
        low, high = stacked.min(axis=0), stacked.max(axis=0)
        return (q < low - self._margin) | (q > high + self._margin)
