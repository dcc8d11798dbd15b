"""``splitter bench {sim,mpc,bag,graph}``: benchmarks that print figures (JSON with --json)."""

from __future__ import annotations

from collections.abc import Sequence

from splitter_bringup.cli.main import dispatch

BENCHMARKS = {
    "sim": ("splitter_sim.bench", "real-time factor of the bare simulator"),
    "mpc": (
        "splitter_tools.bench_mpc",
        "MPC solve times against a plain Opti+IPOPT baseline",
    ),
    "bag": ("splitter_tools.bench_bag", "sustained bag write rate without loss"),
    "graph": (
        "splitter_tools.bench_graph",
        "real-time factor of the lockstep node graph per scenario, against the library",
    ),
}


def run_argv(argv: Sequence[str]) -> int:
    """Run one benchmark: ``splitter bench NAME [options]``."""
    return dispatch("splitter bench", argv, BENCHMARKS, "Benchmarks that print figures.")
