"""Scenario files: what a run sets up, which variants it compares, and the paper's numbers.

ROS-free. A scenario is a YAML file in ``splitter_bringup/scenarios`` (or any
path). ``variants`` maps a variant name to overrides deep-merged over the base;
the first variant is the main one (the one a plain ``splitter run`` reports
against the paper). ``paper`` holds the paper's numbers; ``findings`` its
qualitative findings, each a comparison of one metric between two variants
(:class:`PaperFinding`), which ``splitter run`` checks on the variants it ran.
``robot_errors`` (optional) makes the simulated robot differ from the nominal one
its controllers assume (:class:`~splitter_sim.core.robot_errors.RobotErrors`:
masses, hemi bodies' inertia, gyro noise and bias, actuator lag), in the graph and the
library loop alike. ``estimator`` (optional) sets the flight estimator's parameters
(:class:`~splitter_mpc.core.estimator.EstimatorConfig`) that the robot's errors ask
for: its sensors' datasheet, and which model parameters it identifies.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from splitter_model.faults import JointFault, faults_from_records
from splitter_model.model import gravity_from_name
from splitter_model.terrain import FLAT, Step, Terrain
from splitter_mpc.core.estimator import EstimatorConfig
from splitter_mpc.core.gait import ATTITUDE_REFERENCE_MODES, GaitConfig
from splitter_mpc.core.ocp import INTEGRATORS, OBJECTIVES
from splitter_mpc.core.solvers import SOLVERS
from splitter_msgs_py.core.parameter_fields import parameter_fields
from splitter_sim.core.robot_errors import RobotErrors
from splitter_sim.core.simulator import SimConfig


class ScenarioError(ValueError):
    """A scenario file that is missing, malformed or out of range (names the field)."""


@dataclass(frozen=True)
class JumpSpec:
    """A planned jump: thrust ``force_n`` (world frame) for ``duration_s`` from ``time_s``.

    ``hemi`` names the Hemi-SPLITTER whose legs push ("a", "b"), or "auto" for
    the one touching the ground (the lower one). The thrust acts through that
    hemi's body, so it also exerts a moment about the centre of mass.
    ``hemi: both`` pushes with both at once, each its own force: in YAML
    ``force_a_n`` and ``force_b_n`` (kept as ``force_n`` and ``force_b_n``); unequal
    forces make a launch that adds rotation (paper III.A). ``couple_n`` [N] (hemi
    "both" or "auto"): each hemi also pushes this across the tether in the horizontal
    plane, in opposite directions, a spin about the vertical whatever the heading
    (``splitter_mpc.core.gait.PlannedJump``).
    The jump starts at the first control tick at or after ``time_s`` when the
    pushing hemi (both, for "both") is in stance.
    """

    time_s: float  # [s]
    force_n: tuple[float, float, float]  # [N] world frame (hemi a's for "both")
    duration_s: float  # [s]
    hemi: str = "auto"
    force_b_n: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [N] world, hemi b's ("both")
    couple_n: float = 0.0  # [N] each hemi's push across the tether (a spin about the vertical)


@dataclass(frozen=True)
class ControllerSpec:
    """Inertial-morphing MPC settings of a scenario (paper Tables I and II)."""

    enabled: bool = True
    w_ref_rad_s: tuple[float, float, float] = (0.0, 1.0, 0.0)  # [rad/s]
    q_w: tuple[float, float, float] = (100.0, 100.0, 100.0)
    r: tuple[float, float, float] = (0.01, 1.0, 1.0)
    q_t: tuple[float, float, float] = (100.0, 10.0, 100.0)
    q_q: float = 0.0
    q_tq: float = 0.0
    # "initial": hold the initial attitude; "integrate_w_ref": attitude reference
    # propagated from the initial attitude with w_ref (the paper's "nonconstant"
    # reference "calculated based on the angular velocity reference");
    # "momentum_aligned": the same, started with the body axis of w_ref turned onto
    # the angular momentum (reachable in torque-free flight; splitter_mpc.core.gait).
    attitude_reference: str = "integrate_w_ref"
    # [rad/s] landing_timed: where no steady spin within the reel's reach times the
    # landing, spin up to this first and back (0: steady spins only;
    # splitter_mpc.core.gait.timed_landing_plan)
    landing_spin_up_rad_s: float = 0.0
    # [s] landing_timed: a spin-up ends at least this long before the predicted touchdown
    landing_spin_up_settle_s: float = 1.5
    # The MPC formulation (splitter_mpc.core.mpc): "paper" weighs w - w_ref over
    # N = 50 x 10 ms (section VI); "momentum" weighs the rate across the reference
    # axis and the reachable spin about it, over a longer prediction step.
    objective: str = "paper"
    horizon: int = 50  # N [steps]
    dt_s: float = 0.01  # [s] prediction step
    integrator: str = "euler"
    # [s] the prediction step the weights are given for (None: per stage, whatever
    # the step); with it the stage weights keep one continuous-time cost on any grid
    weights_step_s: float | None = None
    # [rad/s] supervisory recovery spin (0: off): while the body turns across the
    # reference axis, the MPC is asked for at least this spin about it
    # (splitter_mpc.core.controller.ControllerConfig)
    recovery_spin_rad_s: float = 0.0
    # [-] recovery only for a tumble with |H| / I_e,max < this * |w_ref| (None: any)
    recovery_momentum_ratio_max: float | None = None
    # [-] after a fault, the effort weights R times this (ControllerConfig)
    fault_effort_scale: float = 0.01
    # the MPC's numerical back-end (splitter_mpc.core.solvers.SOLVERS) in the graph and
    # the library loop; `splitter run --solver` and `splitter campaign --solver` override it
    solver: str = "fatrop"


@dataclass(frozen=True)
class PaperFinding:
    """A qualitative finding of the paper as a comparison of one metric between two variants.

    ``expect: A > B`` (or ``<``) in the scenario's ``findings`` list: the finding is
    reproduced when metric(A) > metric(B) on this project's runs.
    """

    statement: str
    metric: str
    variant: str
    relation: str  # ">" or "<"
    other: str

    @property
    def expectation(self) -> str:
        return f"{self.variant} {self.relation} {self.other}"


FINDING_RELATIONS = (">", "<")


@dataclass(frozen=True)
class Scenario:
    """A complete run description."""

    name: str
    description: str
    variant: str
    duration_s: float  # [s]
    gravity_m_s2: float  # [m/s^2]
    sim_dt_s: float  # [s]
    initial_angular_velocity_rad_s: NDArray[np.float64]  # [rad/s] body frame
    initial_orientation_euler_deg: NDArray[np.float64]  # [deg] roll, pitch, yaw (xyz)
    initial_position_m: NDArray[np.float64]  # [m] world frame, centre of mass
    initial_velocity_m_s: NDArray[np.float64]  # [m/s] world frame
    initial_radii_m: NDArray[np.float64]  # [m] r_x, r_y, r_z
    controller: ControllerSpec
    jumps: tuple[JumpSpec, ...]
    ground_contact: bool
    compliant_legs: bool = False  # stance legs under impedance control (splitter_sim.core.legs)
    # [deg] the legs' workspace cone: belly normal to ground normal (SimConfig's field)
    leg_cone_half_angle_deg: float = 60.0
    # [N/m] the legs' ride posture (SimConfig's field; splitter_sim.core.legs "Ride
    # height"): 0, off, the robot stands crouched
    leg_posture_stiffness_n_m: float = 0.0
    # [m] the height the ride posture stands a hemi's lowest mass at (SimConfig's field)
    leg_ride_height_m: float = 0.2
    # the ground (splitter_model.terrain): level z = 0 unless the scenario's ``ground``
    terrain: Terrain = FLAT
    friction_coefficient: float = 0.8  # [-] of the ground (SimConfig's field)
    # joints and the reel that fail in the run (splitter_model.faults); default: none
    faults: tuple[JointFault, ...] = ()
    # the allocator detects faulty joints and re-plans without them (its fault_handling)
    fault_handling: bool = True
    # how the simulated robot differs from the nominal one its controllers assume
    # (masses, gyro noise and bias, actuator lag); default: not at all
    robot_errors: RobotErrors = field(default_factory=RobotErrors)
    # the flight estimator's parameters (the graph's flight_estimator node, the library's
    # estimator), when the robot errors put the controllers on it; default: its defaults
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    paper: Mapping[str, Any] = field(default_factory=dict)
    variants: tuple[str, ...] = ()
    findings: tuple[PaperFinding, ...] = ()
    raw: Mapping[str, Any] = field(default_factory=dict)


def scenario_dir() -> Path:
    """Folder of the scenario files shipped with the project."""
    return Path(str(resources.files("splitter_bringup") / "scenarios"))


def available_scenarios() -> list[str]:
    """Names of the shipped scenarios."""
    return sorted(p.stem for p in scenario_dir().glob("*.yaml"))


def _deep_merge(base: dict[str, Any], override: Mapping[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for key, value in override.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), dict):
            out[key] = _deep_merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _vector(
    data: Mapping[str, Any], key: str, default: list[float] | None = None, size: int = 3
) -> NDArray:
    value = data.get(key, default)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(f"{key}: expected {size} numbers, got {value!r}") from exc
    if arr.shape != (size,) or not np.all(np.isfinite(arr)):
        raise ScenarioError(f"{key}: expected {size} finite numbers, got {value!r}")
    return arr


def _positive(
    data: Mapping[str, Any], key: str, default: float | None = None, *, zero_ok: bool = False
) -> float:
    """``data[key]`` as a finite number > 0 (>= 0 with ``zero_ok``)."""
    value = data.get(key, default)
    try:
        number = float(value)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(f"{key}: expected a number, got {value!r}") from exc
    if not (math.isfinite(number) and (number > 0.0 or (zero_ok and number == 0.0))):
        bound = ">= 0" if zero_ok else "> 0"
        raise ScenarioError(f"{key}: must be finite and {bound}, got {value!r}")
    return number


def _horizon(data: Mapping[str, Any]) -> int:
    value = data.get("horizon", 50)
    if isinstance(value, bool) or not isinstance(value, int) or not 2 <= value <= 1000:
        raise ScenarioError(f"horizon: expected an integer in [2, 1000], got {value!r}")
    return value


def _robot_errors(data: Any) -> RobotErrors:
    """The ``robot_errors`` mapping (fields of :class:`RobotErrors`); errors name the field."""
    if data is None:
        return RobotErrors()
    if not isinstance(data, Mapping):
        raise ScenarioError(f"robot_errors: expected a mapping of field -> value, got {data!r}")
    known = {f.name for f in fields(RobotErrors)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ScenarioError(f"robot_errors.{unknown[0]}: unknown field; use {sorted(known)}")
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
    try:
        return RobotErrors(**values)
    except ValueError as exc:  # names the field first
        raise ScenarioError(f"robot_errors.{exc}") from exc


def _estimator(data: Any) -> EstimatorConfig:
    """The ``estimator`` mapping (parameters of :class:`EstimatorConfig`, checked as the
    node checks them); errors name the field."""
    if data is None:
        return EstimatorConfig()
    if not isinstance(data, Mapping):
        raise ScenarioError(f"estimator: expected a mapping of field -> value, got {data!r}")
    specs = {name: spec for name, _default, spec in parameter_fields(EstimatorConfig)}
    unknown = sorted(set(data) - set(specs))
    if unknown:
        raise ScenarioError(f"estimator.{unknown[0]}: unknown field; use {sorted(specs)}")
    values = {}
    for name, value in data.items():
        try:
            checked = specs[name].validate(value)
        except ValueError as exc:
            raise ScenarioError(f"estimator.{name}: {exc}") from exc
        values[name] = tuple(checked) if isinstance(checked, list) else checked
    return EstimatorConfig(**values)


def _findings(data: Any, variants: tuple[str, ...]) -> tuple[PaperFinding, ...]:
    if data is None:
        return ()
    if not isinstance(data, list):
        raise ScenarioError("findings: expected a list of {statement, metric, expect}")
    out = []
    for i, item in enumerate(data):
        where = f"findings[{i}]"
        if not isinstance(item, Mapping) or set(item) != {"statement", "metric", "expect"}:
            raise ScenarioError(f"{where}: expected exactly the keys statement, metric, expect")
        words = str(item["expect"]).split()
        if len(words) != 3 or words[1] not in FINDING_RELATIONS:
            raise ScenarioError(
                f"{where}.expect: expected 'VARIANT > VARIANT' or 'VARIANT < VARIANT', "
                f"got {item['expect']!r}"
            )
        for name in (words[0], words[2]):
            if name not in variants:
                raise ScenarioError(f"{where}.expect: no variant {name!r} in {list(variants)}")
        out.append(
            PaperFinding(str(item["statement"]), str(item["metric"]), words[0], words[1], words[2])
        )
    return tuple(out)


JUMP_FIELDS = ("time_s", "force_n", "duration_s", "hemi", "couple_n")
BOTH_JUMP_FIELDS = ("time_s", "force_a_n", "force_b_n", "duration_s", "hemi", "couple_n")


def _jumps(data: Any) -> tuple[JumpSpec, ...]:
    """The ``jumps`` list, each entry checked; errors name ``jumps[i].field``."""
    if data is None:
        return ()
    if not isinstance(data, list):
        raise ScenarioError("jumps: expected a list of pushes")
    out: list[JumpSpec] = []
    for i, j in enumerate(data):
        where = f"jumps[{i}]"
        if not isinstance(j, Mapping):
            raise ScenarioError(f"{where}: expected a mapping of {JUMP_FIELDS}")
        hemi = str(j.get("hemi", "auto"))
        if hemi not in ("a", "b", "auto", "both"):
            raise ScenarioError(f"{where}.hemi: must be 'a', 'b', 'auto' or 'both', got {hemi!r}")
        known = BOTH_JUMP_FIELDS if hemi == "both" else JUMP_FIELDS
        unknown = sorted(set(j) - set(known))
        if unknown:
            raise ScenarioError(
                f"{where}.{unknown[0]}: unknown field for hemi {hemi!r}; use {list(known)}"
            )
        try:
            if hemi == "both":
                force = _vector(j, "force_a_n")
                force_b = _vector(j, "force_b_n")
            else:
                force = _vector(j, "force_n")
                force_b = np.zeros(3)
            duration = _positive(j, "duration_s")
            time_s = _finite(j, "time_s", 0.0)
            couple = _finite(j, "couple_n", 0.0)
        except ScenarioError as exc:
            raise ScenarioError(f"{where}.{exc}") from exc
        if couple != 0.0 and hemi not in ("both", "auto"):
            raise ScenarioError(
                f"{where}.couple_n: needs both hemis (hemi 'both' or 'auto'), got hemi {hemi!r}"
            )
        if time_s < 0.0:
            raise ScenarioError(f"{where}.time_s: must be >= 0, got {time_s}")
        if out and time_s < out[-1].time_s + out[-1].duration_s:
            raise ScenarioError(
                f"{where}.time_s: {time_s} s is before the end of jumps[{i - 1}] "
                f"({out[-1].time_s + out[-1].duration_s} s); two hemis pushing at once are "
                "one jump with hemi: both"
            )
        out.append(
            JumpSpec(
                time_s=time_s,
                force_n=(float(force[0]), float(force[1]), float(force[2])),
                duration_s=duration,
                hemi=hemi,
                force_b_n=(float(force_b[0]), float(force_b[1]), float(force_b[2])),
                couple_n=couple,
            )
        )
    return tuple(out)


def _boolean(data: Mapping[str, Any], key: str, default: bool) -> bool:
    value = data.get(key, default)
    if not isinstance(value, bool):
        raise ScenarioError(f"{key}: must be true or false, got {value!r}")
    return value


def _faults(data: Any) -> tuple[JointFault, ...]:
    """The scenario's ``faults``: ``[{joint, kind, time_s}]``; errors name the field."""
    if data is None:
        return ()
    try:
        return faults_from_records(data, "faults")
    except ValueError as exc:
        raise ScenarioError(str(exc)) from None


