"""``splitter bench mpc``: solve times of the project's MPC against a plain Opti + IPOPT one.

In one run, the spin_stabilization closed loop (library loop: simulator,
allocator, gait phase machine) is flown twice, once with the reference MPC
written the plain way (:class:`~splitter_mpc.core.baseline.OptiBaselineMpc`,
built once) and once with the project's controller. Printed: the median, 99th
percentile and largest solve time of each, the median speed-up, and the largest
difference between the two closed-loop angular-velocity trajectories (the two
solve the same problem, so it measures solver agreement, not tuning).
Progress goes to stderr; ``--json`` prints one JSON object on stdout; ``--plot
PNG`` draws each re-plan's solve time (with the p99 goal, 10 % of the re-plan
period), its iterations, and the difference between the two closed loops.
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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter bench mpc``."""
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument(
        "--solver", default="fatrop", help="project's solver (fatrop, ipopt, sqp, rti)"
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


def run_benchmark(
    solver: str = "fatrop",
    scenario_name: str = "spin_stabilization",
    duration_s: float | None = None,
    compile_code: bool = True,
    plot_path: Path | None = None,
) -> dict:
    """Fly the scenario with both controllers; the figures as a dictionary (and a PNG)."""
    from splitter_bringup.run.library import controller_config, run_closed_loop
    from splitter_bringup.scenario.definition import load_scenario
    from splitter_model.model import RobotModel
    from splitter_mpc.core.baseline import OptiBaselineMpc
    from splitter_mpc.core.controller import MorphingController
    from splitter_mpc.core.mpc import InertialMorphingMpc, MpcSettings
    from splitter_mpc.core.solvers import SolverOptions

    scenario = load_scenario(scenario_name)
    model = RobotModel()
    # No wall-time cap (lockstep): a late solve would be discarded by the controller,
    # and the two closed loops would no longer compare solutions to the same problems.
    settings = MpcSettings(
        solver=solver, options=SolverOptions(compile=compile_code, max_time_s=60.0)
    )
    config = controller_config(scenario, settings)
    print(f"building {solver} (first start compiles, then cached) ...", file=sys.stderr)
    started = time.monotonic()
    ours = MorphingController(model, config, InertialMorphingMpc(model, config.mpc))
    build_s = time.monotonic() - started
    print("building the Opti + IPOPT baseline ...", file=sys.stderr)
    baseline = MorphingController(model, config, OptiBaselineMpc(model, config.mpc))
    runs = {}
    with ours:  # the solver worker stops with the runs
        for label, controller in (("baseline", baseline), (solver, ours)):
            runs[label] = run_closed_loop(
                scenario,
                _progress(label),
                model=model,
                controller=controller,
                duration_s=duration_s,
            )
    base, mine = runs["baseline"], runs[solver]
    if plot_path is not None:
        from splitter_bringup.figures.plots import plot_solve_times

        budget_ms = P99_GOAL_FRACTION * config.replan_period_ns / 1e6
        title = f"{scenario_name}: Opti + IPOPT baseline vs {solver}"
        plot_solve_times(runs, plot_path, budget_ms, title)
        print(f"wrote {plot_path}", file=sys.stderr)
    base_ms, mine_ms = _solve_times_ms(base), _solve_times_ms(mine)
    diff = np.abs(base.angular_velocity_rad_s - mine.angular_velocity_rad_s)
    ok = np.asarray(mine.extras["mpc_solve_ok"], dtype=float)
    ok = ok[np.isfinite(ok)]
    return {
        "scenario": scenario_name,
        "solver": solver,
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
    result = run_benchmark(
        args.solver, args.scenario, args.duration, not args.no_compile, args.plot
    )
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        goals = {
            "p99_ms": f"goal <= {GOAL_P99_MS:g}",
            "speedup_median": f"goal >= {GOAL_SPEEDUP:g}",
        }
        for key, value in result.items():
            if key.startswith("goal_"):
                continue
            text = f"{value:.4g}" if isinstance(value, float) else f"{value}"
            goal = f"  ({goals[key]})" if key in goals else ""
            print(f"{key:>20}: {text}{goal}")
    return 0
