"""Monte-Carlo campaigns of a scenario: random tumbles, success, failure modes, statistics.

ROS-free; the algorithm of ``splitter campaign`` (:mod:`splitter_bringup.cli.campaign`
runs it on Dask). Figures: :mod:`.campaign_plots`.

Draws (issue 16). Draw ``i`` of a campaign with seed ``S`` has its own integer seed,
``numpy.random.SeedSequence(S).spawn(n)[i]`` (which does not depend on ``n``), and
everything it varies is a pure function of that seed (:func:`make_draw`), in this
order from ``numpy.random.default_rng(seed)``:

1. ``|w0|`` uniform in ``[w_min, w_max]`` [rad/s];
2. its direction uniform on the sphere (a normalised standard normal 3-vector), body frame;
3. the initial attitude uniform on SO(3) (``Rotation.random``), stored as the scenario
   files' Euler angles (extrinsic xyz, degrees; the flight starts from those);
4. the perturbations, drawn always (so switching one on never changes 1-3): mass
   factors of ``m_x, m_y, m_z`` uniform in ``[1 - p, 1 + p]``, a gyro bias uniform in
   ``[-b, b]`` per axis, the seed of the gyro noise, and each hemi body's box
   edges (x, y, z) uniform in ``[e/2, e]``, whose moments about its centre with the
   body's mass ``m_x`` are the body's own inertia (``m (b^2 + c^2) / 12``, ...).

Everything else is the scenario's. A draw flies
:func:`splitter_bringup.run.campaign.run_draw` (the library closed loop).

Success (issue 16), on the body rate ``w`` [rad/s] at the last sample:
``|w_x| < 0.01``, ``|w_z| < 0.01`` and ``|w_y| / |w| >= 0.99`` (either spin sense).
Settling time: the first sample time after which that holds to the end (NaN when
it does not hold at the end).

Failure modes (:func:`classify_flight`), the first that applies, in this order:

* ``error``: the run raised (no trajectory; the message is kept).
* ``diverged``: the rate left what torque-free flight allows: a non-finite sample, a
  rate above ``DIVERGENCE_FACTOR`` x ``|w(0)|``, or a final rate of zero (``|H|`` is
  conserved and the inertia bounded, so ``|w|`` stays within a factor ~3 of ``|w0|``).
* (success: no failure mode)
* ``deadline_miss``: not a success, and at least one MPC solve was abandoned at its
  wall-time deadline (the controller then ran a stale plan).
* ``solver_failure``: not a success, no deadline miss, and at least one solve failed
  (not converged, infeasible, late or raised).
* otherwise the axis that dominates the tail, the last ``TAIL_WINDOW_S`` of the run
  (all of a shorter run): the mean of ``|w_k| / |w|`` over the tail for k = x, y, z;
  the largest is the dominant axis:

  - ``tumbling``: no axis carries at least ``DOMINANT_FRACTION`` (0.8) of ``|w|`` on
    average: the body still tumbles;
  - ``minor_axis_spin``: x dominates: stuck spinning about the tether axis (the
    minor axis of inertia);
  - ``wrong_axis``: z dominates: settled about z instead of y;
  - ``slow_convergence``: y dominates but the residual is above tolerance at the end.

Statistics: the success rate with its 95 % Wilson score interval
(:func:`wilson_interval`), counts per failure mode, median and 90th percentile of
the settling time over the successful draws (:func:`summarize`), and the same
binned by ``|w0|`` (:func:`binned_by_speed`).
"""

from __future__ import annotations

import copy
import csv
import math
import shlex
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from splitter_bringup.analysis.fault_draws import (
    NO_DETECTION,
    FaultDetection,
    detection_table,
    draw_fault,
    fault_detection,
    fault_row,
)
from splitter_bringup.analysis.summary import estimator_errors, hemi_inertia_error
from splitter_bringup.scenario.definition import Scenario
from splitter_model.faults import JointFault
from splitter_model.model import RobotModel
from splitter_sim.core.robot_errors import RobotErrors

