"""The allocator's control tick: inputs, stamp rules, hold, fallback, lead, diagnostics. ROS-free.

:class:`AllocatorTick` is what the ``ik_tether_allocator`` node runs (it turns
messages into these calls and the returned :class:`TickOutput` into messages) and
what the library closed loop drives (:meth:`AllocatorTick.lockstep_tick`), so
both answer a tick with the same objects and the same numbers.

* A setpoint stamped ``t`` is answered with joint commands
  (:class:`~splitter_ik.core.allocator.Allocation`, one per control period): stamped
  ``t`` in lockstep, ahead by the latency measured with the command lead
  (:class:`~splitter_ik.core.command_lead.CommandLead`), the body rate then predicted
  at the command's stamp from the inertia planned when it was measured.
* The IMU gives the body rate for the taut-tether limit, and its specific force
  whether that limit applies (free fall) or the robot has been held by its feet for
  ``supported_dwell_s``.
* The first measured inertia sets the starting radii
  (``initialize_from_measured_inertia``); while nothing publishes setpoints
  (``publishers``), each control tick of it is answered from the held setpoint
  (``answer_state_without_setpoints``), once the IMU of that tick is in.
* The held setpoint is the last good one, else the inertia of the radii commanded.

Stamp rules (:attr:`AllocatorTick.stamps`, a :class:`StampGate`): never backwards on
a topic, never far ahead of the node's time, and a setpoint never before the last
tick answered (:meth:`AllocatorTick.not_before_ns`). Content rules: a setpoint is
``base``-framed, finite, each moment in ``(0, max_setpoint_kg_m2]``
(``SETPOINT_LIMIT_FACTOR`` times the largest reachable moment), else its tick is
answered from the held setpoint; an IMU body rate is ``base``-framed, finite and
below ``MAX_BODY_RATE_RAD_S``, else the last good one is kept. Every rejection is
counted in the diagnostics window (:class:`DiagnosticsWindow`), which closes once
per ``diagnostics_period_s`` of the ticks' stamps; :meth:`AllocatorTick.status` is
its level, message and values.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_ik.core.allocator import Allocation, AllocatorConfig, TetherLimbAllocator
from splitter_ik.core.command_lead import CommandLead, CommandLeadConfig
from splitter_ik.core.joint_health import (
    NOT_FOLLOWING,
    Detection,
    JointHealthConfig,
    JointHealthMonitor,
)
from splitter_ik.core.projection import project_inertia, reachable_inertia_bounds
from splitter_model.actuators import TETHER_INDEX
from splitter_model.joints import JOINT_NAMES
from splitter_model.model import (
    PAPER_INITIAL_RADII_M,
    RobotModel,
    angular_velocity_after_morphing,
    principal_inertia,
)
from splitter_model.redundancy import RemainingShape, remaining_shape
from splitter_msgs_py import names
from splitter_msgs_py.core.latency import InputLatency
from splitter_msgs_py.core.parameter_fields import parameter_field
from splitter_msgs_py.core.stamps import MAX_STAMP_LEAD_NS, StampGate, refusal_answers_tick

_LOG = logging.getLogger(__name__)
# [-] a setpoint moment above this many times the largest reachable moment of the model
# (163 kg m^2 for the paper's robot) is corrupt, not merely unreachable: rejected.
SETPOINT_LIMIT_FACTOR = 10.0
# [rad/s] an IMU body rate above this is corrupt (the robot spins at ~1 rad/s, its
# joints at 84 rad/s; a gyro saturates far below): rejected.
MAX_BODY_RATE_RAD_S = 1.0e3
# [m/s^2] an IMU specific force above this is corrupt (a 196 N landing on a 9 kg hemi
# is 22 m/s^2; accelerometers saturate at 16 G): rejected.
MAX_SPECIFIC_FORCE_M_S2 = 1.0e3
LEAD_HISTORY_NS = 1_000_000_000  # [ns] planned inertia kept for the rate prediction
Values = dict[str, float | int | str | bool]


@dataclass(frozen=True)
class AllocatorTickSettings:
    """How the tick starts, holds and reports (node parameters besides the allocator's)."""

    initial_radii_m: tuple[float, ...] = parameter_field(  # [m]
        tuple(float(v) for v in PAPER_INITIAL_RADII_M),
        "r_x, r_y, r_z the commands start from when no measured inertia came first [m]",
        bounds=(0.0, 100.0),
        length=3,
    )
    initialize_from_measured_inertia: bool = parameter_field(
        True, "start from the radii of the first /splitter/inertia (projected) if it comes first"
    )
    answer_state_without_setpoints: bool = parameter_field(
        True,
        "while no node publishes setpoints, answer each control tick of /splitter/inertia "
        "from the last good setpoint (lockstep keeps running)",
    )
    diagnostics_period_s: float = parameter_field(  # [s]
        0.1, "diagnostics period in simulated time [s]", bounds=(1e-3, 100.0), live=True
    )
    fault_handling: bool = parameter_field(
        True,
        "detect faulty joints from /splitter/joint_states against the commands and re-plan "
        "with what remains (splitter_ik.core.joint_health, splitter_model.redundancy); "
        "false: watch nothing, plan as if every joint worked",
    )


@dataclass
class DiagnosticsWindow:
    """What happened since the last diagnostics message."""

    answered: int = 0
    fallback: int = 0
    saturated: int = 0
    rate_limited: int = 0
    rejected: int = 0
    max_saturation: float = 0.0  # [kg m^2]
    min_margin: float = math.inf  # [N]
    max_joint_speed: float = 0.0  # [rad/s]
    max_tether_speed: float = 0.0  # [m/s]


class AllocatorStatus(NamedTuple):
    """A diagnostics status as plain data: level 0 (OK) or 1 (WARN), message, values."""

    level: int
    message: str
    values: Values


@dataclass(frozen=True)
class TickOutput:
    """What one input did: commands to publish (each stamped its ``t_ns``), in order."""

    commands: tuple[Allocation, ...] = ()
    rejected: str | None = None  # why the input's content was refused (counted)
    refused: str | None = None  # the allocator refused a command: the tick is not answered
    answered_ns: int | None = None  # [ns] the input tick answered
    closed_window: DiagnosticsWindow | None = None  # diagnostics due, stamped answered_ns


def _no_clock() -> int | None:
    return None


def _frame_refusal(frame_id: str) -> str | None:
    """Why an input in ``frame_id`` is refused (None: it is in ``base``)."""
    if frame_id == names.BASE_FRAME:
        return None
    return f"header.frame_id: expected '{names.BASE_FRAME}', got {frame_id!r}"


class AllocatorTick:
    """The allocator node's state and rules; see the module doc.

    ``config``, ``settings`` and ``lead`` default to their dataclasses' defaults.
    ``clock_ns`` gives the node's simulated time (None: no clock, latency 0);
    ``publishers(topic)`` how many nodes publish ``topic`` (None: setpoints and
    IMU are published, so measured-inertia ticks are never answered from the hold).
    """

    def __init__(
        self,
        model: RobotModel,
        config: AllocatorConfig | None = None,
        settings: AllocatorTickSettings | None = None,
        lead: CommandLeadConfig | None = None,
        *,
        health: JointHealthConfig | None = None,
        clock_ns: Callable[[], int | None] = _no_clock,
        publishers: Callable[[str], int] | None = None,
    ) -> None:
        config = config or AllocatorConfig()
        settings = settings or AllocatorTickSettings()
        radii = np.array(settings.initial_radii_m, dtype=float)
        lo, hi = model.radii_min_m, model.radii_max_m
        if radii.shape != (3,) or np.any(radii < lo) or np.any(radii > hi):
            raise ValueError(
                f"'initial_radii_m' {radii.tolist()} must lie within "
                f"{np.round(lo, 4).tolist()} .. {np.round(hi, 4).tolist()} m "
                "(tether length and knee range)"
            )
        self.model = model
        self.allocator: TetherLimbAllocator | None = None
        self.period_ns = round(config.control_period_s * 1e9)
        self.lead = CommandLead(self.period_ns)
        self.configure(config, settings, lead or CommandLeadConfig())
        self.latency = InputLatency()  # simulated clock at use - stamp, per input
        self.stamps = StampGate(MAX_STAMP_LEAD_NS)
        self.max_setpoint_kg_m2 = SETPOINT_LIMIT_FACTOR * float(
            np.max(reachable_inertia_bounds(model)[1])
        )
        self.last_allocation: Allocation | None = None
        self.last_good_setpoint: NDArray[np.float64] | None = None
        self.angular_velocity: NDArray[np.float64] | None = None  # [rad/s] last good
        self.specific_force: NDArray[np.float64] | None = None  # [m/s^2] last good, body
        self._supported_since_ns: int | None = None  # [ns] the support began (None: none)
        self.imu_t_ns: int | None = None
        self.answered_ns: int | None = None  # the last input tick answered
        self.window = DiagnosticsWindow()
        self._initial_radii = radii
        self._clock_ns = clock_ns
        self._publishers = publishers
        self._pending_fallback_ns: int | None = None
        self._last_command_ns: int | None = None
        self._last_diagnostics_ns: int | None = None
        # [kg m^2] inertia the commands plan at their stamps (the last second), to
        # predict the body rate at a command stamped ahead of its input
        self._planned_inertia: dict[int, NDArray[np.float64]] = {}
        self.health = JointHealthMonitor(health, enabled=settings.fault_handling)
        self.remaining: RemainingShape | None = None  # what a fault left, once detected

    def configure(
        self, config: AllocatorConfig, settings: AllocatorTickSettings, lead: CommandLeadConfig
    ) -> None:
        """Settings changed at runtime (the live ones), applied from the next tick on."""
        self.config, self.settings, self.lead_config = config, settings, lead
        if self.allocator is not None:
            self.allocator.config = config
        self._diagnostics_ns = round(settings.diagnostics_period_s * 1e9)
        self.lead.configure(lead)

    # --- inputs ----------------------------------------------------------------------
    def not_before_ns(self, topic: str) -> int | None:
        """The earliest stamp ``topic`` may carry besides the gate's rules (a setpoint
        answers a tick: never one before the last tick answered)."""
        return self.answered_ns if topic == names.INERTIA_SETPOINT else None

    def count_rejected(self) -> None:
        """An input refused for its stamp (by :attr:`stamps`): counted, nothing changed."""
        self.window.rejected += 1

    def rejected(self, topic: str, t_ns: int, reason: str) -> TickOutput:
        """An input of ``t_ns`` refused for its content: counted; a setpoint's tick is
        answered from the held setpoint while the MPC is the topic's one publisher
        (:func:`refusal_answers_tick`), any other input changes nothing."""
        self.window.rejected += 1
        publishers = None if self._publishers is None else self._publishers(topic)
        if topic != names.INERTIA_SETPOINT or not refusal_answers_tick(publishers):
            return TickOutput(rejected=reason)
        return dataclasses.replace(self._answer(t_ns, self._hold_setpoint()), rejected=reason)

    def setpoint(
        self, t_ns: int, inertia_kg_m2: ArrayLike, frame_id: str = names.BASE_FRAME
    ) -> TickOutput:
        """The inertia setpoint [kg m^2] stamped ``t_ns`` (admitted), answered."""
        setpoint = np.asarray(inertia_kg_m2, dtype=float)
        limit = self.max_setpoint_kg_m2
        reason = _frame_refusal(frame_id)
        if reason is None and not np.all((setpoint > 0.0) & (setpoint <= limit)):  # NaN too
            reason = f"vector: moments must be in (0, {limit:.4g}] kg m^2, got {setpoint.tolist()}"
        if reason is not None:
            return self.rejected(names.INERTIA_SETPOINT, t_ns, reason)
        self.last_good_setpoint = setpoint
        return self._answer(t_ns, setpoint)

    def imu(
        self,
        t_ns: int,
        angular_velocity_rad_s: ArrayLike,
        frame_id: str = names.BASE_FRAME,
        specific_force_m_s2: ArrayLike | None = None,
    ) -> TickOutput:
        """The body rate [rad/s] and specific force [m/s^2] stamped ``t_ns`` (admitted);
        answers a tick it completes. Without a specific force the robot is taken to be
        in free fall (the taut-tether limits apply)."""
        w = np.array(angular_velocity_rad_s, dtype=float)
        f = None if specific_force_m_s2 is None else np.array(specific_force_m_s2, dtype=float)
        reason = _frame_refusal(frame_id)
        if reason is None and not np.all(np.abs(w) <= MAX_BODY_RATE_RAD_S):  # NaN too
            reason = f"angular_velocity: {w.tolist()} rad/s beyond {MAX_BODY_RATE_RAD_S:g} rad/s"
        if reason is None and f is not None and not np.all(np.abs(f) <= MAX_SPECIFIC_FORCE_M_S2):
            reason = (
                f"linear_acceleration: {f.tolist()} m/s^2 beyond {MAX_SPECIFIC_FORCE_M_S2:g} m/s^2"
            )
        if reason is not None:
            return self.rejected(names.IMU, t_ns, reason)
        self.angular_velocity, self.specific_force, self.imu_t_ns = w, f, t_ns
        if f is None or float(np.linalg.norm(f)) <= self.config.supported_specific_force_m_s2:
            self._supported_since_ns = None
        elif self._supported_since_ns is None:
            self._supported_since_ns = t_ns
        if self._pending_fallback_ns is not None and self._pending_fallback_ns == t_ns:
            return self._answer_fallback(t_ns)
        return TickOutput()

    def measured_inertia(self, t_ns: int, inertia_kg_m2: ArrayLike) -> TickOutput:
        """The measured principal inertia [kg m^2] stamped ``t_ns`` (admitted, validated)."""
        if self.allocator is None and self.settings.initialize_from_measured_inertia:
            self._ensure_allocator(project_inertia(self.model, inertia_kg_m2).radii_m)
        published = self._publishers
        if (
            not self.settings.answer_state_without_setpoints
            or t_ns % self.period_ns != 0
            or published is None
            or published(names.INERTIA_SETPOINT) > 0
        ):
            return TickOutput()
        if published(names.IMU) == 0 or self.imu_t_ns == t_ns:
            return self._answer_fallback(t_ns)
        self._pending_fallback_ns = t_ns  # answered when the IMU of this tick arrives
        return TickOutput()

    def lockstep_tick(
        self,
        t_ns: int,
        measured_inertia_kg_m2: ArrayLike,
        angular_velocity_rad_s: ArrayLike,
        setpoint_kg_m2: ArrayLike,
        specific_force_m_s2: ArrayLike | None = None,
    ) -> TickOutput:
        """One control tick as the node receives it in lockstep (the library loop's call):
        the IMU (body rate, specific force) and the measured inertia of ``t_ns``, then
        the setpoint stamped ``t_ns``.

        A stamp the rules refuse raises ``MessageValidationError``; a refused content is
        logged and handled as the node does.
        """
        for topic in (names.IMU, names.INERTIA, names.INERTIA_SETPOINT):
            self.stamps.admit(topic, t_ns, self._clock_ns, self.not_before_ns(topic))
        outputs = (
            self.imu(t_ns, angular_velocity_rad_s, specific_force_m_s2=specific_force_m_s2),
            self.measured_inertia(t_ns, measured_inertia_kg_m2),
            self.setpoint(t_ns, setpoint_kg_m2),
        )
        for out in outputs:
            if out.rejected is not None or out.refused is not None:
                _LOG.warning("t = %.3f s: %s", t_ns * 1e-9, out.rejected or out.refused)
        return outputs[-1]

    def joint_states(self, t_ns: int, position: ArrayLike) -> list[Detection]:
        """Measured joint positions (25) at ``t_ns``: the joints newly found faulty.

        After a detection the allocator re-plans with what remains (held limbs where
        these positions have them, from every call on).
        """
        q = np.asarray(position, dtype=float)
        new = self.health.on_measurement(t_ns, q)
        faulty = self.health.faulty_joints
        if faulty:
            moving = [j for j, s in self.health.symptoms.items() if s == NOT_FOLLOWING]
            self.remaining = remaining_shape(self.model, faulty, q, moving)
            self._ensure_allocator().set_remaining(self.remaining, q)
        for detection in new:
            _LOG.warning(
                "t = %.3f s: joint %s is faulty (%s): re-planning without it",
                t_ns * 1e-9,
                detection.joint_name,
                detection.symptom,
            )
        return new

    @property
    def supported(self) -> bool:
        """The IMU says the robot is held by more than its tether (feet on the ground):
        its specific force has been above ``supported_specific_force_m_s2`` for
        ``supported_dwell_s``, up to the last good reading."""
        since, now = self._supported_since_ns, self.imu_t_ns
        if since is None or now is None:
            return False
        return now - since >= round(self.config.supported_dwell_s * 1e9)

    # --- answering -------------------------------------------------------------------
    def _ensure_allocator(self, radii: ArrayLike | None = None) -> TetherLimbAllocator:
        if self.allocator is None:
            start = self._initial_radii if radii is None else radii
            self.allocator = TetherLimbAllocator(self.model, self.config, start)
        return self.allocator

    def _hold_setpoint(self) -> NDArray[np.float64]:
        """The last good setpoint, or the inertia of the radii commanded now."""
        if self.last_good_setpoint is not None:
            return self.last_good_setpoint
        radii = self._ensure_allocator().radii_m
        return principal_inertia(self.model, radii if radii is not None else self._initial_radii)

    def _answer_fallback(self, t_ns: int) -> TickOutput:
        self._pending_fallback_ns = None
        if self.answered_ns is not None and self.answered_ns >= t_ns:
            return TickOutput()  # that tick is answered (or past): a late state changes nothing
        self.window.fallback += 1
        return self._answer(t_ns, self._hold_setpoint())

    def _answer(self, t_ns: int, setpoint: NDArray[np.float64]) -> TickOutput:
        """Answer the input tick ``t_ns``: one command per control period it covers."""
        now = self._clock_ns()
        self.latency.record("inertia_setpoint", t_ns, now)
        if self.lead_config.command_lead:
            self.lead.record(t_ns, now)
            stamps = self.lead.output_stamps(t_ns, self._last_command_ns)
        else:
            stamps = [t_ns]
        commands = []
        for stamp in stamps:
            try:  # stamps were checked (never before the last tick), the setpoint validated
                commands.append(self._command(stamp, setpoint, t_ns))
            except ValueError as exc:  # nothing more sent, the allocator's state kept
                reason = f"t = {stamp * 1e-9:.3f} s: tick not answered, the allocator refused it"
                return TickOutput(tuple(commands), refused=f"{reason}: {exc}")
        self.answered_ns = t_ns
        return TickOutput(tuple(commands), answered_ns=t_ns, closed_window=self._close(t_ns))

    def _rate_at(self, t_ns: int, input_t_ns: int) -> NDArray[np.float64] | None:
        """The last body rate measured, predicted for a command stamped ``t_ns``.

        Lockstep (a command stamped with its input) and before any lead: as measured.
        """
        w, allocator = self.angular_velocity, self.allocator
        if w is None or t_ns == input_t_ns or allocator is None or allocator.radii_m is None:
            return w
        measured_t = self.imu_t_ns or 0
        then = self._planned_inertia.get(measured_t - measured_t % self.period_ns)
        if then is None:
            return w
        return angular_velocity_after_morphing(
            w, then, principal_inertia(self.model, allocator.radii_m)
        )

    def _command(self, t_ns: int, setpoint: NDArray[np.float64], setpoint_t_ns: int) -> Allocation:
        allocator = self._ensure_allocator()
        allocation = allocator.allocate(
            t_ns,
            setpoint,
            self._rate_at(t_ns, setpoint_t_ns),
            setpoint_t_ns,
            supported=self.supported,
        )
        self.last_allocation = allocation
        self._last_command_ns = t_ns
        self.health.on_command(t_ns, allocation.joint_position, allocation.joint_velocity)
        if self.lead.lead_ns > 0:
            planned = self._planned_inertia
            planned[t_ns] = allocation.achieved_inertia_kg_m2
            for old in [t for t in planned if t < t_ns - LEAD_HISTORY_NS]:
                del planned[old]
        self._account(allocation)
        return allocation

    # --- diagnostics -----------------------------------------------------------------
    def _account(self, a: Allocation) -> None:
        w = self.window
        w.answered += 1
        w.saturated += int(a.saturated)
        w.rate_limited += int(a.rate_limited)
        if a.saturated:  # distance from the request to the reachable set
            projected = project_inertia(self.model, a.requested_inertia_kg_m2)
            saturation = float(np.linalg.norm(projected.saturation_kg_m2))
            w.max_saturation = max(w.max_saturation, saturation)
        if math.isfinite(a.tension_margin_n):
            w.min_margin = min(w.min_margin, a.tension_margin_n)
        w.max_joint_speed = max(
            w.max_joint_speed, float(np.max(np.abs(a.joint_velocity[:TETHER_INDEX])))
        )
        w.max_tether_speed = max(w.max_tether_speed, abs(float(a.joint_velocity[TETHER_INDEX])))

    def _close(self, t_ns: int) -> DiagnosticsWindow | None:
        """The window, closed when ``t_ns`` starts a new diagnostics period (else None)."""
        last, period = self._last_diagnostics_ns, self._diagnostics_ns
        if last is not None and t_ns // period == last // period:
            return None
        self._last_diagnostics_ns = t_ns
        closed, self.window = self.window, DiagnosticsWindow()
        return closed

    def status(
        self, window: DiagnosticsWindow | None = None, extra: Mapping[str, object] | None = None
    ) -> AllocatorStatus:
        """The status of ``window`` (default: the open one) with ``extra`` values (the node's
        warning counts and parameter changes) after the latencies."""
        w, a = self.window if window is None else window, self.last_allocation
        values: Values = {
            "ticks_answered": w.answered,
            "ticks_answered_without_setpoint": w.fallback,
            "setpoints_rejected": w.rejected,
            "setpoints_projected": w.saturated,
            "ticks_rate_limited": w.rate_limited,
            "max_saturation_kg_m2": w.max_saturation,
            "max_limb_joint_speed_rad_s": w.max_joint_speed,
            "max_tether_speed_m_s": w.max_tether_speed,
            "tension_margin_setting_n": self.config.tension_margin_n,
            "command_lead_ms": self.lead.lead_ns * 1e-6,
            **self.latency.values(),
            **(extra or {}),  # type: ignore[dict-item]
        }
        problems = []
        if a is not None:
            values.update(
                {
                    "saturated": a.saturated,
                    "rate_limited": a.rate_limited,
                    "r_x_m": float(a.radii_m[0]),
                    "r_y_m": float(a.radii_m[1]),
                    "r_z_m": float(a.radii_m[2]),
                    "tether_length_m": float(a.joint_position[TETHER_INDEX]),
                }
            )
            if math.isfinite(a.tension_n):
                values["tension_n"] = a.tension_n
                values["required_tension_n"] = a.required_tension_n
                values["tension_margin_n"] = a.tension_margin_n
        if math.isfinite(w.min_margin):
            values["min_tension_margin_n"] = w.min_margin
            if w.min_margin < 0.0:
                problems.append("tension below the required margin")
        elif self.angular_velocity is None:
            problems.append("no angular velocity yet: tension not checked")
        symptoms = self.health.symptoms
        values["fault_handling"] = self.health.enabled
        values["faulty_joints"] = (
            ", ".join(f"{JOINT_NAMES[j]} {s}" for j, s in sorted(symptoms.items())) or "none"
        )
        if symptoms:
            problems.append(f"{len(symptoms)} faulty joint(s): planning without them")
        if w.rejected:
            problems.append(f"{w.rejected} input(s) rejected")
        if w.saturated:
            problems.append(f"{w.saturated} setpoint(s) projected onto the reachable set")
        message = "; ".join(problems) if problems else "tracking"
        if w.rate_limited and not problems:
            message = "tracking, rate limited"
        level = 2 if symptoms else 1 if problems else 0  # a broken joint is an error
        return AllocatorStatus(level=level, message=message, values=values)
