"""Monte-Carlo campaigns of a jumping scenario: random launches and robots, landings judged.

ROS-free; the algorithm of ``splitter campaign lunar_jumping`` (issue 26;
:mod:`splitter_bringup.cli.jump_campaign` runs it on Dask). The tumble campaign of a
spinning scenario is :mod:`.campaign`; both share the seeds (:func:`.campaign.draw_seeds`),
the Wilson interval and the Dask executor.

Draws. Draw ``i`` of a campaign with seed ``S`` has its own integer seed (that of
:func:`.campaign.draw_seeds`), and everything it varies is a pure function of it
(:func:`make_jump_draw`), in this order from ``numpy.random.default_rng(seed)``:

1. the launch spin: the couple of a ``hemi: both`` push, ``(f_a - f_b) / 2``, scaled
   by a factor uniform in ``1 +- spin_fraction`` (the common part ``(f_a + f_b) / 2``
   kept); for each planned jump and each hemi (a, then b):
2. the push's magnitude, a factor uniform in ``1 +- push_fraction``, and its direction,
   turned by an angle uniform in ``[0, push_tilt_deg]`` towards a uniform azimuth
   around it (:func:`tilted_push`; a shared push, ``auto``, becomes each hemi's half,
   ``both``);
3. the simulated robot: ``m_x, m_y, m_z`` each scaled uniform in ``1 +- mass_fraction``
   (so the inertia), a gyro noise uniform in ``[0, gyro_noise_rad_s]``, a gyro bias
   uniform in ``+-gyro_bias_rad_s`` per axis, a command latency uniform in
   ``[0, command_latency_s]``, and the seed of the sensor noise;
4. the terrain (drawn last, so a draw's other numbers do not depend on it): a slope
   uniform in ``[0, slope_deg]`` rising towards a uniform azimuth, and a step across
   the path (the robot jumps along world +x): a raised plane of height uniform in
   ``[0, step_height_m]`` beyond an edge at x uniform in ``STEP_EDGE_RANGE_M`` (before
   the first landing, under it, between the hemis of a landing, after it). On a
   slope the base scenario's initial pose and pushes are the ground frame's
   (:func:`splitter_bringup.scenario.definition.pose_on_terrain`).

The step range is narrowed (issue 26 allows it where a range is physically out of
reach; the success rule is not loosened). Issue 26 asks for steps up to 0.2 m; the
default is ``STEP_REACH_M`` (6 cm). A hemi touching down at the nominal 3.63 m/s
(``NOMINAL_TOUCHDOWN_SPEED_M_S``) is stopped within the legs' 190 N cap in no less
than 0.338 m of their 0.4 m stroke, so its lowest mass comes down to 0.062 m above
the ground or lower, whatever the leg law
(:func:`splitter_sim.core.legs.stroke_left_after_stop_m`). Meanwhile it travels on at
1-3 m/s (0.2-0.6 m in the stop). A step higher than that whose edge falls there is
struck by the body: a hard impact no controller avoids (the campaigns with each
range: README "Random jumps"). ``--step-height 0.2`` flies the issue's range.

The controllers know the nominal robot and fly on the flight estimator (issue 27);
the scenario's other robot errors (effort, range, load-cell and accelerometer noise,
actuator lag), if it has any, are kept. Every draw flies every variant of the
scenario (``mpc`` and ``open_loop``) on the same draw.

Success of a variant's flight (:func:`classify_landing`), all of:

* LANDED (the gait's final phase: at rest on both hemis) by the end of the run;
* every ground contact within ``FORCE_LIMIT_N`` per hemi over the whole run (the
  limbs' dynamic limit, paper VII.C: 20 kg at 1 G);
* every touchdown on the legs (:mod:`.touchdowns`);
* no lumped mass on the ground (``body_ground_contact_s`` = 0).

Failure modes, the first that applies, in this order:

* ``error``: the run raised (the message is kept);
* ``cartwheel``: the tether rose more than ``CARTWHEEL_TILT_DEG`` from the ground at
  some time: the dumbbell turned end over end;
* ``on_its_side``: a touchdown came down with the legs outside their workspace cone
  (on a side, or on the back);
* ``hard_impact``: a contact above ``FORCE_LIMIT_N``, or a lumped mass on the ground;
* ``no_landing``: the jumps were not all pushed, or the robot is not on both hemis at
  the end;
* ``slow_to_rest``: on both hemis at the end, every contact soft, yet not LANDED.

Statistics per variant: the success rate with its 95 % Wilson interval, the counts
per failure mode, and the rate against each randomized factor
(:func:`binned_success`). The time the tether lay on the terrain is reported per
draw (``tether_ground_contact_s``), not judged.
"""

