"""``splitter bench mpc``: solve times of the project's MPC against a plain Opti + IPOPT one.

In one run, the spin_stabilization closed loop (library loop: simulator,
allocator, gait phase machine) is flown twice, once with the reference MPC
written the plain way (:class:`~splitter_mpc.core.baseline.OptiBaselineMpc`,
built once) and once with the project's controller. Printed: the median, 99th
percentile and largest solve time of each, the median speed-up, and the largest
difference between the two closed-loop angular-velocity trajectories (the two
solve the same problem, so it measures solver agreement, not tuning).
Progress goes to stderr; ``--json`` prints one JSON object on stdout; ``--plot
PNG`` draws each re-plan's solve time (with the p99 goal: 3 ms, or 10 % of the
re-plan period if that is less), its iterations, and the difference between the two closed loops.

``--solver`` (repeatable) picks the back-ends, each written ``NAME`` (solved in the
controller's worker process, killed at the deadline: the nodes' default) or
``NAME/in-process`` (solved in the controller's own process); by default
:data:`DEFAULT_BACKENDS`, side by side against one baseline run. The first one's
figures are also the JSON's top level; ``backends`` lists every one.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

P99_GOAL_FRACTION = 0.1  # [-] of the re-plan period: issue 4's p99 solve-time goal
GOAL_P99_MS = 3.0  # [ms] issue 18: p99 solve time
GOAL_SPEEDUP = 100.0  # [-] issue 18: median speed-up over Opti + IPOPT kept
IN_PROCESS = "/in-process"  # a back-end spec's suffix: solved in the controller's process
DEFAULT_BACKENDS = (
    "fatrop",
    f"fatrop{IN_PROCESS}",
    f"ipopt{IN_PROCESS}",
    f"sqp{IN_PROCESS}",
    f"rti{IN_PROCESS}",
    f"condensed_sqp{IN_PROCESS}",
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter bench mpc``."""
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--solver",
        action="append",
        default=None,
        help="back-end, NAME or NAME/in-process (NAME: fatrop, ipopt, sqp, rti, condensed_sqp; "
        "repeatable; "
        f"default: {' '.join(DEFAULT_BACKENDS)})",
    )
    parser.add_argument("--scenario", default="spin_stabilization", help="flight scenario")
    parser.add_argument("--duration", type=float, default=None, help="shorter run [s]")
    parser.add_argument(
        "--no-compile", action="store_true", help="project's solver without compiled code"
    )
    parser.add_argument(
        "--plot",
        type=Path,
        default=None,
        metavar="PNG",
        help="also plot solve times, iterations and the w difference per re-plan",
    )


def _progress(label: str):
    state = {"decile": -1}

    def report(fraction: float) -> None:
        decile = int(10 * fraction)
        if decile != state["decile"]:
            state["decile"] = decile
            print(f"  {label}: {10 * decile:3d} %", file=sys.stderr, flush=True)

    return report


def _solve_times_ms(series) -> np.ndarray:
    times = np.asarray(series.extras["mpc_solve_time_ms"], dtype=float)
    return times[np.isfinite(times)]


def parse_backend(spec: str) -> tuple[str, bool]:
    """(solver, isolated) of ``NAME`` or ``NAME/in-process``; ValueError for another."""
    from splitter_mpc.core.solvers import SOLVERS

    name, in_process = (
        (spec[: -len(IN_PROCESS)], True) if spec.endswith(IN_PROCESS) else (spec, False)
    )
    if name not in SOLVERS:
        raise ValueError(
            f"unknown back-end {spec!r}: use NAME or NAME{IN_PROCESS}, NAME in {SOLVERS}"
        )
    return name, not in_process


