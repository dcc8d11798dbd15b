"""``splitter launch --in-process`` and ``splitter run --in-process``: the whole graph in
one process, recorded, with the library loop's result; a SIGTERM finalizes the bag."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from splitter_bag import read_metadata
from splitter_bringup.analysis.summary import metric_values
from splitter_bringup.run.graph_run import WallTiming, run_graph
from splitter_bringup.run.library import run_closed_loop
from splitter_bringup.scenario.definition import load_scenario
from splitter_msgs_py import names
from splitter_msgs_py.environment import ros_environment
from splitter_tools.bench_graph import largest_relative_difference

SPLITTER = Path(sys.executable).with_name("splitter")
SIM_DT_S = 0.005  # [s] simulator step: one /clock message each


@pytest.mark.slow
def test_in_process_run_records_the_whole_flight_with_the_library_result(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", str(int(os.environ["ROS_DOMAIN_ID"]) + 20))
    scenario = load_scenario("spin_stabilization", "mpc")
    timing: list[WallTiming] = []
    graph = run_graph("spin_stabilization", "mpc", tmp_path, timing=timing, in_process=True)
    run_dir = tmp_path / "mpc"
    assert {p.stem for p in (run_dir / "params").glob("*.yaml")} == {
        "recorder",
        "inertial_morphing_mpc",
        "ik_tether_allocator",
        "gait_phase_manager",
        "simulator",
    }
    counts = {
        t.topic_metadata.name: t.message_count
        for t in read_metadata(run_dir / "bag").topics_with_message_count
    }
    steps = round(scenario.duration_s / SIM_DT_S) + 1  # t = 0 .. duration, both included
    assert counts[names.CLOCK] == steps
    assert counts[names.IMU] == steps
    assert counts[names.JOINT_COMMANDS] == steps // 2 + 1  # every 10 ms control tick
    assert 0.0 < timing[0].flight_wall_time_s and timing[0].startup_s > 0.0
    worst, metric = largest_relative_difference(
        metric_values(graph, scenario), metric_values(run_closed_loop(scenario), scenario)
    )
    assert worst < 0.01, f"{metric} differs by {100 * worst:.3g} % from the library loop"


@pytest.mark.slow
def test_sigterm_stops_the_in_process_launch_with_its_bag_finalized(tmp_path: Path) -> None:
    env = ros_environment(domain_id=int(os.environ["ROS_DOMAIN_ID"]) + 21)
    env["PYTHONUNBUFFERED"] = "1"
    launcher = subprocess.Popen(
        [str(SPLITTER), "launch", "spin_stabilization", "--in-process", "--out", str(tmp_path)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline:
            line = launcher.stdout.readline()
            if "stepping starts" in line or not line:
                break
        assert launcher.poll() is None, "the launch ended before stepping"
        time.sleep(1.0)
        launcher.send_signal(signal.SIGTERM)
        output, _ = launcher.communicate(timeout=60)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    assert launcher.returncode == 130, output
    counts = {
        t.topic_metadata.name: t.message_count
        for t in read_metadata(tmp_path / "bag").topics_with_message_count
    }
    assert counts[names.CLOCK] > 0
    assert counts[names.CLOCK] < round(8.0 / SIM_DT_S), "the run was not stopped"
