"""The run interface: one call whatever executes the run (library backend here; the graph
backends are compared with the library in tests/test_inprocess_launch.py)."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_bringup.run.backends import BACKENDS, run, run_variant
from splitter_bringup.run.library import run_closed_loop
from splitter_bringup.scenario.definition import load_scenario


def test_library_backend_is_the_library_loop_bit_for_bit() -> None:
    scenario = load_scenario("spin_stabilization", "open_loop")
    via_interface = run_variant(scenario, "library")
    direct = run_closed_loop(scenario)
    assert len(via_interface.series) == len(direct)
    np.testing.assert_array_equal(via_interface.series.t_s, direct.t_s)
    np.testing.assert_array_equal(
        via_interface.series.angular_velocity_rad_s, direct.angular_velocity_rad_s
    )
    assert via_interface.startup_s >= 0.0 and via_interface.flight_wall_time_s > 0.0
    assert via_interface.facts == {}


def test_unknown_backend_and_missing_run_folder_are_refused(tmp_path) -> None:
    scenario = load_scenario("spin_stabilization", "open_loop")
    assert BACKENDS == ("library", "processes", "inprocess")
    with pytest.raises(ValueError, match="not one of"):
        run(scenario, "dask")
    with pytest.raises(ValueError, match="out_dir"):
        run(scenario, "processes")
    with pytest.raises(ValueError, match="library-backend"):
        run(scenario, "inprocess", out_dir=tmp_path, estimator=False)
