"""``splitter run SCENARIO --out DIR``: run a scenario's variants, write summary and plots.

Backends: ``graph`` (default) runs the node graph, one process per node, records
its bag and reads it back (:func:`splitter_bringup.run.graph_run.run_graph`);
``library`` (also ``--no-ros``) steps the same core objects in the lockstep
order in one process (:mod:`splitter_bringup.run.library`).
Either way the same metrics and plots are made from a ``RunSeries``.

Writes ``DIR/summary.json`` (the main variant's figures beside the paper's, and
every variant's), ``DIR/<variant>.npz``, ``DIR/<variant>_*.png`` and the flight in
3D, ``DIR/<variant>_flight.mp4`` (:mod:`splitter_bringup.cli.animate`;
``--no-animation`` skips it), and prints a table.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.analysis.summary import variant_metrics
from splitter_bringup.run.backends import (
    BACKENDS,
    IN_PROCESS,
    LIBRARY,
    PROCESSES,
    VariantRun,
    run_variant,
)
from splitter_bringup.scenario.definition import (
    Scenario,
    ScenarioError,
    available_scenarios,
    load_scenario,
)
from splitter_model.terrain import FLAT, Terrain
from splitter_mpc.core.solvers import SOLVERS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter run``."""
    parser.add_argument(
        "scenario", help=f"scenario name ({', '.join(available_scenarios())}) or YAML path"
    )
    parser.add_argument("--out", type=Path, required=True, help="output folder")
    parser.add_argument(
        "--variant", action="append", help="variant to run (repeatable; default: all of them)"
    )
    parser.add_argument(
        "--backend",
        choices=("graph", *BACKENDS),
        default="graph",
        help="graph: the node graph, recorded to DIR/<variant>/bag (processes, or inprocess "
        "with --in-process); library: no ROS",
    )
    parser.add_argument(
        "--no-ros", action="store_true", help="same as --backend library (no ROS graph)"
    )
    parser.add_argument(
        "--in-process",
        action="store_true",
        help="graph backend: every node in this one process on one executor "
        "(default: one process per node)",
    )
    parser.add_argument(
        "--solver", choices=SOLVERS, default=None, help="MPC solver (library backend)"
    )
    parser.add_argument(
        "--no-compile", action="store_true", help="MPC without compiled code (library backend)"
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG figures")
    parser.add_argument(
        "--no-animation", action="store_true", help="skip the 3D animation of each variant"
    )
    parser.add_argument(
        "--domain-id",
        type=int,
        help="graph backend: ROS domain of the graph (default: ROS_DOMAIN_ID when set, else "
        "one no other graph on this machine uses; written to DIR/<variant>/domain_id)",
    )


def _progress_printer(label: str):
    state = {"last": -1}

    def report(fraction: float) -> None:
        percent = int(100 * fraction)
        if percent // 10 != state["last"] // 10 or fraction >= 1.0:
            state["last"] = percent
            print(f"  {label}: {percent:3d} %", file=sys.stderr, flush=True)

    return report


def _backend(args: argparse.Namespace) -> str:
    """The run backend the options choose (``graph`` is one of the two graph backends)."""
    if args.no_ros or args.backend == LIBRARY:
        return LIBRARY
    if args.backend == "graph":
        return IN_PROCESS if args.in_process else PROCESSES
    return args.backend


def _run_variant(args: argparse.Namespace, scenario: Scenario) -> VariantRun:
    """The variant's run on the chosen backend, with the options that apply to it."""
    backend = _backend(args)
    if backend != LIBRARY:
        return run_variant(scenario, backend, out_dir=args.out, domain_id=args.domain_id)
    from splitter_mpc.core.mpc import MpcSettings
    from splitter_mpc.core.solvers import LOCKSTEP_MAX_TIME_S, SolverOptions

    mpc = MpcSettings(
        solver=args.solver or scenario.controller.solver,
        options=SolverOptions(compile=not args.no_compile, max_time_s=LOCKSTEP_MAX_TIME_S),
    )
    return run_variant(scenario, LIBRARY, mpc=mpc, progress=_progress_printer(scenario.variant))


def _animate(
    series: RunSeries, out: Path, variant: str, title: str, terrain: Terrain = FLAT
) -> None:
    """``out/<variant>_flight.mp4`` over ``terrain``, with contact arrows when the graph
    recorded a bag."""
    from splitter_bringup.figures.flight_animation import write_animation
    from splitter_bringup.run.run_bag import contact_forces_from_bag

    bag = out / variant / "bag"
    contact = contact_forces_from_bag(bag, series.t_s) if (bag / "metadata.yaml").exists() else None
    started = time.monotonic()
    info = write_animation(
        series, out / f"{variant}_flight.mp4", title, contact_forces_n=contact, terrain=terrain
    )
    print(
        f"  {variant}: animation {info.path.name}, {info.frames} frames "
        f"({time.monotonic() - started:.1f} s)",
        file=sys.stderr,
    )


def _jsonable(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def main(args: argparse.Namespace) -> int:
    """Run, summarise, plot; 0 on success, 2 on a bad scenario or variant."""
    from splitter_bringup.analysis.metrics import Metric, evaluate_findings, summary_table

    try:
        base = load_scenario(args.scenario)
        variants = list(args.variant or base.variants)
        for v in variants:
            if v not in base.variants:
                raise ScenarioError(f"variant {v!r} not in {list(base.variants)}")
    except ScenarioError as exc:
        print(f"splitter run: {exc}", file=sys.stderr)
        return 2
    if args.no_ros:
        args.backend = "library"
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    backend = args.backend
    print(f"{base.name}: variants {', '.join(variants)} ({backend})", file=sys.stderr)
    runs: dict[str, RunSeries] = {}
    summaries: dict[str, dict] = {}
    all_metrics: dict[str, dict[str, Metric]] = {}
    for variant in variants:
        started = time.monotonic()
        scenario = load_scenario(args.scenario, variant)
        variant_run = _run_variant(args, scenario)
        series, startup_s = variant_run.series, variant_run.startup_s
        flight_wall_s, graph_facts = variant_run.flight_wall_time_s, variant_run.facts
        wall = time.monotonic() - started
        runs[variant] = series
        series.save_npz(out / f"{variant}.npz")
        metrics = variant_metrics(series, scenario)
        all_metrics[variant] = metrics
        summaries[variant] = {
            "wall_time_s": wall,
            "startup_s": startup_s,  # processes, solver load and discovery before the first step
            "flight_wall_time_s": flight_wall_s,  # the flight itself
            "flight_real_time_factor": scenario.duration_s / max(flight_wall_s, 1e-9),
            "controller_enabled": scenario.controller.enabled,
            **graph_facts,  # graph backend: domain_id, foreign_publishers
            "metrics": {
                k: {kk: _jsonable(vv) for kk, vv in m.as_dict().items()} for k, m in metrics.items()
            },
        }
        print(
            f"  {variant}: done in {wall:.1f} s (start-up {startup_s:.1f} s, flight "
            f"{flight_wall_s:.1f} s: {scenario.duration_s / max(flight_wall_s, 1e-9):.1f}x "
            "real time)",
            file=sys.stderr,
        )
        if not args.no_plots:
            from splitter_bringup.figures.plots import plot_flight, plot_quaternion_map

            plot_flight(series, out / f"{variant}_flight.png", f"{base.name}: {variant}")
            plot_quaternion_map(
                series, out / f"{variant}_quaternion.png", f"{base.name}: {variant}"
            )
            if "estimate_t_s" in series.extras and scenario.robot_errors.present:
                from splitter_bringup.figures.plots import plot_estimator

                plot_estimator(
                    series,
                    scenario.robot_errors,
                    out / f"{variant}_estimator.png",
                    f"{base.name}: {variant}, flight estimator (dashed: the simulated robot)",
                )
            if scenario.jumps or scenario.gravity_m_s2 > 0.0:
                from splitter_bringup.figures.trajectory import plot_trajectory

                plot_trajectory(
                    series,
                    out / f"{variant}_trajectory.png",
                    f"{base.name}: {variant}",
                    terrain=scenario.terrain,
                )
            if scenario.jumps:
                from splitter_bringup.analysis.actuator_sizing import limb_dynamic_force_limit_n
                from splitter_bringup.analysis.summary import plant_model
                from splitter_bringup.analysis.touchdowns import touchdowns
                from splitter_bringup.figures.plots import plot_gait

                plot_gait(
                    series,
                    out / f"{variant}_gait.png",
                    f"{base.name}: {variant}, gait phases",
                    limb_dynamic_force_limit_n(),
                    touchdowns(
                        series,
                        scenario.leg_cone_half_angle_deg,
                        plant_model(scenario),
                        terrain=scenario.terrain,
                    ),
                    terrain=scenario.terrain,
                )
        if not args.no_animation:
            _animate(series, out, variant, f"{base.name}: {variant}", scenario.terrain)
    findings = evaluate_findings(base.findings, all_metrics)
    if not args.no_plots and len(runs) > 1:
        from splitter_bringup.figures.plots import plot_comparison, plot_findings

        plot_comparison(runs, out / "comparison.png", base.name)
        if any(f.reproduced is not None for f in findings):
            plot_findings(findings, out / "findings.png", f"{base.name}: the paper's findings")
    main_variant = variants[0]
    summary = {
        "scenario": base.name,
        "backend": backend,
        "main_variant": main_variant,
        "metrics": summaries[main_variant]["metrics"],
        "variants": summaries,
        "findings": [f.as_dict() for f in findings],
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2), encoding="utf-8")
    for variant in variants:
        print(f"\n{base.name} / {variant}")
        print(f"  {'metric':<26}{'value':>12}  {'unit':<9}paper")
        for name, value, unit, paper in summary_table(all_metrics[variant]):
            print(f"  {name:<26}{value:>12}  {unit:<9}{paper}")
    if findings:
        print(f"\n{base.name}: the paper's findings")
        for f in findings:
            verdict = {True: "reproduced", False: "NOT reproduced", None: "not run"}[f.reproduced]
            values = ", ".join(f"{v} {x:.4g}" for v, x in f.values.items())
            print(f"  {verdict:<15} {f.statement}\n  {'':<15} {f.metric}: {values}")
    print(f"\nwrote {out / 'summary.json'}")
    return 0