W_MIN_RAD_S = 0.5  # [rad/s] default lower bound of |w0|
W_MAX_RAD_S = 1.8  # [rad/s] default upper bound of |w0|
RESIDUAL_TOLERANCE_RAD_S = 0.01  # [rad/s] on |w_x| and |w_z| at the end
ALIGNMENT_MIN = 0.99  # [-] |w_y| / |w| at the end
TAIL_WINDOW_S = 1.0  # [s] the end of the run the failure mode is read from
DOMINANT_FRACTION = 0.8  # [-] mean |w_k| / |w| over the tail for axis k to dominate
DIVERGENCE_FACTOR = 10.0  # [-] |w| above this times |w(0)|: diverged
# [N m] limbs, [N] tether: joint effort sensor noise of a draw with robot errors (~5 % of
# the limbs' ~1 N m centripetal load in a 1 rad/s spin)
DEFAULT_JOINT_EFFORT_NOISE = 0.05
# [kg m^2] the estimator's prior std of each hemi body's own moment when a campaign
# flies bodies that are not points (what an engineer who knows they are not sets)
HEMI_INERTIA_PRIOR_KG_M2 = 0.05

SUCCESS = "success"
FAILURE_MODES = (
    "minor_axis_spin",
    "wrong_axis",
    "tumbling",
    "slow_convergence",
    "solver_failure",
    "deadline_miss",
    "diverged",
    "error",
)
OUTCOMES = (SUCCESS, *FAILURE_MODES)


# --- draws ----------------------------------------------------------------------------
@dataclass(frozen=True)
class PerturbationSpec:
    """How much a campaign perturbs each draw (0: off); see :class:`Draw`."""

    mass_fraction: float = 0.0  # [-] m_x, m_y, m_z each scaled within 1 +- this
    gyro_noise_rad_s: float = 0.0  # [rad/s] white noise std per axis and reading
    gyro_bias_rad_s: float = 0.0  # [rad/s] bias drawn uniform in +- this per axis
    actuator_lag_s: float = 0.0  # [s] first-order lag time constant of the joint commands
    command_latency_s: float = 0.0  # [s] delay of every joint command to the servos
    # [m] hemi bodies with their own inertia: a box each, edges uniform in [e/2, e]
    hemi_body_edge_m: float = 0.0
    # [N m] limbs, [N] tether: the joint effort sensors' noise, std per reading, in every
    # draw with robot errors (a sensor, not a perturbation: it does not make one)
    joint_effort_noise: float = DEFAULT_JOINT_EFFORT_NOISE
    # the controllers fly on the flight estimator (splitter_mpc.core.estimator) and lead
    # their commands through the actuators' lag; False: they read the sensors as they are
    estimator: bool = True
    # [s] every draw has one random fault (analysis.fault_draws) before this time; 0: none
    fault_time_max_s: float = 0.0
    # the allocator detects faulty joints and re-plans without them (Scenario.fault_handling)
    fault_handling: bool = True

    def __post_init__(self) -> None:
        for name, value in self.as_dict().items():
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if self.mass_fraction >= 1.0:
            raise ValueError(f"mass_fraction must be < 1, got {self.mass_fraction!r}")

    @property
    def active(self) -> bool:
        """True when the robot is perturbed (its masses, sensors, actuators)."""
        return any(
            v > 0.0
            for k, v in self.as_dict().items()
            if k not in ("joint_effort_noise", "fault_time_max_s")
        )

    def as_dict(self) -> dict[str, float]:
        """Each perturbation by its field name."""
        return {k: v for k, v in asdict(self).items() if k not in ("estimator", "fault_handling")}


@dataclass(frozen=True)
class Draw:
    """One random initial condition (and perturbation) of a campaign."""

    index: int
    seed: int  # the draw's own seed: replays it alone
    w0_rad_s: tuple[float, float, float]  # [rad/s] body frame
    euler_deg: tuple[float, float, float]  # [deg] roll, pitch, yaw (extrinsic xyz)
    mass_scale: tuple[float, float, float] = (1.0, 1.0, 1.0)  # [-] m_x, m_y, m_z factors
    gyro_bias_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [rad/s] body frame
    noise_seed: int = 0  # of the gyro noise
    # [kg m^2] each hemi body's own principal moments (zero: the paper's points)
    hemi_inertia_kg_m2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fault: JointFault | None = None  # the draw's fault (--fault RANDOM), else None

    @property
    def w0_norm_rad_s(self) -> float:
        return float(np.linalg.norm(self.w0_rad_s))


def draw_seeds(seed: int, count: int) -> list[int]:
    """The integer seed of each of the first ``count`` draws of campaign ``seed``."""
    children = np.random.SeedSequence(int(seed)).spawn(int(count))
    return [int(c.generate_state(1, dtype=np.uint32)[0]) for c in children]


