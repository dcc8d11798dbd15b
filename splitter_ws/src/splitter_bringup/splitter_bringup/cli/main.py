"""The ``splitter`` command: one entry, subcommands implemented in each package.

Each subcommand lives in its own module exposing::

    def add_arguments(parser: argparse.ArgumentParser) -> None: ...
    def main(args: argparse.Namespace) -> int: ...

A command group (like ``bench``) exposes ``run_argv(argv) -> int`` instead.
Only the chosen subcommand's module is imported, so ``splitter --help`` stays fast
and lists what exists in this installation.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import logging
import sys
from collections.abc import Mapping, Sequence

# name -> (module, one-line help)
COMMANDS: Mapping[str, tuple[str, str]] = {
    "run": ("splitter_bringup.cli.run", "run a scenario to its end, write summary and plots"),
    "launch": ("splitter_bringup.cli.launch", "start every node as its own process"),
    "bench": (
        "splitter_tools.bench",
        "benchmarks that print figures (sim, mpc, bag, graph; splitter_tools)",
    ),
    "bag": ("splitter_bag.cli", "bag tools: info, recover, play, record"),
    "plot": ("splitter_bringup.cli.plot", "plot a recorded bag as the paper's figures"),
    "animate": (
        "splitter_bringup.cli.animate",
        "render a recorded bag's flight in 3D as an mp4 or gif",
    ),
    "replay": (
        "splitter_bringup.cli.replay",
        "re-run the MPC on a recorded bag's inputs and compare its setpoints",
    ),
    "campaign": (
        "splitter_bringup.cli.campaign",
        "Monte-Carlo campaign of random tumbles on Dask: success rate and failure modes",
    ),
    "build-mpc": (
        "splitter_bringup.cli.build_mpc",
        "compile and cache the MPC solvers the scenarios fly",
    ),
    "actuator": (
        "splitter_bringup.cli.actuator",
        "actuator sizing against the paper's numbers",
    ),
}


def available(commands: Mapping[str, tuple[str, str]] = COMMANDS) -> dict[str, tuple[str, str]]:
    """The subcommands whose module is installed."""
    out = {}
    for name, (module, text) in commands.items():
        try:
            found = importlib.util.find_spec(module) is not None
        except ModuleNotFoundError:
            found = False
        if found:
            out[name] = (module, text)
    return out


def dispatch(
    prog: str,
    argv: Sequence[str],
    commands: Mapping[str, tuple[str, str]],
    description: str,
) -> int:
    """Parse ``argv`` as ``<subcommand> [args]`` and run it; shared by nested commands."""
    present = available(commands)
    listing = "\n".join(f"  {name:<10} {text}" for name, (_, text) in present.items())
    parser = argparse.ArgumentParser(
        prog=prog,
        description=description,
        epilog=f"subcommands:\n{listing}\n\n'{prog} SUBCOMMAND --help' for each one's options.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("subcommand", choices=sorted(present), metavar="SUBCOMMAND")
    parser.add_argument("args", nargs=argparse.REMAINDER, help=argparse.SUPPRESS)
    if not argv:
        parser.print_help()
        return 2
    if argv[0] in ("-h", "--help"):
        parser.print_help()
        return 0
    ns = parser.parse_args(argv[:1])
    module_name, text = present[ns.subcommand]
    module = importlib.import_module(module_name)
    if hasattr(module, "run_argv"):  # a command group with subcommands of its own
        return int(module.run_argv(list(argv[1:])) or 0)
    sub = argparse.ArgumentParser(prog=f"{prog} {ns.subcommand}", description=text)
    module.add_arguments(sub)
    sub_args = sub.parse_args(list(argv[1:]))
    return int(module.main(sub_args) or 0)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``splitter`` console script."""
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    argv = list(sys.argv[1:] if argv is None else argv)
    return dispatch(
        "splitter",
        argv,
        COMMANDS,
        "SPLITTER: inertial-morphing attitude control of a tethered pair of jumping quadrupeds.",
    )


if __name__ == "__main__":
    sys.exit(main())
