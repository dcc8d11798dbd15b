"""``splitter bench mpc`` on a short flight: both closed loops agree and the figures are there.

Timing is not asserted here (speed goals are met by the benchmark command itself).
"""

from __future__ import annotations

import math

import pytest

from splitter_tools.bench_mpc import parse_backend, run_benchmark

pytestmark = pytest.mark.slow


def test_short_benchmark_reports_agreeing_closed_loops_and_plots(tmp_path) -> None:
    plot = tmp_path / "solve_times.png"
    result = run_benchmark(duration_s=0.3, compile_code=False, plot_path=plot)
    assert result["n_solves"] == 3  # re-plans at 0, 0.1 and 0.2 s
    assert result["failed_solves"] == 0
    # the same problem solved two ways: the closed loops agree (issue 4: <= 0.01 rad/s)
    assert result["max_abs_w_diff"] <= 0.01
    for key in ("baseline_median_ms", "median_ms", "p99_ms", "max_ms", "speedup_median"):
        assert math.isfinite(result[key]) and result[key] > 0.0
    assert result["median_ms"] <= result["p99_ms"] <= result["max_ms"]
    assert plot.stat().st_size > 10_000
    assert (result["goal_p99_ms"], result["goal_speedup_median"]) == (3.0, 100.0)  # issue 18


def test_back_ends_side_by_side_in_one_run() -> None:
    """The worker's and the in-process fatrop solve the same problems: the same loops."""
    result = run_benchmark(("fatrop", "fatrop/in-process"), duration_s=0.3, compile_code=False)
    worker, own = result["backends"]
    assert (worker["backend"], worker["in_process"]) == ("fatrop", False)
    assert (own["backend"], own["in_process"]) == ("fatrop/in-process", True)
    assert result["median_ms"] == worker["median_ms"]  # the first one is the top level
    for figures in (worker, own):
        assert figures["n_solves"] == 3 and figures["failed_solves"] == 0
        assert figures["max_abs_w_diff"] <= 0.01
    with pytest.raises(ValueError, match="unknown back-end"):
        parse_backend("fatrop/elsewhere")
    assert parse_backend("sqp/in-process") == ("sqp", False)


def test_the_condensed_sqp_flies_the_turn_as_the_baseline_does_in_its_own_process() -> None:
    """The first second of the turn holds its hardest re-plans (15-25 SQP iterations)."""
    result = run_benchmark("condensed_sqp/in-process", duration_s=1.0, compile_code=False)
    assert (result["solver"], result["in_process"]) == ("condensed_sqp", True)
    assert result["n_solves"] == 10 and result["failed_solves"] == 0
    assert result["max_abs_w_diff"] <= 0.01
    assert result["median_iterations"] > 1  # it iterates to convergence, not one RTI step
