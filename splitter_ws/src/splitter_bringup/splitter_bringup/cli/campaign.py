"""``splitter campaign SCENARIO --draws N --seed S``: a Monte-Carlo campaign on Dask.

Flies ``N`` random tumbles of a scenario (random ``|w0|`` in ``[--w-min, --w-max]``,
random direction and attitude; optional perturbations) with the library closed loop
and reports the success rate, its 95 % Wilson interval, the failure modes and the
settling times. The draws, the success test and the failure modes are defined in
:mod:`splitter_bringup.analysis.campaign`.

Parallel on Dask distributed: an embedded ``LocalCluster`` on 127.0.0.1 (one
process per worker, one thread each, ``--workers`` of them, all cores by default,
no dashboard), or an existing cluster with ``--scheduler ADDRESS``. Each draw runs
in one task with its own MPC and solver worker process (``subprocess``, which a
daemonic Dask worker may start). Every worker gets the project's environment
(:func:`splitter_bringup.run.campaign.run_on_dask`).

Writes to ``--out``:

* ``draws.csv``: one row per draw (seed, ``w0``, attitude, outcome, settling time,
  failure mode, final rate, MPC failures, wall time, perturbations);
* ``campaign.json``: the figures, the definitions, and per draw its seed and the
  command that replays it alone;
* ``success_vs_speed.png`` and ``outcome_directions.png`` (:mod:`.campaign_plots`);
* ``draws/draw_NNNN.yaml`` for every failed draw (``--yaml all`` for all draws; with its
  robot errors, not with ``--no-estimator``): a scenario file, so that
  ``splitter run draws/draw_NNNN.yaml --no-ros --out DIR`` flies it again with every
  figure of ``splitter run`` (the same flight as in the campaign).

Replay: ``--replay SEED`` flies the single draw of that seed (a ``seed`` of
``draws.csv``) in this process with the same flags, and also writes its flight
figures and series (``replay_flight.png``, ``replay.npz``). ``campaign.json`` gives
the exact command for every draw; it is the way to replay a perturbed draw.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from splitter_bringup.analysis.campaign import (
    DEFAULT_JOINT_EFFORT_NOISE,
    W_MAX_RAD_S,
    W_MIN_RAD_S,
    Draw,
    PerturbationSpec,
    definitions,
    draw_campaign,
    draw_result,
    make_draw,
    robot_errors_for_draw,
    scenario_document,
    scenario_for_draw,
    summarize,
    write_csv,
    write_draw_scenario,
)
from splitter_bringup.analysis.fault_draws import FAULT_TIME_MAX_S
from splitter_bringup.analysis.jump_campaign import JumpRanges
from splitter_bringup.run.campaign import fly_draw, run_on_dask
from splitter_bringup.scenario.definition import Scenario, ScenarioError, load_scenario
from splitter_mpc.core.solvers import SOLVERS

# the value a perturbation flag given without one takes
DEFAULT_MASS_FRACTION = 0.1  # [-] +-10 %
DEFAULT_GYRO_NOISE_RAD_S = 0.002  # [rad/s] per reading (100 Hz): a MEMS rate gyro
DEFAULT_GYRO_BIAS_RAD_S = 0.005  # [rad/s] per axis, an uncalibrated MEMS turn-on bias
DEFAULT_ACTUATOR_LAG_S = 0.05  # [s]
DEFAULT_COMMAND_LATENCY_S = 0.02  # [s] a servo bus and a network hop
DEFAULT_HEMI_BODY_EDGE_M = 0.35  # [m] a 3 kg body of up to 0.35 m a side


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter campaign``."""
    parser.add_argument("scenario", help="scenario name or YAML path")
    parser.add_argument("--draws", type=int, default=100, help="number of draws (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="campaign seed (default 0)")
    parser.add_argument(
        "--duration", type=float, default=None, help="flight time of each draw [s] (scenario's)"
    )
    parser.add_argument(
        "--w-min", type=float, default=W_MIN_RAD_S, help=f"lowest |w0| [rad/s] ({W_MIN_RAD_S})"
    )
    parser.add_argument(
        "--w-max", type=float, default=W_MAX_RAD_S, help=f"highest |w0| [rad/s] ({W_MAX_RAD_S})"
    )
    parser.add_argument(
        "--variant", default=None, help="scenario variant (default: mpc, else the first)"
    )
    parser.add_argument(
        "--solver",
        choices=SOLVERS,
        default=None,
        help="MPC back-end the draws fly (default: the scenario's controller.solver)",
    )
    parser.add_argument(
        "--workers", type=int, default=None, help="local Dask workers (default: all cores)"
    )
    parser.add_argument(
        "--scheduler", default=None, help="address of a running Dask scheduler to use instead"
    )
    parser.add_argument(
        "--out", type=Path, default=None, help="output folder (runs/campaign/SCENARIO_seedS)"
    )
    perturb = parser.add_argument_group(
        "robot errors (drawn per draw, flown as the scenario's robot_errors; off by default)"
    )
    perturb.add_argument(
        "--perturb-mass",
        type=float,
        nargs="?",
        const=DEFAULT_MASS_FRACTION,
        default=None,
        metavar="FRACTION",
        help="scale the simulated m_x, m_y, m_z (so the inertia) each within 1 +- FRACTION; "
        "the controllers know the nominal model and estimate the masses (flag alone: "
        f"{DEFAULT_MASS_FRACTION})",
    )
    perturb.add_argument(
        "--imu-noise",
        type=float,
        nargs="?",
        const=DEFAULT_GYRO_NOISE_RAD_S,
        default=None,
        metavar="SIGMA",
        help="white noise on the gyro's rate (/splitter/imu), std per axis and "
        f"reading [rad/s] (flag alone: {DEFAULT_GYRO_NOISE_RAD_S})",
    )
    perturb.add_argument(
        "--imu-bias",
        type=float,
        nargs="?",
        const=DEFAULT_GYRO_BIAS_RAD_S,
        default=None,
        metavar="BIAS",
        help="constant gyro bias, uniform in +-BIAS per axis [rad/s] "
        f"(flag alone: {DEFAULT_GYRO_BIAS_RAD_S})",
    )
    perturb.add_argument(
        "--actuator-lag",
        type=float,
        nargs="?",
        const=DEFAULT_ACTUATOR_LAG_S,
        default=0.0,
        metavar="TAU",
        help="first-order lag of every joint and tether command, time constant [s] "
        f"(flag alone: {DEFAULT_ACTUATOR_LAG_S})",
    )
    perturb.add_argument(
        "--command-latency",
        type=float,
        nargs="?",
        const=DEFAULT_COMMAND_LATENCY_S,
        default=None,
        metavar="DELAY",
        help="delay of every joint and tether command to the servos [s] "
        f"(flag alone: {DEFAULT_COMMAND_LATENCY_S})",
    )
    perturb.add_argument(
        "--hemi-bodies",
        type=float,
        nargs="?",
        const=DEFAULT_HEMI_BODY_EDGE_M,
        default=0.0,
        metavar="EDGE",
        help="hemi bodies that are not points: each a solid box of m_x with edges uniform "
        "in [EDGE/2, EDGE] [m]; the estimator then identifies their moments "
        f"(flag alone: {DEFAULT_HEMI_BODY_EDGE_M})",
    )
    perturb.add_argument(
        "--effort-noise",
        type=float,
        default=DEFAULT_JOINT_EFFORT_NOISE,
        metavar="SIGMA",
        help="with robot errors: noise of the joint effort sensors, std per joint and reading "
        f"[N m] (limbs), [N] (tether) (default: {DEFAULT_JOINT_EFFORT_NOISE})",
    )
    perturb.add_argument(
        "--no-estimator",
        action="store_true",
        help="robot errors: the controllers read the gyro and the simulator's inertia as "
        "they are and ignore the lag (default: they fly on the flight estimator of gyro "
        "bias and masses and take setpoints the lag ahead)",
    )
    jumping = parser.add_argument_group(
        "jumping scenarios (a scenario with jumps: both variants fly every draw; the robot "
        "errors above, when given, set the width of their ranges instead)"
    )
    jumping.add_argument(
        "--push-fraction",
        type=float,
        default=JumpRanges.push_fraction,
        metavar="F",
        help=f"each hemi's push magnitude within 1 +- F (default {JumpRanges.push_fraction})",
    )
    jumping.add_argument(
        "--push-tilt",
        type=float,
        default=JumpRanges.push_tilt_deg,
        metavar="DEG",
        help=f"each hemi's push direction within DEG (default {JumpRanges.push_tilt_deg})",
    )
    jumping.add_argument(
        "--spin-fraction",
        type=float,
        default=JumpRanges.spin_fraction,
        metavar="F",
        help=f"the launch's couple within 1 +- F (default {JumpRanges.spin_fraction})",
    )
    jumping.add_argument(
        "--slope",
        type=float,
        default=JumpRanges.slope_deg,
        metavar="DEG",
        help=f"the ground's slope within [0, DEG], any direction (default {JumpRanges.slope_deg})",
    )
    jumping.add_argument(
        "--step-height",
        type=float,
        default=JumpRanges.step_height_m,
        metavar="M",
        help="a step across the path within [0, M] high, its edge anywhere along the path "
        f"(default {JumpRanges.step_height_m}: what the legs' stroke keeps under the body "
        "at a nominal touchdown; higher steps can be struck whatever the controller)",
    )
    faults = parser.add_argument_group("faults (splitter_bringup.analysis.fault_draws)")
    faults.add_argument(
        "--fault",
        choices=("RANDOM",),
        default=None,
        help="every draw has one fault: a limb joint locked, a limb joint limp, or the reel "
        "locked (equal chances), at a random time before --fault-time-max",
    )
    faults.add_argument(
        "--fault-time-max",
        type=float,
        default=FAULT_TIME_MAX_S,
        metavar="S",
        help=f"latest fault time [s] (default {FAULT_TIME_MAX_S})",
    )
    faults.add_argument(
        "--no-fault-handling",
        action="store_true",
        help="the allocator neither detects faulty joints nor re-plans without them "
        "(the comparison the handling must beat)",
    )
    parser.add_argument(
        "--replay",
        type=int,
        default=None,
        metavar="SEED",
        help="fly only the draw of this seed (draws.csv), here, and plot its flight",
    )
    parser.add_argument(
        "--yaml",
        choices=("failed", "all", "none"),
        default="failed",
        help="draws to write as scenario files for 'splitter run' (with their robot errors)",
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")


def _given(value: float | None) -> float:
    """A perturbation flag's value, 0 when it was not given."""
    return 0.0 if value is None else value


def _spec(args: argparse.Namespace) -> PerturbationSpec:
    if args.fault and not (math.isfinite(args.fault_time_max) and args.fault_time_max > 0.0):
        raise ValueError(f"--fault-time-max must be > 0 s, got {args.fault_time_max}")
    return PerturbationSpec(
        mass_fraction=_given(args.perturb_mass),
        gyro_noise_rad_s=_given(args.imu_noise),
        gyro_bias_rad_s=_given(args.imu_bias),
        actuator_lag_s=args.actuator_lag,
        command_latency_s=_given(args.command_latency),
        hemi_body_edge_m=args.hemi_bodies,
        joint_effort_noise=args.effort_noise,
        estimator=not args.no_estimator,
        fault_time_max_s=args.fault_time_max if args.fault else 0.0,
        fault_handling=not args.no_fault_handling,
    )


def _variant(scenario: str, wanted: str | None) -> str:
    base = load_scenario(scenario)
    if wanted is not None:
        if wanted not in base.variants:
            raise ScenarioError(f"variant {wanted!r} not in {list(base.variants)}")
        return wanted
    return "mpc" if "mpc" in base.variants else base.variants[0]


def replay_command(args: argparse.Namespace, variant: str, out: Path, seed: int) -> str:
    """The command that flies the draw of ``seed`` alone, with the campaign's settings."""
    words = ["splitter", "campaign", str(args.scenario), "--variant", variant]
    words += ["--replay", str(seed)]
    if args.solver is not None:
        words += ["--solver", args.solver]
    if args.duration is not None:
        words += ["--duration", repr(args.duration)]
    words += ["--w-min", repr(args.w_min), "--w-max", repr(args.w_max)]
    for flag, value in (
        ("--perturb-mass", _given(args.perturb_mass)),
        ("--imu-noise", _given(args.imu_noise)),
        ("--imu-bias", _given(args.imu_bias)),
        ("--actuator-lag", args.actuator_lag),
        ("--command-latency", _given(args.command_latency)),
        ("--hemi-bodies", args.hemi_bodies),
    ):
        if value > 0.0:
            words += [flag, repr(value)]
    if args.effort_noise != DEFAULT_JOINT_EFFORT_NOISE:
        words += ["--effort-noise", repr(args.effort_noise)]
    if args.no_estimator:
        words.append("--no-estimator")
    if args.fault:
        words += ["--fault", args.fault, "--fault-time-max", repr(args.fault_time_max)]
    if args.no_fault_handling:
        words.append("--no-fault-handling")
    words += ["--out", str(out)]
    return shlex.join(words)


def campaign_command(argv: Sequence[str] | None = None) -> str:
    """The command line this process was started with (for campaign.json)."""
    return shlex.join(["splitter", *(sys.argv[1:] if argv is None else argv)])


def _print_summary(summary: dict[str, Any], title: str) -> None:
    lo, hi = summary["success_rate_wilson_95"]
    rate = summary["success_rate"]
    print(f"\n{title}")
    if rate is not None:
        print(
            f"  success rate  {summary['successes']}/{summary['draws']} = {rate:.3f} "
            f"(95 % Wilson {lo:.3f} - {hi:.3f})"
        )
    for mode, count in summary["failure_mode_counts"].items():
        if count:
            print(f"  {mode:<18}{count}")
    med, p90 = summary["settling_time_median_s"], summary["settling_time_p90_s"]
    if med is not None:
        print(f"  settling time median {med:.2f} s, p90 {p90:.2f} s")
    bias, ratio = summary.get("gyro_bias_error_p95_rad_s"), summary.get("mass_ratio_error_p95")
    mass = summary.get("mass_error_p95")
    if bias is not None:
        print(
            f"  estimator at the end, p95 over draws: gyro bias error {bias:.5f} rad/s, "
            f"mass ratio error {100 * ratio:.2f} %, mass error {100 * (mass or 0.0):.2f} %"
        )
    for row, figures in (summary.get("faults") or {}).items():
        latency = figures["detection_latency_max_s"]
        print(
            f"  {row:<12} {figures['successes']}/{figures['draws']} = "
            f"{figures['success_rate']:.3f}, detections missed {figures['detections_missed']}, "
            f"latency max {'-' if latency is None else f'{latency:.3f} s'}, "
            f"false detections {figures['false_detections']}"
        )
    print(f"  wall time {summary['wall_time_s']:.1f} s")


def main(args: argparse.Namespace) -> int:
    """Draw, fly on Dask, classify, summarise, plot; 0 when it ran, 2 on bad input."""
    try:
        if load_scenario(args.scenario).jumps:
            from splitter_bringup.cli import jump_campaign

            return jump_campaign.main(args)
        variant = _variant(args.scenario, args.variant)
        base = load_scenario(args.scenario, variant)
        spec = _spec(args)
        if args.draws < 1:
            raise ValueError(f"--draws must be >= 1, got {args.draws}")
        if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
            raise ValueError(f"--duration must be > 0, got {args.duration}")
        if args.replay is None:
            draws = draw_campaign(args.seed, args.draws, args.w_min, args.w_max, spec)
        else:
            draws = [make_draw(0, args.replay, args.w_min, args.w_max, spec)]
    except (ScenarioError, ValueError) as exc:
        print(f"splitter campaign: {exc}", file=sys.stderr)
        return 2
    name = Path(args.scenario).stem
    out: Path = args.out or Path("runs") / "campaign" / f"{name}_seed{args.seed}"
    out.mkdir(parents=True, exist_ok=True)
    jobs = [(scenario_for_draw(base, d, args.duration), d) for d in draws]
    started = time.monotonic()
    if args.replay is None:
        results, cluster = run_on_dask(jobs, spec, args.workers, args.scheduler, args.solver)
    else:
        results = [_replay(jobs[0], spec, out, args.no_plots, args.solver)]
        cluster = {"replay": True}
    wall = time.monotonic() - started
    write_csv(results, out / "draws.csv")
    summary = summarize(results).as_dict()
    summary["wall_time_s"] = wall
    per_draw = []
    for (scenario, draw), result in zip(jobs, results, strict=True):
        entry: dict[str, Any] = {
            "index": draw.index,
            "seed": draw.seed,
            "outcome": result.outcome,
            "replay": replay_command(args, variant, out / f"replay_{draw.seed}", draw.seed),
        }
        wanted = args.yaml == "all" or (args.yaml == "failed" and not result.success)
        if wanted and spec.estimator and args.replay is None:
            doc = scenario_document(
                base, draw, scenario.duration_s, robot_errors_for_draw(draw, spec)
            )
            if not spec.fault_handling:  # flown blind: so is the file
                doc["fault_handling"] = False
            entry.update(write_draw_scenario(out, draw.index, doc))
        per_draw.append(entry)
    document = {
        "scenario": base.name,
        "variant": variant,
        "solver": args.solver or base.controller.solver,
        "command": campaign_command(),
        "seed": args.seed,
        "duration_s": jobs[0][0].duration_s,
        "w_min_rad_s": args.w_min,
        "w_max_rad_s": args.w_max,
        "perturbation": spec.as_dict(),
        "cluster": cluster,
        **summary,
        "definitions": definitions(),
        "per_draw": per_draw,
    }
    (out / "campaign.json").write_text(json.dumps(document, indent=2), encoding="utf-8")
    if not args.no_plots and args.replay is None:
        from splitter_bringup.figures.campaign_plots import (
            plot_direction_map,
            plot_speed_dependence,
        )

        title = f"{base.name}/{variant}: {len(results)} draws, {jobs[0][0].duration_s:g} s"
        plot_speed_dependence(results, out / "success_vs_speed.png", args.w_min, args.w_max, title)
        plot_direction_map(results, out / "outcome_directions.png", title)
    _print_summary(document, f"{base.name}/{variant} campaign, seed {args.seed}")
    print(f"\nwrote {out / 'draws.csv'} and {out / 'campaign.json'}")
    return 0


def _replay(
    job: tuple[Scenario, Draw],
    spec: PerturbationSpec,
    out: Path,
    no_plots: bool,
    solver: str | None = None,
):
    """Fly one draw here; keep its series and flight figure beside the campaign files."""
    scenario, draw = job
    started = time.monotonic()
    series = fly_draw(scenario, draw, spec, solver)
    result = draw_result(draw, series, time.monotonic() - started)
    series.save_npz(out / "replay.npz")
    if not no_plots:
        from splitter_bringup.figures.plots import plot_flight

        plot_flight(
            series,
            out / "replay_flight.png",
            f"{scenario.name}/{scenario.variant}: draw seed {draw.seed}, {result.outcome}",
        )
    return result