from __future__ import annotations

import copy
import csv
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from splitter_bringup.analysis.campaign import wilson_interval
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.analysis.summary import variant_metrics
from splitter_bringup.scenario.definition import JumpSpec, Scenario, pose_on_terrain
from splitter_model.terrain import SLOPE_MAX_DEG, STEP_HEIGHT_MAX_M, Step, Terrain
from splitter_sim.core.robot_errors import RobotErrors

FORCE_LIMIT_N = 196.133  # [N] per hemi: 20 kg at 1 G, the limbs' dynamic limit (VII.C)
CARTWHEEL_TILT_DEG = 45.0  # [deg] tether above this from the ground: end over end
# [m] where a draw's step edge falls along the path: past the start's 3.4 m clearance
# (scenario.definition.START_CLEARANCE_M plus the tether's half length), up to the
# nominal second landing (~17 m on lunar_jumping)
STEP_EDGE_RANGE_M = (4.0, 16.0)
# [m/s] lunar_jumping's nominal touchdown along the legs (README "The whole stroke")
NOMINAL_TOUCHDOWN_SPEED_M_S = 3.63
# [m] the default step range (module docstring): the stroke a 9 kg hemi keeps under it,
# stopped from the nominal touchdown within the legs' 190 N cap on the Moon, 0.062 m
STEP_REACH_M = 0.06
STEP_HALF_WIDTH_M = 50.0  # [m] the step spans the path sideways
STEP_DEPTH_M = 100.0  # [m] and reaches beyond the run's end
VARIANTS = ("mpc", "open_loop")

SUCCESS = "success"
FAILURE_MODES = (
    "error",
    "cartwheel",
    "on_its_side",
    "hard_impact",
    "no_landing",
    "slow_to_rest",
)
OUTCOMES = (SUCCESS, *FAILURE_MODES)


# --- draws ------------------------------------------------------------------------------
@dataclass(frozen=True)
class JumpRanges:
    """How widely a jumping campaign randomizes each draw (module docstring, 0: off)."""

    push_fraction: float = 0.1  # [-] each hemi's push magnitude within 1 +- this
    push_tilt_deg: float = 10.0  # [deg] each hemi's push direction within this cone
    spin_fraction: float = 0.25  # [-] the launch couple within 1 +- this
    mass_fraction: float = 0.1  # [-] m_x, m_y, m_z each within 1 +- this
    gyro_noise_rad_s: float = 0.004  # [rad/s] noise std drawn in [0, this]
    gyro_bias_rad_s: float = 0.005  # [rad/s] bias drawn in +- this per axis
    command_latency_s: float = 0.02  # [s] drawn in [0, this]
    slope_deg: float = 10.0  # [deg] the ground's slope drawn in [0, this]
    step_height_m: float = STEP_REACH_M  # [m] a step across the path drawn in [0, this]

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        for name in ("push_fraction", "spin_fraction", "mass_fraction"):
            if getattr(self, name) >= 1.0:
                raise ValueError(f"{name} must be < 1, got {getattr(self, name)!r}")
        if self.push_tilt_deg >= 90.0:
            raise ValueError(f"push_tilt_deg must be < 90, got {self.push_tilt_deg!r}")
        if self.slope_deg > SLOPE_MAX_DEG:
            raise ValueError(f"slope_deg must be <= {SLOPE_MAX_DEG}, got {self.slope_deg!r}")
        if self.step_height_m > STEP_HEIGHT_MAX_M:
            raise ValueError(
                f"step_height_m must be <= {STEP_HEIGHT_MAX_M}, got {self.step_height_m!r}"
            )