def _leg_cone(data: Mapping[str, Any]) -> float:
    """``leg_cone_half_angle_deg`` [deg] in [1, 89] (SimConfig's range), default 60."""
    cone = _positive(data, "leg_cone_half_angle_deg", SimConfig.leg_cone_half_angle_deg)
    if not 1.0 <= cone <= 89.0:
        raise ScenarioError(f"leg_cone_half_angle_deg: must be in [1, 89] deg, got {cone!r}")
    return cone


def _leg_posture(data: Mapping[str, Any]) -> float:
    """``leg_posture_stiffness_n_m`` [N/m] in [0, 1e6] (SimConfig's range), default 0 (off)."""
    stiffness = _finite(data, "leg_posture_stiffness_n_m", 0.0)
    if not 0.0 <= stiffness <= 1e6:
        raise ScenarioError(
            f"leg_posture_stiffness_n_m: must be in [0, 1e6] N/m, got {stiffness!r}"
        )
    return stiffness


def _leg_ride_height(data: Mapping[str, Any]) -> float:
    """``leg_ride_height_m`` [m] in [0, the 0.4 m stroke] (SimConfig's range), default 0.2."""
    height = _finite(data, "leg_ride_height_m", SimConfig.leg_ride_height_m)
    if not 0.0 <= height <= SimConfig.thrust_stroke_m:
        raise ScenarioError(
            f"leg_ride_height_m: must be in [0, {SimConfig.thrust_stroke_m:g}] m (within the "
            f"legs' stroke), got {height!r}"
        )
    return height


