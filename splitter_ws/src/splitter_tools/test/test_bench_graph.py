"""The backend comparison of ``splitter bench graph``."""

from __future__ import annotations

import subprocess
import sys

import pytest

from splitter_tools.bench_graph import (
    METRIC_FLOOR,
    cpu_goal_s,
    cpu_seconds,
    largest_relative_difference,
)


def test_the_cpu_count_includes_the_processes_it_started() -> None:
    """A child that burns ~0.4 s of CPU shows up in the count once waited for."""
    before = cpu_seconds()
    burn = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.4: pass"
    subprocess.run([sys.executable, "-c", burn], check=True)
    assert cpu_seconds() - before >= 0.4
    assert cpu_goal_s(16.0) == pytest.approx(0.8 * 16.0 + 5.0)


def test_largest_relative_difference_names_the_metric() -> None:
    worst, name = largest_relative_difference(
        {"speed": 3.0, "height": 4.0, "only_a": 1.0}, {"speed": 3.03, "height": 4.0}
    )
    assert name == "speed"
    assert worst == pytest.approx(0.03 / 3.03)


def test_round_off_zeros_are_compared_absolutely() -> None:
    worst, name = largest_relative_difference({"residual": 1e-7}, {"residual": -1e-9})
    assert name == "residual"
    assert worst == pytest.approx(1.01e-7 / METRIC_FLOOR)
    assert largest_relative_difference({"x": 2.0}, {"x": 2.0}) == (0.0, "")


def test_the_time_plot_splits_each_flight_and_refuses_a_run_without_its_floor(tmp_path) -> None:
    from splitter_bringup.figures.plots import plot_graph_time

    run = {
        "scenario": "lunar_jumping",
        "mode": "in-process",
        "duration_s": 16.0,
        "flight_wall_time_s": 7.0,
        "transport_floor_s": 1.5,
        "library_flight_wall_time_s": 2.0,
    }
    path = plot_graph_time([run, {**run, "mode": "processes"}], tmp_path / "time.png", 5.0)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(KeyError, match="transport_floor_s"):
        plot_graph_time([{k: v for k, v in run.items() if k != "transport_floor_s"}], path)