@dataclass(frozen=True)
class JumpDraw:
    """One random world of a jumping campaign: its pushes and its robot."""

    index: int
    seed: int  # the draw's own seed: replays it alone
    spin_scale: float  # [-] factor on the launch couple
    push_scale: tuple[tuple[float, float], ...]  # [-] per jump, (hemi a, hemi b)
    push_tilt_deg: tuple[tuple[float, float], ...]  # [deg] per jump, (a, b)
    push_azimuth_deg: tuple[tuple[float, float], ...]  # [deg] tilt axis azimuth, (a, b)
    mass_scale: tuple[float, float, float]  # [-] m_x, m_y, m_z
    gyro_noise_rad_s: float  # [rad/s]
    gyro_bias_rad_s: tuple[float, float, float]  # [rad/s] body frame
    command_latency_s: float  # [s]
    noise_seed: int
    slope_deg: float = 0.0  # [deg]
    slope_azimuth_deg: float = 0.0  # [deg] direction of the rise, from world x
    step_height_m: float = 0.0  # [m] 0: no step
    step_edge_m: float = math.inf  # [m] world x of the step's edge

    @property
    def terrain(self) -> Terrain:
        """The draw's ground (module docstring)."""
        steps = ()
        if self.step_height_m > 0.0:
            edge = self.step_edge_m
            steps = (
                Step(edge, edge + STEP_DEPTH_M, -STEP_HALF_WIDTH_M, STEP_HALF_WIDTH_M,
                     self.step_height_m),
            )  # fmt: skip
        return Terrain(self.slope_deg, self.slope_azimuth_deg, steps)

    def factors(self) -> dict[str, float]:
        """The draw's randomized numbers as scalars (the CSV columns and the figures)."""
        scales = np.asarray(self.push_scale, dtype=float)
        tilts = np.asarray(self.push_tilt_deg, dtype=float)
        return {
            "spin_scale": self.spin_scale,
            "push_scale_min": float(scales.min()) if scales.size else 1.0,
            "push_scale_max": float(scales.max()) if scales.size else 1.0,
            "push_scale_imbalance": float(np.abs(scales[:, 0] - scales[:, 1]).max())
            if scales.size
            else 0.0,
            "push_tilt_max_deg": float(tilts.max()) if tilts.size else 0.0,
            "mass_scale_min": min(self.mass_scale),
            "mass_scale_max": max(self.mass_scale),
            "gyro_noise_rad_s": self.gyro_noise_rad_s,
            "gyro_bias_max_rad_s": float(np.abs(self.gyro_bias_rad_s).max()),
            "command_latency_s": self.command_latency_s,
            "slope_deg": self.slope_deg,
            # [deg] the slope's rise along the path (+x): negative, downhill
            "slope_along_path_deg": self.slope_deg * math.cos(math.radians(self.slope_azimuth_deg)),
            "step_height_m": self.step_height_m,
            "step_edge_m": self.step_edge_m if self.step_height_m > 0.0 else math.nan,
        }


