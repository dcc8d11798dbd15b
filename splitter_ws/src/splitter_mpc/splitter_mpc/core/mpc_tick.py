"""The MPC's control tick, ROS-free: inputs, stamp rules, joining, waits, hold, diagnostics.

The ``inertial_morphing_mpc`` node converts messages into the calls below and
publishes what :class:`MpcTick` answers; the library closed loop drives the same
object with plain values (:meth:`MpcTick.set_phase`, :meth:`MpcTick.set_reference`,
:meth:`MpcTick.gait_answered`, :meth:`MpcTick.on_state`).

* Inputs of tick ``t`` (a multiple of ``control_period_s``): the body rate and
  attitude (``/splitter/imu``) and the principal moments (``/splitter/inertia``),
  joined by a :class:`~splitter_mpc.core.tick_inputs.TickAssembler`. A rejected
  message is not filed: its tick waits for a good one of the same stamp.
* Stamp rules (:attr:`MpcTick.stamps`, a :class:`StampGate`): never backwards on a
  topic, never far ahead, and a tick's input never before the last tick answered
  (:attr:`MpcTick.last_answered`).
* Waits (lockstep): a tick is answered once the attitude reference is set, the
  gait phase (and the stance-shape flag) is known when a gait manager publishes one,
  and that manager has
  answered the tick (its jump command stamped ``t``): it publishes the phase and
  reference of tick ``t`` before that command, so tick ``t`` plans with them
  whatever the message timing, in the library loop's order (gait, then MPC). The
  waiting tick is answered when what it waits for arrives; a later complete tick
  replaces it.
* The reference: the rate (``/splitter/attitude_reference``) and the attitude at
  its stamp (``/splitter/attitude_reference_pose``), given to the controller once
  both are in.
* ``plan_from_setpoints`` (real time): the plan starts from the last setpoint sent,
  with the body rate momentum gives there.
* The answer (:class:`MpcAnswer`): the setpoint, or the controller's refusal, and
  the diagnostics content on the ``diagnostics_period_s`` grid.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.model import angular_velocity_after_morphing, with_masses
from splitter_mpc.core.controller import ControllerConfig, ControllerStatus, MorphingController
from splitter_mpc.core.mpc import NS_PER_S, MpcSettings, settings_for_weights
from splitter_mpc.core.ocp import MpcWeights
from splitter_mpc.core.solvers import SolverOptions
from splitter_mpc.core.tick_inputs import TickAssembler
from splitter_msgs_py import names
from splitter_msgs_py.core.latency import InputLatency
from splitter_msgs_py.core.parameter_fields import PERIOD_S, parameter_field, parameter_fields
from splitter_msgs_py.core.stamps import ClockNs, MessageValidationError, StampGate, clock_value

MAX_RATE_RAD_S = 100.0  # [rad/s] a body rate or rate reference component beyond it is corrupt
TICK_INPUTS = (names.IMU, names.INERTIA)


@dataclass(frozen=True)
class MpcTickSettings:
    """The node's settings of the tick itself (not the controller's)."""

    plan_from_setpoints: bool = parameter_field(
        False,
        "real time: plan from the inertia the setpoints already sent will reach (the "
        "allocator stamps them ahead by the latency), with the body rate momentum gives "
        "there, not from the inertia measured now, which lags them",
    )
    diagnostics_period_s: float = parameter_field(
        0.1, "diagnostics period, simulated time [s]", bounds=PERIOD_S, live=True
    )
    estimated_masses: bool = parameter_field(
        False,
        "plan with the masses /splitter/estimate/masses and the hemi bodies' moments "
        "/splitter/estimate/hemi_inertia give, stamped with each tick (the flight "
        "estimator's; a tick waits for them), instead of the nominal model's",
    )

    @property
    def diagnostics_period_ns(self) -> int:
        return round(self.diagnostics_period_s * NS_PER_S)


# The node's parameters: the fields of these classes marked with parameter_field ...
PARAMETER_CLASSES = (
    ControllerConfig,
    MpcWeights,
    MpcSettings,
    SolverOptions,
    MpcTickSettings,
)
# ... named as the field, or as here (core field -> node parameter)
PARAMETER_NAMES = {
    "max_time_s": "max_solve_time_s",
    "tol": "tolerance",
    "isolated": "isolated_solver",
    "wait_for_worker_start": "wait_for_solver_start",
    "tension_slack": "tension_slack_weight",
}


def _fields(config_class: type, values: Mapping[str, object]) -> dict[str, object]:
    """The keyword arguments of ``config_class`` that ``values`` (node parameters) give."""
    out: dict[str, object] = {}
    for name, default, _info in parameter_fields(config_class):
        key = PARAMETER_NAMES.get(name, name)
        if key in values:
            value = values[key]
            out[name] = tuple(value) if isinstance(default, tuple) else value  # type: ignore[arg-type]
    return out


def controller_config_from_parameters(values: Mapping[str, object]) -> ControllerConfig:
    """The controller's configuration from the node's parameter values (missing: defaults).

    ``ValueError`` when the values do not make a valid configuration.
    """
    weights = MpcWeights(**_fields(MpcWeights, values))  # type: ignore[arg-type]
    options = SolverOptions(**_fields(SolverOptions, values))  # type: ignore[arg-type]
    mpc = MpcSettings(options=options, **_fields(MpcSettings, values))  # type: ignore[arg-type]
    return ControllerConfig(
        weights=weights,
        mpc=settings_for_weights(mpc, weights),
        **_fields(ControllerConfig, values),  # type: ignore[arg-type]
    )


def tick_settings_from_parameters(values: Mapping[str, object]) -> MpcTickSettings:
    """The tick's settings from the node's parameter values (missing: defaults)."""
    return MpcTickSettings(**_fields(MpcTickSettings, values))  # type: ignore[arg-type]


def checked_rate(field_name: str, w: ArrayLike) -> NDArray[np.float64]:
    """``w`` [rad/s] if no component is beyond ``MAX_RATE_RAD_S``; ``MessageValidationError``."""
    w = np.asarray(w, dtype=float)
    if np.max(np.abs(w)) > MAX_RATE_RAD_S:
        raise MessageValidationError(f"{field_name}: |w| component above {MAX_RATE_RAD_S} rad/s")
    return w


def controller_diagnostics(
    status: ControllerStatus,
) -> tuple[int, str, dict[str, float | int | str | bool]]:
    """(level, message, values) of the controller's last tick, for ``/diagnostics``."""
    level, message = 0, status.solve_status
    if not status.active:
        message = "inactive: holding the nominal inertia"
    elif status.consecutive_failures > 0:
        level = 1 if status.consecutive_failures < 5 else 2
        message = f"{status.solve_status}: executing the previous plan"
    keys = (
        "active phase solver solve_status solve_ok converged iterations solve_time_ms cost "
        "infeasibility plan_age_s solves failures deadline_misses consecutive_failures recovering"
    ).split()
    values = {key: getattr(status, key) for key in keys}
    for axis, value in zip(("ixx", "iyy", "izz"), status.setpoint_kg_m2, strict=True):
        values[f"setpoint_{axis}_kg_m2"] = value
    return level, message, values


