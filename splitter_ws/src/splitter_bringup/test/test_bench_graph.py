"""The backend comparison of ``splitter bench graph``."""

from __future__ import annotations

import pytest

from splitter_bringup.commands.bench_graph import METRIC_FLOOR, largest_relative_difference


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