def make_jump_draw(index: int, seed: int, jumps: int, ranges: JumpRanges) -> JumpDraw:
    """Draw ``index`` of a plan of ``jumps`` jumps from its own ``seed`` (docstring order)."""
    rng = np.random.default_rng(int(seed))
    r = ranges
    spin = 1.0 + r.spin_fraction * float(rng.uniform(-1.0, 1.0))
    scales, tilts, azimuths = [], [], []
    for _ in range(jumps):
        per_hemi = [
            (
                1.0 + r.push_fraction * float(rng.uniform(-1.0, 1.0)),
                r.push_tilt_deg * float(rng.uniform(0.0, 1.0)),
                360.0 * float(rng.uniform(0.0, 1.0)),
            )
            for _hemi in range(2)
        ]
        scales.append((per_hemi[0][0], per_hemi[1][0]))
        tilts.append((per_hemi[0][1], per_hemi[1][1]))
        azimuths.append((per_hemi[0][2], per_hemi[1][2]))
    mass = 1.0 + r.mass_fraction * rng.uniform(-1.0, 1.0, 3)
    noise = r.gyro_noise_rad_s * float(rng.uniform(0.0, 1.0))
    bias = r.gyro_bias_rad_s * rng.uniform(-1.0, 1.0, 3) + 0.0
    latency = r.command_latency_s * float(rng.uniform(0.0, 1.0))
    noise_seed = int(rng.integers(0, 2**31 - 1))
    slope = r.slope_deg * float(rng.uniform(0.0, 1.0))
    slope_azimuth = 360.0 * float(rng.uniform(0.0, 1.0))
    step_height = r.step_height_m * float(rng.uniform(0.0, 1.0))
    step_edge = float(rng.uniform(*STEP_EDGE_RANGE_M))
    return JumpDraw(
        index=int(index),
        seed=int(seed),
        spin_scale=spin,
        push_scale=tuple(scales),
        push_tilt_deg=tuple(tilts),
        push_azimuth_deg=tuple(azimuths),
        mass_scale=(float(mass[0]), float(mass[1]), float(mass[2])),
        gyro_noise_rad_s=noise,
        gyro_bias_rad_s=(float(bias[0]), float(bias[1]), float(bias[2])),
        command_latency_s=latency,
        noise_seed=noise_seed,
        slope_deg=slope,
        slope_azimuth_deg=slope_azimuth,
        step_height_m=step_height,
        step_edge_m=step_edge,
    )


def tilted_push(
    force_n: Sequence[float], scale: float, tilt_deg: float, azimuth_deg: float
) -> tuple[float, float, float]:
    """``force_n`` [N] scaled by ``scale`` and its direction turned by ``tilt_deg`` towards
    the azimuth ``azimuth_deg`` on the cone around it (measured from the horizontal
    direction across the push, or from world y for a vertical push)."""
    f = scale * np.asarray(force_n, dtype=float)
    norm = float(np.linalg.norm(f))
    if norm == 0.0 or tilt_deg == 0.0:
        return (float(f[0]), float(f[1]), float(f[2]))
    direction = f / norm
    across = np.cross([0.0, 0.0, 1.0], direction)
    if np.linalg.norm(across) < 1e-9:
        across = np.array([0.0, 1.0, 0.0])
    u1 = across / np.linalg.norm(across)
    u2 = np.cross(direction, u1)
    az = math.radians(azimuth_deg)
    axis = math.cos(az) * u1 + math.sin(az) * u2
    turned = Rotation.from_rotvec(axis * math.radians(tilt_deg)).apply(f)
    return (float(turned[0]), float(turned[1]), float(turned[2]))


def jumps_for_draw(jumps: Sequence[JumpSpec], draw: JumpDraw) -> tuple[JumpSpec, ...]:
    """The draw's pushes: every jump as each hemi's own push (``hemi: both``).

    A single-hemi push keeps its hemi and takes hemi a's numbers when it is a's, b's
    when it is b's; a shared push (``auto``) becomes each hemi's half; a launch's
    couple (the difference of its hemis' forces, or its ``couple_n``) is scaled by
    ``spin_scale``.
    """
    out = []
    for k, jump in enumerate(jumps):
        (sa, sb), (ta, tb), (za, zb) = (
            draw.push_scale[k],
            draw.push_tilt_deg[k],
            draw.push_azimuth_deg[k],
        )
        if jump.hemi in ("a", "b"):
            s, t, z = (sa, ta, za) if jump.hemi == "a" else (sb, tb, zb)
            out.append(replace(jump, force_n=tilted_push(jump.force_n, s, t, z)))
            continue
        if jump.hemi == "both":
            fa, fb = np.asarray(jump.force_n, float), np.asarray(jump.force_b_n, float)
            common, couple = 0.5 * (fa + fb), 0.5 * (fa - fb) * draw.spin_scale
            fa, fb = common + couple, common - couple
        else:  # auto: each hemi's legs push half
            fa = fb = 0.5 * np.asarray(jump.force_n, float)
        out.append(
            JumpSpec(
                time_s=jump.time_s,
                force_n=tilted_push(fa, sa, ta, za),
                duration_s=jump.duration_s,
                hemi="both",
                force_b_n=tilted_push(fb, sb, tb, zb),
                couple_n=jump.couple_n * draw.spin_scale,
            )
        )
    return tuple(out)