def run_benchmark(
    solver: str | tuple[str, ...] = "fatrop",
    scenario_name: str = "spin_stabilization",
    duration_s: float | None = None,
    compile_code: bool = True,
    plot_path: Path | None = None,
) -> dict:
    """Fly the scenario with the baseline and each back-end; the figures as a dictionary.

    ``solver``: one back-end spec or several (:func:`parse_backend`). The top level
    holds the first one's figures; ``backends`` every one's, in order.
    """
    from splitter_bringup.run.library import controller_config, run_closed_loop
    from splitter_bringup.scenario.definition import load_scenario
    from splitter_model.model import RobotModel
    from splitter_mpc.core.baseline import OptiBaselineMpc
    from splitter_mpc.core.controller import MorphingController
    from splitter_mpc.core.mpc import InertialMorphingMpc, MpcSettings
    from splitter_mpc.core.solvers import SolverOptions

    specs = (solver,) if isinstance(solver, str) else tuple(solver)
    backends = [(spec, *parse_backend(spec)) for spec in specs]
    scenario = load_scenario(scenario_name)
    model = RobotModel()
    # No wall-time cap (lockstep): a late solve would be discarded by the controller,
    # and the two closed loops would no longer compare solutions to the same problems.
    baseline_config = controller_config(
        scenario, MpcSettings(options=SolverOptions(compile=compile_code, max_time_s=60.0))
    )
    print("building the Opti + IPOPT baseline ...", file=sys.stderr)
    baseline = MorphingController(
        model, baseline_config, OptiBaselineMpc(model, baseline_config.mpc)
    )
    runs = {
        "baseline": run_closed_loop(
            scenario,
            _progress("baseline"),
            model=model,
            controller=baseline,
            duration_s=duration_s,
        )
    }
    build_s = {}
    for spec, name, isolated in backends:
        options = SolverOptions(compile=compile_code, max_time_s=60.0, isolated=isolated)
        config = controller_config(scenario, MpcSettings(solver=name, options=options))
        print(f"building {spec} (first start compiles, then cached) ...", file=sys.stderr)
        started = time.monotonic()
        controller = MorphingController(model, config, InertialMorphingMpc(model, config.mpc))
        build_s[spec] = time.monotonic() - started
        with controller:  # the solver worker stops with the run
            runs[spec] = run_closed_loop(
                scenario,
                _progress(spec),
                model=model,
                controller=controller,
                duration_s=duration_s,
            )
    if plot_path is not None:
        from splitter_bringup.figures.plots import plot_solve_times

        budget_ms = min(GOAL_P99_MS, P99_GOAL_FRACTION * baseline_config.replan_period_ns / 1e6)
        title = f"{scenario_name}: Opti + IPOPT baseline vs {', '.join(specs)}"
        plot_solve_times(runs, plot_path, budget_ms, title)
        print(f"wrote {plot_path}", file=sys.stderr)
    base = runs["baseline"]
    base_ms = _solve_times_ms(base)
    figures = [_figures(spec, base, base_ms, runs[spec], build_s[spec]) for spec, _, _ in backends]
    return {"scenario": scenario_name, **figures[0], "backends": figures}


def _figures(spec: str, base, base_ms, mine, build_s: float) -> dict:
    name, isolated = parse_backend(spec)
    mine_ms = _solve_times_ms(mine)
    diff = np.abs(base.angular_velocity_rad_s - mine.angular_velocity_rad_s)
    ok = np.asarray(mine.extras["mpc_solve_ok"], dtype=float)
    ok = ok[np.isfinite(ok)]
    return {
        "backend": spec,
        "solver": name,
        "in_process": not isolated,
        "n_solves": len(mine_ms),
        "baseline_median_ms": float(np.median(base_ms)),
        "baseline_p99_ms": float(np.percentile(base_ms, 99)),
        "median_ms": float(np.median(mine_ms)),
        "p99_ms": float(np.percentile(mine_ms, 99)),
        "max_ms": float(np.max(mine_ms)),
        "speedup_median": float(np.median(base_ms) / np.median(mine_ms)),
        "goal_p99_ms": GOAL_P99_MS,
        "goal_speedup_median": GOAL_SPEEDUP,
        "max_abs_w_diff": float(np.max(diff)),
        "failed_solves": int(np.sum(ok < 0.5)),
        "median_iterations": float(np.nanmedian(mine.extras["mpc_iterations"])),
        "build_s": build_s,
    }


def main(args: argparse.Namespace) -> int:
    """Run the benchmark; print the figures."""
    specs = tuple(args.solver or DEFAULT_BACKENDS)
    try:
        for spec in specs:
            parse_backend(spec)
    except ValueError as exc:
        print(f"splitter bench mpc: {exc}", file=sys.stderr)
        return 2
    result = run_benchmark(specs, args.scenario, args.duration, not args.no_compile, args.plot)
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    first = result["backends"][0]
    print(
        f"{result['scenario']}: {first['n_solves']} solves; Opti + IPOPT baseline median "
        f"{first['baseline_median_ms']:.1f} ms, p99 {first['baseline_p99_ms']:.1f} ms "
        f"(goals: p99 <= {GOAL_P99_MS:g} ms, median speed-up >= {GOAL_SPEEDUP:g}x)"
    )
    print(
        f"{'back-end':>20} {'median ms':>10} {'p99 ms':>8} {'max ms':>8} {'speed-up':>9} "
        f"{'iter':>5} {'failed':>6} {'max |dw| rad/s':>15}"
    )
    for r in result["backends"]:
        print(
            f"{r['backend']:>20} {r['median_ms']:>10.2f} {r['p99_ms']:>8.2f} "
            f"{r['max_ms']:>8.2f} {r['speedup_median']:>8.0f}x {r['median_iterations']:>5.0f} "
            f"{r['failed_solves']:>6d} {r['max_abs_w_diff']:>15.2e}"
        )
    return 0