def _finite(data: Mapping[str, Any], key: str, default: float) -> float:
    value = data.get(key, default)
    try:
        number = float(value)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(f"{key}: expected a number, got {value!r}") from exc
    if not math.isfinite(number):
        raise ScenarioError(f"{key}: expected a finite number, got {value!r}")
    return number


def load_scenario(name_or_path: str | Path, variant: str | None = None) -> Scenario:
    """Load a shipped scenario by name, or a YAML file by path, with one variant applied."""
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = scenario_dir() / f"{name_or_path}.yaml"
    if not path.is_file():
        raise ScenarioError(
            f"scenario {name_or_path!r} not found; shipped: {', '.join(available_scenarios())}"
        )
    with path.open(encoding="utf-8") as stream:
        data = yaml.safe_load(stream)
    if not isinstance(data, dict):
        raise ScenarioError(f"{path}: top level must be a mapping")
    variants: dict[str, Any] = data.pop("variants", None) or {"default": {}}
    if not isinstance(variants, dict):
        raise ScenarioError(f"{path}: variants must be a mapping of name -> overrides")
    chosen = variant or next(iter(variants))
    if chosen not in variants:
        raise ScenarioError(f"variant {chosen!r} not in {list(variants)}")
    merged = _deep_merge(data, variants[chosen] or {})
    return _from_dict(merged, chosen, tuple(variants), path.stem)