def robot_errors_for_jump_draw(base: RobotErrors, draw: JumpDraw) -> RobotErrors:
    """The scenario's robot errors with the draw's masses, gyro and latency."""
    return replace(
        base,
        mass_scale=draw.mass_scale,
        gyro_noise_rad_s=draw.gyro_noise_rad_s,
        gyro_bias_rad_s=draw.gyro_bias_rad_s,
        command_latency_s=draw.command_latency_s,
        noise_seed=draw.noise_seed,
    )


def scenario_for_jump_draw(base: Scenario, draw: JumpDraw) -> Scenario:
    """``base`` (one variant, on level ground) flown in the draw's world.

    On the draw's terrain the base's initial pose and pushes are the ground frame's
    (as a scenario with ``ground`` states them). ValueError when the draw has a
    terrain and the base scenario one of its own.
    """
    terrain = draw.terrain
    jumps = jumps_for_draw(base.jumps, draw)
    if terrain.flat:
        return replace(
            base, jumps=jumps, robot_errors=robot_errors_for_jump_draw(base.robot_errors, draw)
        )
    if not base.terrain.flat:
        raise ValueError(
            f"scenario {base.name!r} has a ground of its own: run its campaign with "
            "--slope 0 --step-height 0"
        )
    position, velocity, euler = pose_on_terrain(
        terrain,
        np.asarray(base.initial_position_m, dtype=float),
        np.asarray(base.initial_velocity_m_s, dtype=float),
        np.asarray(base.initial_orientation_euler_deg, dtype=float),
    )
    frame = terrain.ground_frame()
    return replace(
        base,
        jumps=tuple(
            replace(
                j,
                force_n=tuple((frame @ np.asarray(j.force_n)).tolist()),
                force_b_n=tuple((frame @ np.asarray(j.force_b_n)).tolist()),
            )
            for j in jumps
        ),
        robot_errors=robot_errors_for_jump_draw(base.robot_errors, draw),
        terrain=terrain,
        initial_position_m=position,
        initial_velocity_m_s=velocity,
        initial_orientation_euler_deg=euler,
    )


def _overrides(base: Mapping[str, Any], other: Mapping[str, Any]) -> dict[str, Any]:
    """What ``other`` changes of ``base`` (nested mappings compared key by key)."""
    out: dict[str, Any] = {}
    for key, value in other.items():
        mine = base.get(key)
        if isinstance(value, Mapping) and isinstance(mine, Mapping):
            nested = _overrides(mine, value)
            if nested:
                out[key] = nested
        elif value != mine:
            out[key] = copy.deepcopy(value)
    return out


def ground_document(terrain: Terrain) -> dict[str, Any]:
    """A scenario file's ``ground`` of ``terrain``."""
    return {
        "slope_deg": terrain.slope_deg,
        "slope_azimuth_deg": terrain.slope_azimuth_deg,
        "steps": [
            {"x_m": [s.x_min_m, s.x_max_m], "y_m": [s.y_min_m, s.y_max_m], "height_m": s.height_m}
            for s in terrain.steps
        ],
    }


