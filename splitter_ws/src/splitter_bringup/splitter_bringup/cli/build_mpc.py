"""``splitter build-mpc [SCENARIO ...]``: compile and cache the scenarios' MPC solvers.

It first compiles the simulator's kernels (:mod:`splitter_sim.core.kernels`, one
library for every model and scenario, ~10 s) into the same cache.

The compiled derivative code of an MPC depends on its horizon, prediction step,
integrator and whether its state carries the attitude (only when the weights
track it); objective and weights are parameters. Each formulation the scenarios
fly is built once here, through the same code the ``inertial_morphing_mpc`` node
runs, so that later starts load it from the cache in under a second
(:mod:`splitter_mpc.core.codegen`). ``make test`` calls it before the suite: the
graph tests then start their MPC node without a compile inside their time limits.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed

from splitter_bringup.scenario.definition import Scenario, available_scenarios, load_scenario


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "scenarios", nargs="*", help="scenario names or YAML paths (default: all bundled ones)"
    )
    parser.add_argument(
        "--solver", default="fatrop", help="MPC solver to build (the node's default: fatrop)"
    )
    parser.add_argument(
        "--jobs",
        type=_jobs,
        default=0,
        help="formulations built at once (default 0: one per CPU core)",
    )


def _jobs(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {value}")
    return value


def formulations(names: list[str]) -> dict[tuple[int, float, str, bool], Scenario]:
    """(horizon, prediction step [s], integrator, attitude states) -> first variant flying it."""
    from splitter_bringup.run.library import controller_config

    found: dict[tuple[int, float, str, bool], Scenario] = {}
    for name in names:
        for variant in load_scenario(name).variants:
            scenario = load_scenario(name, variant)
            if scenario.controller.enabled:
                mpc = controller_config(scenario).mpc
                key = (mpc.horizon, mpc.dt_s, mpc.integrator, mpc.attitude_states)
                found.setdefault(key, scenario)
    return found


def build(scenario: Scenario, solver: str) -> float:
    """Build (compile or load from the cache) the ``solver`` MPC a scenario flies; seconds taken."""
    from dataclasses import replace

    from splitter_bringup.run.library import controller_config
    from splitter_model.model import RobotModel
    from splitter_mpc.core.mpc import InertialMorphingMpc

    settings = replace(controller_config(scenario).mpc, solver=solver)
    # in this process: the compiled code lands in the cache every worker loads it from
    settings = replace(settings, options=replace(settings.options, isolated=False))
    started = time.monotonic()
    InertialMorphingMpc(RobotModel(), settings)
    return time.monotonic() - started


def _build_simulator_kernels() -> None:
    """Compile (or find in the cache) the simulator's kernels; a warning when impossible."""
    from splitter_model.codegen import CompilationError
    from splitter_sim.core import kernels

    started = time.monotonic()
    try:
        library = kernels.build_library()
    except CompilationError as exc:
        print(f"simulator kernels not built ({exc}): it runs pure Python", file=sys.stderr)
        return
    print(
        f"simulator kernels ready in {time.monotonic() - started:.1f} s ({library.name})",
        file=sys.stderr,
        flush=True,
    )


def main(args: argparse.Namespace) -> int:
    from splitter_bringup.run.library import controller_config

    _build_simulator_kernels()
    found = formulations(list(args.scenarios) or available_scenarios())
    jobs = max(1, min(args.jobs or os.cpu_count() or 1, len(found)))
    print(
        f"building {len(found)} {args.solver} MPC formulation(s), {jobs} at a time; "
        "a first build compiles (1-2 min each) ...",
        file=sys.stderr,
        flush=True,
    )
    # One process per build: gcc is single-threaded, and the cache writes are atomic.
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
        futures = {pool.submit(build, s, args.solver): s for s in found.values()}
        for done, future in enumerate(as_completed(futures), start=1):
            scenario = futures[future]
            settings = controller_config(scenario).mpc
            print(
                f"  [{done}/{len(found)}] {scenario.name}/{scenario.variant} "
                f"(N = {settings.horizon}, dt = {settings.dt_s} s, {settings.integrator}, "
                f"attitude states: {settings.attitude_states}) ready in {future.result():.1f} s",
                file=sys.stderr,
                flush=True,
            )
    return 0