SCENARIO_FIELDS = (
    "name",
    "description",
    "duration_s",
    "gravity",
    "sim_dt_s",
    "ground_contact",
    "compliant_legs",
    "leg_cone_half_angle_deg",
    "leg_posture_stiffness_n_m",
    "leg_ride_height_m",
    "ground",
    "initial",
    "controller",
    "jumps",
    "paper",
    "findings",
    "robot_errors",
    "estimator",
    "faults",
    "fault_handling",
)
INITIAL_FIELDS = (
    "angular_velocity_rad_s",
    "orientation_euler_deg",
    "position_m",
    "velocity_m_s",
    "radii_m",
)
CONTROLLER_FIELDS = (
    "enabled",
    "w_ref_rad_s",
    "q_w",
    "r",
    "q_t",
    "q_q",
    "q_tq",
    "attitude_reference",
    "landing_spin_up_rad_s",
    "landing_spin_up_settle_s",
    "objective",
    "horizon",
    "dt_s",
    "integrator",
    "weights_step_s",
    "recovery_spin_rad_s",
    "recovery_momentum_ratio_max",
    "fault_effort_scale",
    "solver",
)


GROUND_FIELDS = ("slope_deg", "slope_azimuth_deg", "friction_coefficient", "steps")
STEP_FIELDS = ("x_m", "y_m", "height_m")
# [m] the limbs' reach beyond the hemi bodies: a step within the tether's half length
# plus this of the start would be under the standing robot
START_CLEARANCE_M = 0.6


