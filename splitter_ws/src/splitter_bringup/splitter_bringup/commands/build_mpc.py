"""``splitter build-mpc [SCENARIO ...]``: compile and cache the scenarios' MPC solvers.

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
import sys
import time

from splitter_bringup.core.scenario import Scenario, available_scenarios, load_scenario


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "scenarios", nargs="*", help="scenario names or YAML paths (default: all bundled ones)"
    )
    parser.add_argument(
        "--solver", default="fatrop", help="MPC solver to build (the node's default: fatrop)"
    )


def formulations(names: list[str]) -> dict[tuple[int, float, str, bool], Scenario]:
    """(horizon, prediction step [s], integrator, attitude states) -> first variant flying it."""
    from splitter_bringup.core.closed_loop import controller_config

    found: dict[tuple[int, float, str, bool], Scenario] = {}
    for name in names:
        for variant in load_scenario(name).variants:
            scenario = load_scenario(name, variant)
            if scenario.controller.enabled:
                mpc = controller_config(scenario).mpc
                key = (mpc.horizon, mpc.dt_s, mpc.integrator, mpc.attitude_states)
                found.setdefault(key, scenario)
    return found


def main(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from splitter_bringup.core.closed_loop import controller_config
    from splitter_mpc.core.mpc import InertialMorphingMpc
    from splitter_sim.core.model import RobotModel

    model = RobotModel()
    for scenario in formulations(list(args.scenarios) or available_scenarios()).values():
        settings = replace(controller_config(scenario).mpc, solver=args.solver)
        print(
            f"building the {args.solver} MPC of {scenario.name}/{scenario.variant} "
            f"(N = {settings.horizon}, dt = {settings.dt_s} s, {settings.integrator}, "
            f"attitude states: {settings.attitude_states}); "
            "a first build compiles (1-2 min) ...",
            file=sys.stderr,
            flush=True,
        )
        started = time.monotonic()
        InertialMorphingMpc(model, settings)
        print(f"  ready in {time.monotonic() - started:.1f} s", file=sys.stderr, flush=True)
    return 0