def jump_scenario_document(variants: Mapping[str, Scenario], draw: JumpDraw) -> dict[str, Any]:
    """A scenario file (YAML mapping) of the draw with every variant of ``variants`` (the
    first is the base): ``splitter run FILE`` flies the draw as the campaign did."""
    first = next(iter(variants.values()))
    flown = scenario_for_jump_draw(first, draw)
    doc: dict[str, Any] = copy.deepcopy(dict(first.raw))
    doc.pop("findings", None)
    doc["description"] = f"Campaign draw {draw.index} (seed {draw.seed}) of {first.name}."
    if not flown.terrain.flat:  # the pushes as the ground frame's, as the file states them
        doc["ground"] = ground_document(flown.terrain)
        flown = replace(flown, jumps=jumps_for_draw(first.jumps, draw))
    doc["jumps"] = [
        {
            "time_s": j.time_s,
            "hemi": j.hemi,
            **(
                {"force_a_n": list(j.force_n), "force_b_n": list(j.force_b_n)}
                if j.hemi == "both"
                else {"force_n": list(j.force_n)}
            ),
            "duration_s": j.duration_s,
            **({"couple_n": j.couple_n} if j.couple_n else {}),
        }
        for j in flown.jumps
    ]
    doc["robot_errors"] = {
        k: list(v) if isinstance(v, tuple) else v for k, v in asdict(flown.robot_errors).items()
    }
    doc["variants"] = {
        name: _overrides(first.raw, scenario.raw) for name, scenario in variants.items()
    }
    return doc


# --- one flight -------------------------------------------------------------------------
@dataclass(frozen=True)
class LandingOutcome:
    """A variant's flight of a draw, judged (module docstring)."""

    success: bool
    failure_mode: str | None
    peak_contact_force_n: float = math.nan  # [N] largest per hemi over the run
    touchdowns: int = 0
    touchdowns_on_legs: int = 0
    body_ground_contact_s: float = math.nan  # [s]
    tether_ground_contact_s: float = math.nan  # [s] the tether on the terrain (reported)
    landed_at_s: float = math.nan  # [s] NaN: never LANDED
    max_tether_tilt_deg: float = math.nan  # [deg]
    peak_w_rad_s: float = math.nan  # [rad/s]
    touchdown_w_rad_s: float = math.nan  # [rad/s] largest |w| the ground met
    touchdown_tether_tilt_deg: float = math.nan  # [deg] largest at a touchdown
    mpc_failures: int = 0
    error: str = ""

    @property
    def outcome(self) -> str:
        return SUCCESS if self.success else str(self.failure_mode)


def tether_tilt_deg(
    orientation_wxyz: NDArray[np.float64],
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0),
) -> NDArray[np.float64]:
    """The tether axis (body x) above the ground plane of ``normal`` [deg], per sample.

    Body x in the world is the first column of R: ``(1 - 2 (q_y^2 + q_z^2),
    2 (q_x q_y + q_w q_z), 2 (q_x q_z - q_w q_y))`` of the unit quaternion.
    """
    q = np.asarray(orientation_wxyz, dtype=float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    up = 2.0 * (x * z - w * y)
    if normal[0] != 0.0 or normal[1] != 0.0:
        body_x = np.stack([1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), up], axis=1)
        up = body_x @ np.asarray(normal, dtype=float)
    return np.degrees(np.arcsin(np.clip(np.abs(up), 0.0, 1.0)))


def _value(metrics: Mapping[str, Any], name: str, default: float = math.nan) -> float:
    metric = metrics.get(name)
    if metric is None:
        return default
    try:
        return float(metric.value)
    except (TypeError, ValueError):
        return default


def failure_mode(
    *,
    landed: bool,
    peak_force_n: float,
    body_contact_s: float,
    touchdowns: int,
    touchdowns_on_legs: int,
    legs_tilts_deg: Sequence[float],
    cone_deg: float,
    max_tether_tilt_deg: float,
    jumps_left: int,
    both_down: bool,
) -> str | None:
    """The failure mode of a flight (None: a success), by the module docstring's rules.

    ``peak_force_n`` is the largest ground force on either hemi [N] over the run,
    ``body_contact_s`` how long a lumped mass was on the ground [s], ``legs_tilts_deg``
    the legs' tilt from the ground normal at each touchdown, ``jumps_left`` the
    planned jumps never pushed and ``both_down`` whether both hemis stand at the end.
    """
    soft = peak_force_n <= FORCE_LIMIT_N and body_contact_s == 0.0
    if landed and soft and touchdowns_on_legs == touchdowns:
        return None
    if max_tether_tilt_deg > CARTWHEEL_TILT_DEG:
        return "cartwheel"
    if any(t > cone_deg for t in legs_tilts_deg if math.isfinite(t)):
        return "on_its_side"
    if not soft or touchdowns_on_legs < touchdowns:
        return "hard_impact"
    if jumps_left > 0 or not both_down:
        return "no_landing"
    return "slow_to_rest"