def _ground(data: Any) -> tuple[Terrain, float]:
    """The scenario's ``ground``: (terrain, friction coefficient); errors name the field."""
    ground = _known_fields(data, "ground", GROUND_FIELDS)
    friction = _finite(ground, "friction_coefficient", SimConfig.friction_coefficient)
    if not 0.0 <= friction <= 10.0:
        raise ScenarioError(f"ground.friction_coefficient: must be in [0, 10], got {friction}")
    raw_steps = ground.get("steps") or []
    if not isinstance(raw_steps, list):
        raise ScenarioError(f"ground.steps: expected a list, got {raw_steps!r}")
    steps = []
    for i, raw in enumerate(raw_steps):
        where = f"ground.steps[{i}]"
        step = _known_fields(raw, where, STEP_FIELDS)
        try:
            x = _vector(step, "x_m", None, 2)
            y = _vector(step, "y_m", None, 2)
            height = _finite(step, "height_m", math.nan)
            steps.append(Step(float(x[0]), float(x[1]), float(y[0]), float(y[1]), height))
        except (ScenarioError, ValueError) as exc:
            raise ScenarioError(f"{where}.{exc}") from exc
    try:
        slope = _finite(ground, "slope_deg", 0.0)
        azimuth = _finite(ground, "slope_azimuth_deg", 0.0)
        terrain = Terrain(slope, azimuth, tuple(steps))
    except (ScenarioError, ValueError) as exc:
        raise ScenarioError(f"ground.{exc}") from exc
    return terrain, friction