MAX_MASS_KG = 1.0e3  # [kg] a lumped mass beyond it is corrupt


def checked_hemi_inertia(moments_kg_m2: ArrayLike) -> NDArray[np.float64]:
    """A hemi body's own moments [kg m^2] if each is finite and within +-``MAX_MASS_KG``
    kg m^2 (an estimate may dip below zero); ``MessageValidationError`` otherwise."""
    j = np.asarray(moments_kg_m2, dtype=float)
    if not np.all(np.abs(j) <= MAX_MASS_KG):  # NaN too
        raise MessageValidationError(
            f"vector: hemi body moments must be within +-{MAX_MASS_KG} kg m^2, got {j}"
        )
    return j


def checked_masses(masses_kg: ArrayLike) -> NDArray[np.float64]:
    """(m_x, m_y, m_z) [kg] if each is in (0, ``MAX_MASS_KG``]; ``MessageValidationError``."""
    m = np.asarray(masses_kg, dtype=float)
    if not np.all((m > 0.0) & (m <= MAX_MASS_KG)):  # NaN too
        raise MessageValidationError(f"vector: masses must be in (0, {MAX_MASS_KG}] kg, got {m}")
    return m


@dataclass(frozen=True)
class MpcAnswer:
    """Tick ``t_ns`` answered: the setpoint, or ``error`` (the controller refused the state)."""

    t_ns: int
    setpoint_kg_m2: NDArray[np.float64] | None
    error: str = ""
    diagnostics: tuple[int, str, dict[str, float | int | str | bool]] | None = None