def classify_landing(series: RunSeries, scenario: Scenario, cone_deg: float) -> LandingOutcome:
    """Judge one variant's flight of a draw (module docstring)."""
    metrics = variant_metrics(series, scenario)
    force = max(
        _value(metrics, "peak_contact_force_a_n", 0.0),
        _value(metrics, "peak_contact_force_b_n", 0.0),
    )
    touchdowns = int(_value(metrics, "touchdowns", 0.0))
    on_legs = int(_value(metrics, "touchdowns_on_legs", 0.0))
    body_s = _value(metrics, "body_ground_contact_s", 0.0)
    landed_at = _value(metrics, "landed_at_s")
    tilts = tether_tilt_deg(np.asarray(series.orientation_wxyz), scenario.terrain.normal)
    max_tilt = float(np.max(tilts, initial=0.0))
    w = np.linalg.norm(np.asarray(series.angular_velocity_rad_s, dtype=float), axis=1)
    legs_tilts = [_value(metrics, f"touchdown_{k}_legs_tilt_deg") for k in range(1, touchdowns + 1)]
    td_w = [_value(metrics, f"touchdown_{k}_w_rad_s") for k in range(1, touchdowns + 1)]
    td_tilt = [_value(metrics, f"touchdown_{k}_tether_tilt_deg") for k in range(1, touchdowns + 1)]
    landed = series.gait_phase[-1] == "LANDED" if len(series) else False
    jumps_done = int(_value(metrics, "jumps_done", 0.0))
    contact = series.extras.get("contact_force_n")
    both_down = bool(
        contact is not None and np.all(np.linalg.norm(np.asarray(contact)[-1], axis=1) > 1.0)
    )
    mode = failure_mode(
        landed=landed,
        peak_force_n=force,
        body_contact_s=body_s,
        touchdowns=touchdowns,
        touchdowns_on_legs=on_legs,
        legs_tilts_deg=legs_tilts,
        cone_deg=cone_deg,
        max_tether_tilt_deg=max_tilt,
        jumps_left=len(scenario.jumps) - jumps_done,
        both_down=both_down,
    )
    failures = series.extras.get("mpc_failures")
    return LandingOutcome(
        success=mode is None,
        failure_mode=mode,
        peak_contact_force_n=force,
        touchdowns=touchdowns,
        touchdowns_on_legs=on_legs,
        body_ground_contact_s=body_s,
        tether_ground_contact_s=_value(metrics, "tether_ground_contact_s", 0.0),
        landed_at_s=landed_at,
        max_tether_tilt_deg=max_tilt,
        peak_w_rad_s=float(np.max(w, initial=0.0)),
        touchdown_w_rad_s=max((v for v in td_w if math.isfinite(v)), default=math.nan),
        touchdown_tether_tilt_deg=max((v for v in td_tilt if math.isfinite(v)), default=math.nan),
        mpc_failures=int(np.asarray(failures).max())
        if failures is not None and len(failures)
        else 0,
    )


def error_outcome(message: str) -> LandingOutcome:
    """The outcome of a flight that raised."""
    return LandingOutcome(success=False, failure_mode="error", error=message[:300])


@dataclass(frozen=True)
class JumpDrawResult:
    """A draw and every variant's outcome on it."""

    draw: JumpDraw
    outcomes: dict[str, LandingOutcome] = field(default_factory=dict)
    wall_time_s: float = math.nan  # [s] all variants

    @property
    def success(self) -> bool:
        """The first variant's success (the MPC's): what the progress lines count."""
        return bool(self.outcomes) and next(iter(self.outcomes.values())).success