def _clear_start(terrain: Terrain, position_m: NDArray, radii_m: NDArray) -> None:
    """A step under the standing robot (within the tether's half length plus the limbs'
    reach of its start) is an error naming it."""
    reach = float(radii_m[0]) + START_CLEARANCE_M
    for i, step in enumerate(terrain.steps):
        if step.footprint_distance_m(float(position_m[0]), float(position_m[1])) < reach:
            raise ScenarioError(
                f"ground.steps[{i}]: overlaps the start (within {reach:.2f} m of the initial "
                f"position {position_m[:2].tolist()}: the tether's half length plus the limbs)"
            )


def pose_on_terrain(
    terrain: Terrain, position_m: NDArray, velocity_m_s: NDArray, euler_deg: NDArray
) -> tuple[NDArray, NDArray, NDArray]:
    """The initial pose given in the ground's frame at the start, in the world.

    ``position_m``: x, y the world's, z the height along the ground's normal above the
    base plane there; the velocity and the orientation (extrinsic xyz Euler angles)
    are the ground frame's (:meth:`Terrain.ground_frame`). On level ground: unchanged.
    """
    if terrain.slope_deg == 0.0:
        return position_m, velocity_m_s, euler_deg
    frame = terrain.ground_frame()
    x, y, z = (float(v) for v in position_m)
    world = np.array([x, y, terrain.base_height_m(x, y)]) + z * np.asarray(terrain.normal)
    rotation = Rotation.from_matrix(frame) * Rotation.from_euler("xyz", euler_deg, degrees=True)
    return world, frame @ velocity_m_s, rotation.as_euler("xyz", degrees=True)


def _known_fields(data: Any, where: str, known: tuple[str, ...]) -> Mapping[str, Any]:
    """``data`` (a mapping, None: empty) whose keys are all ``known``; a typo is an error
    naming it (a misspelt field would otherwise silently take its default)."""
    if data is None:
        return {}
    if not isinstance(data, Mapping):
        raise ScenarioError(f"{where}: expected a mapping, got {data!r}")
    unknown = sorted(set(data) - set(known))
    if unknown:
        prefix = f"{where}." if where else ""
        raise ScenarioError(f"{prefix}{unknown[0]}: unknown field; use {sorted(known)}")
    return data