class MpcTick:
    """The MPC node's per-tick logic around :class:`MorphingController` (module doc)."""

    def __init__(
        self,
        controller: MorphingController,
        settings: MpcTickSettings | None = None,
        has_publisher: Callable[[str], bool] = lambda topic: False,
    ) -> None:
        self.controller = controller
        self.settings = settings or MpcTickSettings()
        self._check_periods(self.settings, controller.config)
        self.has_publisher = has_publisher  # a gait manager in the graph is waited for
        self.tick_inputs = TICK_INPUTS + (
            (names.ESTIMATE_MASSES, names.ESTIMATE_HEMI_INERTIA)
            if self.settings.estimated_masses
            else ()
        )
        self.ticks = TickAssembler(controller.config.control_period_ns, self.tick_inputs)
        self.stamps = StampGate()
        self.latency = InputLatency()  # a tick's state: simulated clock when used - stamp
        self.phase: str | None = None
        self.stance_shape: bool | None = None  # the limbs are legs (None: not told yet)
        self.last_answered: int | None = None  # [ns] the last tick answered
        self.answered = 0
        self._w_ref: NDArray[np.float64] | None = None
        self._q_ref: tuple[int, NDArray[np.float64]] | None = None
        self._gait_answered: int | None = None  # stamp of the gait's last answer [ns]
        self._waiting: tuple[int, dict[str, object | None]] | None = None
        self._last_setpoint: NDArray[np.float64] | None = None  # [kg m^2] the last one sent

    @staticmethod
    def _check_periods(settings: MpcTickSettings, config: ControllerConfig) -> None:
        if settings.diagnostics_period_ns % config.control_period_ns != 0:
            raise ValueError(
                f"diagnostics_period_s must be a multiple of control_period_s "
                f"({config.control_period_s:g} s)"
            )

    def reconfigure(self, config: ControllerConfig, settings: MpcTickSettings) -> None:
        """A live change: weights and scheduler settings from the next tick (``ValueError``).

        The solver is reused (its weights are NLP parameters): a change whose solver
        would differ (q_q or q_tq made > 0 while the MPC was built without the
        attitude in its state) is refused.
        """
        if config.mpc != self.controller.config.mpc:
            raise ValueError(
                "q_q/q_tq > 0 needs the attitude in the MPC's state, which this MPC was built "
                "without (q_q = q_tq = 0 at start-up): restart the node with them"
            )
        self._check_periods(settings, config)
        self.controller.config = config
        self.controller.set_weights(config.weights)
        self.settings = settings

    # --- inputs ----------------------------------------------------------------------------
    def add(
        self, topic: str, t_ns: int | None, value: object, clock_ns: ClockNs = None
    ) -> MpcAnswer | None:
        """An input of ``topic`` stamped ``t_ns`` (stamp admitted): imu ``(w, q)``, inertia,
        reference rate, reference attitude, the gait phase (its name, no stamp) or the
        gait's answer (``value`` unused).

        Returns the answer of a tick it lets through; ``ValueError`` for an unknown phase
        and for a reference the controller refuses (kept until the other half of the
        reference replaces it).
        """
        if topic == names.GAIT_PHASE:
            if value not in names.GAIT_PHASES:
                raise ValueError(f"unknown phase {value!r}")
            self.phase = str(value)
        elif topic == names.STANCE_SHAPE:
            if not isinstance(value, bool):
                raise ValueError(f"stance shape must be a bool, got {value!r}")
            self.stance_shape = value
        elif topic in self.tick_inputs:
            events = self.ticks.add(topic, t_ns, value)
            if events.completed is not None:
                self._waiting = events.completed
        elif topic == names.ATTITUDE_REFERENCE:
            self._w_ref = checked_rate("twist.angular", value)  # type: ignore[arg-type]
            self._update_reference()
        elif topic == names.ATTITUDE_REFERENCE_POSE:
            self._q_ref = (t_ns, np.asarray(value, dtype=float))
            self._update_reference()
        elif topic == names.JUMP_COMMAND:
            self._gait_answered = t_ns
        else:
            raise ValueError(f"not an input of the MPC: {topic}")
        return self._try_tick(clock_ns)

    def set_phase(self, phase: str, clock_ns: ClockNs = None) -> MpcAnswer | None:
        """The gait phase (``ValueError`` for an unknown one)."""
        return self.add(names.GAIT_PHASE, None, phase, clock_ns)

    def set_stance_shape(self, stance_shape: bool, clock_ns: ClockNs = None) -> MpcAnswer | None:
        """Whether the limbs are legs now (the gait's ``/splitter/gait/stance_shape``)."""
        return self.add(names.STANCE_SHAPE, None, bool(stance_shape), clock_ns)

    def set_reference(
        self, stamp_ns: int, w_ref_rad_s: ArrayLike, q_ref_wxyz: ArrayLike
    ) -> MpcAnswer | None:
        """Both halves of the attitude reference at once (the library loop)."""
        self.add(names.ATTITUDE_REFERENCE, stamp_ns, w_ref_rad_s)
        return self.add(names.ATTITUDE_REFERENCE_POSE, stamp_ns, q_ref_wxyz)

    def gait_answered(self, t_ns: int, clock_ns: ClockNs = None) -> MpcAnswer | None:
        """The gait manager answered tick ``t_ns`` (the library loop: after its update)."""
        return self.add(names.JUMP_COMMAND, t_ns, None, clock_ns)

    def on_state(
        self,
        t_ns: int,
        angular_velocity_rad_s: ArrayLike,
        orientation_wxyz: ArrayLike,
        inertia_kg_m2: ArrayLike,
        clock_ns: ClockNs = None,
        *,
        masses_kg: ArrayLike | None = None,
        hemi_inertia_kg_m2: ArrayLike | None = None,
    ) -> MpcAnswer | None:
        """Tick ``t_ns``'s state from plain values (the library loop); None: the tick waits.

        ``masses_kg`` (m_x, m_y, m_z) and ``hemi_inertia_kg_m2`` (a hemi body's own
        moments) when the tick takes estimated masses.
        """
        rate = checked_rate("angular_velocity", angular_velocity_rad_s)
        if masses_kg is not None:
            self.add(names.ESTIMATE_MASSES, t_ns, np.asarray(masses_kg, dtype=float), clock_ns)
        if hemi_inertia_kg_m2 is not None:
            moments = np.asarray(hemi_inertia_kg_m2, dtype=float)
            self.add(names.ESTIMATE_HEMI_INERTIA, t_ns, moments, clock_ns)
        self.add(names.IMU, t_ns, (rate, np.asarray(orientation_wxyz, dtype=float)), clock_ns)
        return self.add(names.INERTIA, t_ns, np.asarray(inertia_kg_m2, dtype=float), clock_ns)

    def _update_reference(self) -> None:
        if self._w_ref is None or self._q_ref is None:
            return
        stamp, q_ref = self._q_ref
        self.controller.set_reference(stamp, self._w_ref, q_ref)

    # --- the tick --------------------------------------------------------------------------
    def waits(self, t_ns: int) -> bool:
        """Whether tick ``t_ns`` waits for the reference, the phase or the gait's answer."""
        if not self.controller.config.enabled:
            return False
        if self.controller.reference is None:
            return True
        if self.phase is None and self.has_publisher(names.GAIT_PHASE):
            return True
        if self.stance_shape is None and self.has_publisher(names.STANCE_SHAPE):
            return True
        if self._gait_answered is not None and self._gait_answered >= t_ns:
            return False
        return self.has_publisher(names.JUMP_COMMAND)

    def _try_tick(self, clock_ns: ClockNs) -> MpcAnswer | None:
        if self._waiting is None or self.waits(self._waiting[0]):
            return None
        (t_ns, inputs), self._waiting = self._waiting, None
        (w, q), inertia = inputs[names.IMU], inputs[names.INERTIA]  # type: ignore[misc]
        masses = inputs.get(names.ESTIMATE_MASSES)
        if masses is not None:
            hemi = inputs.get(names.ESTIMATE_HEMI_INERTIA, np.zeros(3))
            self.controller.set_mass_model(with_masses(self.controller.model, masses), hemi)
        self.latency.record("state", t_ns, clock_value(clock_ns))
        if self.settings.plan_from_setpoints and self._last_setpoint is not None:
            # the commands stamped ahead reach the last setpoint before this tick's does
            w = angular_velocity_after_morphing(w, inertia, self._last_setpoint)
            inertia = self._last_setpoint
        try:
            setpoint = self.controller.on_state(
                t_ns, w, q, inertia, self.phase, stance_shape=bool(self.stance_shape)
            )
        except ValueError as exc:  # inputs checked on arrival; keep running regardless
            return MpcAnswer(t_ns, None, error=str(exc))
        self._last_setpoint = np.asarray(setpoint, dtype=float).copy()
        self.answered += 1
        self.last_answered = t_ns
        diagnostics = None
        if t_ns % self.settings.diagnostics_period_ns == 0:
            diagnostics = self.diagnostics()
        return MpcAnswer(t_ns, setpoint, diagnostics=diagnostics)

    def diagnostics(self) -> tuple[int, str, dict[str, float | int | str | bool]]:
        """(level, message, finite values) of the last tick, input latency included."""
        level, message, values = controller_diagnostics(self.controller.status)
        values.update(self.latency.values())
        finite = {
            k: v for k, v in values.items() if not (isinstance(v, float) and not math.isfinite(v))
        }
        return level, message, finite