def make_draw(
    index: int,
    seed: int,
    w_min_rad_s: float = W_MIN_RAD_S,
    w_max_rad_s: float = W_MAX_RAD_S,
    perturbation: PerturbationSpec | None = None,
) -> Draw:
    """Draw ``index`` from its own ``seed`` (the order of the module docstring)."""
    if not (0.0 <= w_min_rad_s <= w_max_rad_s and math.isfinite(w_max_rad_s)):
        raise ValueError(f"need 0 <= w_min <= w_max, got {w_min_rad_s}, {w_max_rad_s}")
    p = perturbation or PerturbationSpec()
    rng = np.random.default_rng(int(seed))
    speed = float(rng.uniform(w_min_rad_s, w_max_rad_s))
    direction = rng.standard_normal(3)
    direction /= np.linalg.norm(direction)
    euler = Rotation.random(random_state=rng).as_euler("xyz", degrees=True)
    mass_u = rng.uniform(-1.0, 1.0, 3)
    bias_u = rng.uniform(-1.0, 1.0, 3)
    noise_seed = int(rng.integers(0, 2**31 - 1))
    edges = p.hemi_body_edge_m * rng.uniform(0.5, 1.0, 3)  # [m] x, y, z
    fault_u = rng.uniform(0.0, 1.0, 3)  # drawn last (analysis.fault_draws)
    body_mass = RobotModel().body_mass_kg * (1.0 + p.mass_fraction * mass_u[0])  # [kg]
    return Draw(
        index=int(index),
        seed=int(seed),
        w0_rad_s=_triple(speed * direction),
        euler_deg=_triple(euler),
        mass_scale=_triple(1.0 + p.mass_fraction * mass_u),
        gyro_bias_rad_s=_triple(p.gyro_bias_rad_s * bias_u + 0.0),  # (no -0.0)
        noise_seed=noise_seed,
        hemi_inertia_kg_m2=box_inertia(body_mass, edges),
        fault=draw_fault(fault_u, p.fault_time_max_s) if p.fault_time_max_s > 0.0 else None,
    )


def box_inertia(mass_kg: float, edges_m: ArrayLike) -> tuple[float, float, float]:
    """Principal moments [kg m^2] of a solid box of ``mass_kg`` with edges (a, b, c) [m]
    along x, y, z about its centre: ``m (b^2 + c^2) / 12``, ... ."""
    a2, b2, c2 = (float(e) ** 2 for e in np.asarray(edges_m, dtype=float).reshape(3))
    return _triple(mass_kg / 12.0 * np.array([b2 + c2, a2 + c2, a2 + b2]))


def draw_campaign(
    seed: int,
    count: int,
    w_min_rad_s: float = W_MIN_RAD_S,
    w_max_rad_s: float = W_MAX_RAD_S,
    perturbation: PerturbationSpec | None = None,
) -> list[Draw]:
    """The ``count`` draws of campaign ``seed``."""
    return [
        make_draw(i, s, w_min_rad_s, w_max_rad_s, perturbation)
        for i, s in enumerate(draw_seeds(seed, count))
    ]


def _triple(v: ArrayLike) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float).reshape(3)
    return (float(a[0]), float(a[1]), float(a[2]))


def scenario_for_draw(base: Scenario, draw: Draw, duration_s: float | None = None) -> Scenario:
    """``base`` started from the draw's rate and attitude (and run ``duration_s``), with
    the draw's fault."""
    return replace(
        base,
        initial_angular_velocity_rad_s=np.array(draw.w0_rad_s, dtype=float),
        initial_orientation_euler_deg=np.array(draw.euler_deg, dtype=float),
        duration_s=base.duration_s if duration_s is None else float(duration_s),
        faults=() if draw.fault is None else (draw.fault,),
    )


def robot_errors_for_draw(draw: Draw, spec: PerturbationSpec | None = None) -> RobotErrors:
    """The robot a draw flies (``Scenario.robot_errors``): its masses, gyro and lag.

    Only what ``spec`` switches on (the draw always carries all its numbers).
    """
    p = spec or PerturbationSpec()
    if not p.active:
        return RobotErrors()
    return RobotErrors(
        mass_scale=draw.mass_scale if p.mass_fraction > 0.0 else (1.0, 1.0, 1.0),
        gyro_noise_rad_s=p.gyro_noise_rad_s,
        gyro_bias_rad_s=draw.gyro_bias_rad_s,
        actuator_lag_s=p.actuator_lag_s,
        command_latency_s=p.command_latency_s,
        joint_effort_noise=p.joint_effort_noise,
        noise_seed=draw.noise_seed,
        hemi_inertia_kg_m2=draw.hemi_inertia_kg_m2,
    )