def _from_dict(d: dict[str, Any], variant: str, variants: tuple[str, ...], stem: str) -> Scenario:
    _known_fields(d, "", SCENARIO_FIELDS)
    initial = _known_fields(d.get("initial"), "initial", INITIAL_FIELDS)
    ctrl = _known_fields(d.get("controller"), "controller", CONTROLLER_FIELDS)
    try:
        gravity = gravity_from_name(d.get("gravity", "zero"))
    except ValueError as exc:
        raise ScenarioError(f"gravity: {exc}") from exc
    controller = ControllerSpec(
        enabled=bool(ctrl.get("enabled", True)),
        w_ref_rad_s=tuple(_vector(ctrl, "w_ref_rad_s", [0.0, 1.0, 0.0])),
        q_w=tuple(_vector(ctrl, "q_w", [100.0, 100.0, 100.0])),
        r=tuple(_vector(ctrl, "r", [0.01, 1.0, 1.0])),
        q_t=tuple(_vector(ctrl, "q_t", [100.0, 10.0, 100.0])),
        q_q=float(ctrl.get("q_q", 0.0)),
        q_tq=float(ctrl.get("q_tq", 0.0)),
        attitude_reference=str(ctrl.get("attitude_reference", "integrate_w_ref")),
        landing_spin_up_rad_s=_positive(ctrl, "landing_spin_up_rad_s", 0.0, zero_ok=True),
        landing_spin_up_settle_s=_positive(ctrl, "landing_spin_up_settle_s", 1.5, zero_ok=True),
        objective=str(ctrl.get("objective", "paper")),
        horizon=_horizon(ctrl),
        dt_s=_positive(ctrl, "dt_s", 0.01),
        integrator=str(ctrl.get("integrator", "euler")),
        weights_step_s=(
            None if ctrl.get("weights_step_s") is None else _positive(ctrl, "weights_step_s")
        ),
        recovery_spin_rad_s=_positive(ctrl, "recovery_spin_rad_s", 0.0, zero_ok=True),
        recovery_momentum_ratio_max=(
            None
            if ctrl.get("recovery_momentum_ratio_max") is None
            else _positive(ctrl, "recovery_momentum_ratio_max")
        ),
        fault_effort_scale=_positive(ctrl, "fault_effort_scale", 0.01),
        solver=str(ctrl.get("solver", "fatrop")),
    )
    if not 1.0e-3 <= controller.fault_effort_scale <= 1.0:
        raise ScenarioError(
            f"controller.fault_effort_scale: must be in [0.001, 1], got "
            f"{controller.fault_effort_scale}"
        )
    gait_specs = {name: spec for name, _default, spec in parameter_fields(GaitConfig)}
    for name in ("landing_spin_up_rad_s", "landing_spin_up_settle_s"):
        try:
            gait_specs[name].validate(getattr(controller, name))
        except ValueError as exc:
            raise ScenarioError(f"controller.{name}: {exc}") from exc
    if controller.objective not in OBJECTIVES:
        raise ScenarioError(f"controller.objective: use one of {OBJECTIVES}")
    if controller.integrator not in INTEGRATORS:
        raise ScenarioError(f"controller.integrator: use one of {INTEGRATORS}")
    if controller.solver not in SOLVERS:
        raise ScenarioError(f"controller.solver: use one of {SOLVERS}")
    if controller.attitude_reference not in ATTITUDE_REFERENCE_MODES:
        raise ScenarioError(f"controller.attitude_reference: use one of {ATTITUDE_REFERENCE_MODES}")
    jumps = _jumps(d.get("jumps"))
    terrain, friction = _ground(d.get("ground"))
    radii = _vector(initial, "radii_m", [2.8, 0.2, 0.2])
    position, velocity, euler = pose_on_terrain(
        terrain,
        _vector(initial, "position_m", [0.0, 0.0, 0.0]),
        _vector(initial, "velocity_m_s", [0.0] * 3),
        _vector(initial, "orientation_euler_deg", [0.0] * 3),
    )
    _clear_start(terrain, position, radii)
    if terrain.slope_deg != 0.0:  # the pushes as the ground frame states them
        frame = terrain.ground_frame()
        jumps = [
            replace(
                j,
                force_n=tuple((frame @ np.asarray(j.force_n)).tolist()),
                force_b_n=tuple((frame @ np.asarray(j.force_b_n)).tolist()),
            )
            for j in jumps
        ]
    return Scenario(
        name=str(d.get("name", stem)),
        description=str(d.get("description", "")),
        variant=variant,
        duration_s=_positive(d, "duration_s"),
        gravity_m_s2=gravity,
        sim_dt_s=_positive(d, "sim_dt_s", 0.005),
        initial_angular_velocity_rad_s=_vector(initial, "angular_velocity_rad_s", [0.0] * 3),
        initial_orientation_euler_deg=euler,
        initial_position_m=position,
        initial_velocity_m_s=velocity,
        initial_radii_m=radii,
        controller=controller,
        jumps=tuple(jumps),
        ground_contact=bool(d.get("ground_contact", False)),
        compliant_legs=bool(d.get("compliant_legs", False)),
        leg_cone_half_angle_deg=_leg_cone(d),
        leg_posture_stiffness_n_m=_leg_posture(d),
        leg_ride_height_m=_leg_ride_height(d),
        terrain=terrain,
        friction_coefficient=friction,
        faults=_faults(d.get("faults")),
        fault_handling=_boolean(d, "fault_handling", True),
        robot_errors=_robot_errors(d.get("robot_errors")),
        estimator=_estimator(d.get("estimator")),
        paper=dict(d.get("paper", {}) or {}),
        variants=variants,
        findings=_findings(d.get("findings"), variants),
        raw=d,
    )