# --- statistics -------------------------------------------------------------------------
def variant_summary(results: Sequence[JumpDrawResult], variant: str) -> dict[str, Any]:
    """Success rate, Wilson interval and failure modes of one variant over the draws."""
    outcomes = [r.outcomes[variant] for r in results if variant in r.outcomes]
    n = len(outcomes)
    k = sum(o.success for o in outcomes)
    lo, hi = wilson_interval(k, n) if n else (math.nan, math.nan)
    return {
        "draws": n,
        "successes": k,
        "success_rate": k / n if n else None,
        "success_rate_wilson_95": [lo, hi],
        "failure_mode_counts": {
            m: sum(o.failure_mode == m for o in outcomes) for m in FAILURE_MODES
        },
    }


def binned_success(
    results: Sequence[JumpDrawResult], variant: str, factor: str, bins: int = 5
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """(bin centres, success rate, draws) of ``variant`` against a draw factor
    (:meth:`JumpDraw.factors`), ``bins`` equal-width bins over its range (draws where
    the factor is NaN, such as the edge of a step not drawn, left out)."""
    x = np.array([r.draw.factors()[factor] for r in results if variant in r.outcomes])
    ok = np.array([r.outcomes[variant].success for r in results if variant in r.outcomes])
    known = np.isfinite(x)
    x, ok = x[known], ok[known]
    if x.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64)
    lo, hi = float(x.min()), float(x.max())
    if hi <= lo:
        hi = lo + 1e-12
    edges = np.linspace(lo, hi, bins + 1)
    index = np.clip(np.digitize(x, edges[1:-1]), 0, bins - 1)
    counts = np.bincount(index, minlength=bins)
    hits = np.bincount(index, weights=ok.astype(float), minlength=bins)
    rate = np.divide(hits, counts, out=np.full(bins, np.nan), where=counts > 0)
    return 0.5 * (edges[:-1] + edges[1:]), rate, counts


CSV_OUTCOME_FIELDS = (
    "outcome",
    "peak_contact_force_n",
    "touchdowns",
    "touchdowns_on_legs",
    "body_ground_contact_s",
    "tether_ground_contact_s",
    "landed_at_s",
    "max_tether_tilt_deg",
    "peak_w_rad_s",
    "touchdown_w_rad_s",
    "touchdown_tether_tilt_deg",
    "mpc_failures",
    "error",
)


def write_jump_csv(results: Sequence[JumpDrawResult], variants: Sequence[str], path: Path) -> None:
    """``draws.csv``: per draw its seed, its factors and each variant's outcome."""
    factor_names = list(results[0].draw.factors()) if results else []
    columns = ["index", "seed", *factor_names]
    columns += [f"{v}_{name}" for v in variants for name in CSV_OUTCOME_FIELDS]
    columns.append("wall_time_s")
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns)
        writer.writeheader()
        for r in results:
            row: dict[str, Any] = {"index": r.draw.index, "seed": r.draw.seed}
            row.update({k: f"{v:.6g}" for k, v in r.draw.factors().items()})
            for v in variants:
                o = r.outcomes.get(v)
                for name in CSV_OUTCOME_FIELDS:
                    value = (
                        "" if o is None else (o.outcome if name == "outcome" else getattr(o, name))
                    )
                    row[f"{v}_{name}"] = f"{value:.6g}" if isinstance(value, float) else value
            row["wall_time_s"] = f"{r.wall_time_s:.3f}"
            writer.writerow(row)


def definitions(ranges: JumpRanges) -> dict[str, Any]:
    """What a draw randomizes and what success and each failure mode mean (campaign.json)."""
    return {
        "ranges": asdict(ranges),
        "success": (
            f"LANDED by the end, every contact <= {FORCE_LIMIT_N} N per hemi, every touchdown "
            "on the legs, no lumped mass on the ground"
        ),
        "failure_modes": {
            "error": "the run raised",
            "cartwheel": f"the tether rose more than {CARTWHEEL_TILT_DEG} deg from the ground",
            "on_its_side": "a touchdown with the legs outside their workspace cone",
            "hard_impact": f"a contact above {FORCE_LIMIT_N} N, or a lumped mass on the ground",
            "no_landing": "not every jump pushed, or not on both hemis at the end",
            "slow_to_rest": "on both hemis, every contact soft, but not LANDED by the end",
        },
        "terrain": "flat ground z = 0 (slope and steps not randomized yet)",
    }