def estimator_for_draw(base: Scenario, draw: Draw) -> Scenario:
    """``base`` whose estimator identifies the hemi bodies' moments when the draw has
    bodies (prior std ``HEMI_INERTIA_PRIOR_KG_M2``); otherwise ``base`` unchanged."""
    if not any(draw.hemi_inertia_kg_m2):
        return base
    return replace(
        base, estimator=replace(base.estimator, hemi_inertia_prior_kg_m2=HEMI_INERTIA_PRIOR_KG_M2)
    )


def plant_model(draw: Draw, nominal: RobotModel | None = None) -> RobotModel:
    """The robot a perturbed draw flies: the nominal one with the draw's masses."""
    return RobotErrors(mass_scale=draw.mass_scale).plant_model(nominal or RobotModel())


def scenario_document(
    base: Scenario,
    draw: Draw,
    duration_s: float | None = None,
    robot_errors: RobotErrors | None = None,
) -> dict:
    """A scenario file (YAML mapping) of the draw: ``splitter run FILE`` flies it.

    The base's chosen variant merged in, as the only variant; the paper's findings
    (comparisons between variants) dropped; the draw's ``robot_errors`` when it has any
    (:func:`robot_errors_for_draw`), so the graph flies the same wrong robot.
    """
    doc: dict[str, Any] = copy.deepcopy(dict(base.raw))
    doc.pop("findings", None)
    doc["name"] = base.name
    doc["description"] = (
        f"Campaign draw {draw.index} (seed {draw.seed}) of {base.name}/{base.variant}: "
        f"|w0| = {draw.w0_norm_rad_s:.3f} rad/s, random attitude."
    )
    doc["duration_s"] = base.duration_s if duration_s is None else float(duration_s)
    initial = dict(doc.get("initial") or {})
    initial["angular_velocity_rad_s"] = list(draw.w0_rad_s)
    initial["orientation_euler_deg"] = list(draw.euler_deg)
    doc["initial"] = initial
    if draw.fault is not None:
        f = draw.fault
        doc["faults"] = [{"joint": f.joint, "kind": f.kind, "time_s": float(f.time_s)}]
    doc["variants"] = {base.variant: {}}
    if robot_errors is not None and robot_errors.present:
        doc["robot_errors"] = {
            k: list(v) if isinstance(v, tuple) else v for k, v in asdict(robot_errors).items()
        }
        if any(robot_errors.hemi_inertia_kg_m2):
            estimator = dict(doc.get("estimator") or {})
            estimator["hemi_inertia_prior_kg_m2"] = HEMI_INERTIA_PRIOR_KG_M2
            doc["estimator"] = estimator
    return doc


# --- one flight -----------------------------------------------------------------------
@dataclass(frozen=True)
class FlightOutcome:
    """What :func:`classify_flight` makes of a trajectory."""

    success: bool
    failure_mode: str  # "" on success, else one of FAILURE_MODES
    settling_time_s: float  # [s] NaN unless success

    @property
    def outcome(self) -> str:
        return SUCCESS if self.success else self.failure_mode


def success_mask(w_rad_s: ArrayLike) -> NDArray[np.bool_]:
    """Per sample: the success condition on the body rate (n, 3) [rad/s]."""
    w = np.asarray(w_rad_s, dtype=float).reshape(-1, 3)
    norm = np.linalg.norm(w, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        aligned = np.abs(w[:, 1]) >= ALIGNMENT_MIN * norm
    return (
        (np.abs(w[:, 0]) < RESIDUAL_TOLERANCE_RAD_S)
        & (np.abs(w[:, 2]) < RESIDUAL_TOLERANCE_RAD_S)
        & aligned
        & (norm > 0.0)
    )


def settling_time(t_s: ArrayLike, w_rad_s: ArrayLike) -> float:
    """First time [s] after which the success condition holds to the end; NaN if never."""
    t = np.asarray(t_s, dtype=float)
    ok = success_mask(w_rad_s)
    if ok.size == 0 or not ok[-1]:
        return math.nan
    failing = np.flatnonzero(~ok)
    return float(t[0] if failing.size == 0 else t[failing[-1] + 1])


def classify_flight(
    t_s: ArrayLike,
    w_rad_s: ArrayLike,
    *,
    mpc_failures: int = 0,
    deadline_misses: int = 0,
    error: str | None = None,
) -> FlightOutcome:
    """Success, failure mode and settling time of a flight (module docstring).

    ``t_s`` (n,) [s], ``w_rad_s`` (n, 3) body rate [rad/s]; ``mpc_failures`` and
    ``deadline_misses`` the MPC's counts over the flight; ``error`` the message of
    an exception that ended the run.
    """
    if error is not None:
        return FlightOutcome(False, "error", math.nan)
    t = np.asarray(t_s, dtype=float).reshape(-1)
    w = np.asarray(w_rad_s, dtype=float).reshape(-1, 3)
    if len(t) == 0 or len(t) != len(w):
        return FlightOutcome(False, "error", math.nan)
    norm = np.linalg.norm(w, axis=1)
    if (
        not (np.all(np.isfinite(w)) and np.all(np.isfinite(t)))
        or norm.max() > DIVERGENCE_FACTOR * norm[0]
        or norm[-1] <= 0.0
    ):
        return FlightOutcome(False, "diverged", math.nan)
    settling = settling_time(t, w)
    if math.isfinite(settling):
        return FlightOutcome(True, "", settling)
    if deadline_misses > 0:
        return FlightOutcome(False, "deadline_miss", math.nan)
    if mpc_failures > 0:
        return FlightOutcome(False, "solver_failure", math.nan)
    tail = t >= t[-1] - TAIL_WINDOW_S
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.nan_to_num(np.nanmean(np.abs(w[tail]) / norm[tail, None], axis=0))
    axis = int(np.argmax(share))
    if share[axis] < DOMINANT_FRACTION:
        mode = "tumbling"
    else:
        mode = ("minor_axis_spin", "slow_convergence", "wrong_axis")[axis]
    return FlightOutcome(False, mode, math.nan)


@dataclass(frozen=True)
class DrawResult:
    """One draw flown: its outcome and the figures of ``draws.csv``."""

    draw: Draw
    success: bool
    failure_mode: str  # "" on success
    settling_time_s: float  # [s] NaN unless success
    w_final_rad_s: tuple[float, float, float]  # [rad/s] body frame, last sample
    mpc_solves: int
    mpc_failures: int
    mpc_deadline_misses: int
    wall_time_s: float  # [s] the draw, controller start-up included
    error: str = ""
    # the flight estimator's errors at the last estimate (NaN: flown without it)
    gyro_bias_error_rad_s: float = math.nan  # [rad/s] largest |b_est - b_true| per axis
    mass_ratio_error: float = math.nan  # [-] largest |r_est / r_true - 1| of m_y/m_x, m_z/m_x
    mass_error: float = math.nan  # [-] largest |m_est / m_true - 1| of m_x, m_y, m_z
    # [kg m^2] |J_x,est - J_x| of a hemi body's own moment about the tether axis
    hemi_inertia_error_kg_m2: float = math.nan
    # the draw's fault found (analysis.fault_draws); NaN times: no fault, or never
    detection: FaultDetection = NO_DETECTION

    @property
    def outcome(self) -> str:
        return SUCCESS if self.success else self.failure_mode


def draw_result(draw: Draw, series, wall_time_s: float) -> DrawResult:
    """Classify a draw's flight (a ``RunSeries``) into its :class:`DrawResult`."""
    extras = series.extras
    n = len(series)
    failures = int(extras["mpc_failures"][-1]) if n else 0
    misses = int(extras["mpc_deadline_misses"][-1]) if n else 0
    solves = int(np.count_nonzero(np.isfinite(extras["mpc_solve_ok"]))) if n else 0
    result = classify_flight(
        series.t_s,
        series.angular_velocity_rad_s,
        mpc_failures=failures,
        deadline_misses=misses,
    )
    w_end = series.angular_velocity_rad_s[-1] if n else (math.nan,) * 3
    errors = RobotErrors(
        mass_scale=draw.mass_scale,
        gyro_bias_rad_s=draw.gyro_bias_rad_s,
        hemi_inertia_kg_m2=draw.hemi_inertia_kg_m2,
    )
    bias_error, ratio_error, mass_error = estimator_errors(series, errors)
    return DrawResult(
        draw=draw,
        success=result.success,
        failure_mode=result.failure_mode,
        settling_time_s=result.settling_time_s,
        w_final_rad_s=_triple(w_end),
        mpc_solves=solves,
        mpc_failures=failures,
        mpc_deadline_misses=misses,
        wall_time_s=wall_time_s,
        gyro_bias_error_rad_s=bias_error,
        mass_ratio_error=ratio_error,
        mass_error=mass_error,
        hemi_inertia_error_kg_m2=(
            hemi_inertia_error(series, errors) if any(draw.hemi_inertia_kg_m2) else math.nan
        ),
        detection=fault_detection(
            series.t_s,
            series.joint_position,
            extras["joint_command"],
            extras["joint_detected"],
            draw.fault,
        )
        if "joint_detected" in extras and n
        else NO_DETECTION,
    )


def error_result(draw: Draw, message: str, wall_time_s: float = math.nan) -> DrawResult:
    """The result of a draw whose run never returned (e.g. its worker process died)."""
    nan3 = (math.nan, math.nan, math.nan)
    return DrawResult(draw, False, "error", math.nan, nan3, 0, 0, 0, wall_time_s, message)


# --- statistics ------------------------------------------------------------------------
def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (no continuity correction).

    (NaN, NaN) for no trials.
    """
    if trials <= 0:
        return (math.nan, math.nan)
    from scipy.stats import binomtest

    ci = binomtest(int(successes), int(trials)).proportion_ci(
        confidence_level=confidence, method="wilson"
    )
    return (float(ci.low), float(ci.high))


def _percentile(values: Sequence[float], q: float) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.percentile(finite, q)) if finite else math.nan


@dataclass(frozen=True)
class CampaignSummary:
    """The figures of ``campaign.json``."""

    draws: int
    successes: int
    success_rate: float
    wilson_95: tuple[float, float]
    outcome_counts: Mapping[str, int]  # every outcome, zeros included
    settling_time_median_s: float  # [s] over the successful draws
    settling_time_p90_s: float  # [s]
    mpc_failures: int  # summed over the draws
    mpc_deadline_misses: int
    draw_wall_time_s: float  # [s] summed over the draws (CPU-ish time of the campaign)
    extra: Mapping[str, Any] = field(default_factory=dict)
    # the flight estimator's errors over the draws that had one (NaN: none had)
    gyro_bias_error_p95_rad_s: float = math.nan  # [rad/s]
    mass_ratio_error_p95: float = math.nan  # [-]
    mass_error_p95: float = math.nan  # [-]

    def as_dict(self) -> dict[str, Any]:
        return {
            "draws": self.draws,
            "successes": self.successes,
            "success_rate": _json_number(self.success_rate),
            "success_rate_wilson_95": [_json_number(v) for v in self.wilson_95],
            "outcome_counts": dict(self.outcome_counts),
            "failure_mode_counts": {m: self.outcome_counts[m] for m in FAILURE_MODES},
            "settling_time_median_s": _json_number(self.settling_time_median_s),
            "settling_time_p90_s": _json_number(self.settling_time_p90_s),
            "mpc_failures": self.mpc_failures,
            "mpc_deadline_misses": self.mpc_deadline_misses,
            "draw_wall_time_s": _json_number(self.draw_wall_time_s),
            "gyro_bias_error_p95_rad_s": _json_number(self.gyro_bias_error_p95_rad_s),
            "mass_ratio_error_p95": _json_number(self.mass_ratio_error_p95),
            "mass_error_p95": _json_number(self.mass_error_p95),
            **dict(self.extra),
        }


def summarize(results: Sequence[DrawResult]) -> CampaignSummary:
    """Success rate (Wilson 95 %), outcome counts, settling-time median and p90."""
    n = len(results)
    k = sum(1 for r in results if r.success)
    counts = {o: 0 for o in OUTCOMES}
    for r in results:
        counts[r.outcome] += 1
    settling = [r.settling_time_s for r in results if r.success]
    return CampaignSummary(
        draws=n,
        successes=k,
        success_rate=k / n if n else math.nan,
        wilson_95=wilson_interval(k, n),
        outcome_counts=counts,
        settling_time_median_s=_percentile(settling, 50.0),
        settling_time_p90_s=_percentile(settling, 90.0),
        mpc_failures=sum(r.mpc_failures for r in results),
        mpc_deadline_misses=sum(r.mpc_deadline_misses for r in results),
        draw_wall_time_s=float(sum(r.wall_time_s for r in results if math.isfinite(r.wall_time_s))),
        gyro_bias_error_p95_rad_s=_percentile(
            [r.gyro_bias_error_rad_s for r in results if math.isfinite(r.gyro_bias_error_rad_s)],
            95.0,
        ),
        mass_ratio_error_p95=_percentile(
            [r.mass_ratio_error for r in results if math.isfinite(r.mass_ratio_error)], 95.0
        ),
        mass_error_p95=_percentile(
            [r.mass_error for r in results if math.isfinite(r.mass_error)], 95.0
        ),
        extra={
            "faults": detection_table(
                [fault_row(r.draw.fault) for r in results],
                [r.success for r in results],
                [r.detection for r in results],
            )
        },
    )


@dataclass(frozen=True)
class SpeedBins:
    """Success and settling time binned by ``|w0|`` (arrays of one entry per bin)."""

    edges_rad_s: NDArray[np.float64]  # (m + 1,) [rad/s]
    draws: NDArray[np.int64]  # (m,)
    successes: NDArray[np.int64]  # (m,)
    rate: NDArray[np.float64]  # (m,) NaN for an empty bin
    wilson_low: NDArray[np.float64]  # (m,)
    wilson_high: NDArray[np.float64]  # (m,)
    settling_median_s: NDArray[np.float64]  # (m,) [s] over the successes, NaN if none

    @property
    def centres_rad_s(self) -> NDArray[np.float64]:
        return 0.5 * (self.edges_rad_s[:-1] + self.edges_rad_s[1:])


def binned_by_speed(
    results: Sequence[DrawResult], w_min_rad_s: float, w_max_rad_s: float, bins: int = 6
) -> SpeedBins:
    """:class:`SpeedBins` of ``bins`` equal bins over ``[w_min, w_max]`` (ends included)."""
    edges = np.linspace(w_min_rad_s, w_max_rad_s, bins + 1)
    speed = np.array([r.draw.w0_norm_rad_s for r in results])
    which = np.clip(np.searchsorted(edges, speed, side="right") - 1, 0, bins - 1)
    n = np.zeros(bins, dtype=np.int64)
    k = np.zeros(bins, dtype=np.int64)
    lo, hi = np.full(bins, math.nan), np.full(bins, math.nan)
    rate, settle = np.full(bins, math.nan), np.full(bins, math.nan)
    for b in range(bins):
        members = [r for r, j in zip(results, which, strict=True) if j == b]
        n[b] = len(members)
        k[b] = sum(1 for r in members if r.success)
        if n[b]:
            rate[b] = k[b] / n[b]
            lo[b], hi[b] = wilson_interval(int(k[b]), int(n[b]))
            settle[b] = _percentile([r.settling_time_s for r in members if r.success], 50.0)
    return SpeedBins(edges, n, k, rate, lo, hi, settle)


def direction_angles_deg(w_rad_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Azimuth (from body x towards y) and elevation (towards z) [deg] of rates (n, 3)."""
    w = np.asarray(w_rad_s, dtype=float).reshape(-1, 3)
    norm = np.linalg.norm(w, axis=1)
    azimuth = np.degrees(np.arctan2(w[:, 1], w[:, 0]))
    with np.errstate(invalid="ignore", divide="ignore"):
        elevation = np.degrees(np.arcsin(np.clip(w[:, 2] / norm, -1.0, 1.0)))
    return azimuth, elevation


# --- files -----------------------------------------------------------------------------
CSV_COLUMNS = (
    "index",
    "seed",
    "w0_x_rad_s",
    "w0_y_rad_s",
    "w0_z_rad_s",
    "w0_norm_rad_s",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "outcome",
    "success",
    "settling_time_s",
    "failure_mode",
    "w_final_x_rad_s",
    "w_final_y_rad_s",
    "w_final_z_rad_s",
    "mpc_solves",
    "mpc_failures",
    "mpc_deadline_misses",
    "wall_time_s",
    "mass_scale_x",
    "mass_scale_y",
    "mass_scale_z",
    "gyro_bias_x_rad_s",
    "gyro_bias_y_rad_s",
    "gyro_bias_z_rad_s",
    "error",
    "gyro_bias_error_rad_s",
    "mass_ratio_error",
    "mass_error",
    "hemi_inertia_x_kg_m2",
    "hemi_inertia_y_kg_m2",
    "hemi_inertia_z_kg_m2",
    "hemi_inertia_error_kg_m2",
    "fault_joint",
    "fault_kind",
    "fault_time_s",
    "fault_detected_s",
    "fault_first_motion_s",
    "fault_detection_latency_s",
    "false_detections",
)


def csv_row(result: DrawResult) -> dict[str, Any]:
    """One row of ``draws.csv`` (floats at full precision: a row replays its draw)."""
    d = result.draw
    return dict(
        zip(
            CSV_COLUMNS,
            (
                d.index,
                d.seed,
                *(repr(v) for v in d.w0_rad_s),
                repr(d.w0_norm_rad_s),
                *(repr(v) for v in d.euler_deg),
                result.outcome,
                int(result.success),
                _csv_number(result.settling_time_s),
                result.failure_mode,
                *(_csv_number(v) for v in result.w_final_rad_s),
                result.mpc_solves,
                result.mpc_failures,
                result.mpc_deadline_misses,
                f"{result.wall_time_s:.3f}",
                *(repr(v) for v in d.mass_scale),
                *(repr(v) for v in d.gyro_bias_rad_s),
                result.error,
                _csv_number(result.gyro_bias_error_rad_s),
                _csv_number(result.mass_ratio_error),
                _csv_number(result.mass_error),
                *(repr(v) for v in d.hemi_inertia_kg_m2),
                _csv_number(result.hemi_inertia_error_kg_m2),
                "" if d.fault is None else d.fault.joint,
                "" if d.fault is None else d.fault.kind,
                "" if d.fault is None else repr(float(d.fault.time_s)),
                _csv_number(result.detection.detected_s),
                _csv_number(result.detection.first_motion_s),
                _csv_number(result.detection.latency_s),
                result.detection.false_detections,
            ),
            strict=True,
        )
    )


def _csv_number(value: float) -> str:
    return "" if not math.isfinite(value) else repr(float(value))


def _json_number(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


# --- campaign files -----------------------------------------------------------------------------
def write_csv(results: Sequence[DrawResult], path: Path) -> None:
    """``draws.csv``: one row per draw (:data:`CSV_COLUMNS`)."""
    with path.open("w", newline="", encoding="utf-8") as stream:
        writer = csv.DictWriter(stream, fieldnames=CSV_COLUMNS)
        writer.writeheader()
        for r in results:
            writer.writerow(csv_row(r))


def write_draw_scenario(out: Path, index: int, document: Mapping[str, Any]) -> dict[str, str]:
    """Write a draw's scenario file ``out/draws/draw_NNNN.yaml``; its path and the
    ``splitter run`` command that flies it again (for the draw's campaign.json entry)."""
    path = out / "draws" / f"draw_{index:04d}.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(dict(document), sort_keys=False), encoding="utf-8")
    command = ["splitter", "run", str(path), "--no-ros", "--out", str(out / f"run_{index}")]
    return {"scenario_yaml": str(path), "run_command": shlex.join(command)}


def definitions() -> dict[str, Any]:
    """The success test and the failure modes, as campaign.json states them."""
    return {
        "success": (
            f"at the last sample |w_x| < {RESIDUAL_TOLERANCE_RAD_S} and |w_z| < "
            f"{RESIDUAL_TOLERANCE_RAD_S} rad/s and |w_y|/|w| >= {ALIGNMENT_MIN}"
        ),
        "settling_time_s": "first sample time after which the success test holds to the end",
        "failure_modes": {
            "error": "the run raised (or its worker died)",
            "diverged": f"non-finite rate, |w| > {DIVERGENCE_FACTOR} |w(0)|, or |w| = 0 at the end",
            "deadline_miss": "not a success and >= 1 MPC solve abandoned at its deadline",
            "solver_failure": "not a success, no deadline miss, >= 1 failed MPC solve",
            "tumbling": (
                f"no axis carries {DOMINANT_FRACTION} of |w| on average over the last "
                f"{TAIL_WINDOW_S} s"
            ),
            "minor_axis_spin": "x (tether, minor axis) dominates the last second",
            "wrong_axis": "z dominates the last second",
            "slow_convergence": "y dominates the last second, residual above tolerance at the end",
        },
        "precedence": [
            "error",
            "diverged",
            "success",
            "deadline_miss",
            "solver_failure",
            "tumbling | minor_axis_spin | wrong_axis | slow_convergence",
        ],
    }
