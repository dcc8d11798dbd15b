"""The launcher as a user runs it: its processes, Ctrl-C/SIGTERM, a node that dies.

Also checks the ROS launch file for full installs against the launcher's graph
(it cannot run here: launch and launch_ros are not installable on these machines).
"""

from __future__ import annotations

import ast
import configparser
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from splitter_bringup.scenario.definition import load_scenario
from splitter_bringup.scenario.graph_config import graph_nodes
from splitter_msgs_py.environment import ros_environment

ROOT = Path(__file__).resolve().parents[1]
SPLITTER = Path(sys.executable).with_name("splitter")


def launch_file_executables() -> dict[str, tuple[str, str]]:
    path = ROOT / "splitter_ws/src/splitter_bringup/launch/splitter.launch.py"
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Assign) and getattr(node.targets[0], "id", "") == "EXECUTABLES":
            return ast.literal_eval(node.value)
    raise AssertionError("EXECUTABLES not found in the launch file")


def test_launch_file_starts_every_node_of_the_graph_by_its_console_script(tmp_path) -> None:
    executables = launch_file_executables()
    nodes = graph_nodes(load_scenario("lunar_jumping"), bag_dir=tmp_path)
    assert {n.name for n in nodes} == set(executables)
    for node in nodes:
        package, script = executables[node.name]
        setup = configparser.ConfigParser()
        setup.read(ROOT / f"splitter_ws/src/{package}/setup.cfg")
        scripts = setup["options.entry_points"]["console_scripts"].strip().splitlines()
        module = node.entry.split(":")[0]
        assert f"{script} = {module}:main" in scripts, (package, script)


def start_launcher(out: Path, domain_id: int, *options: str) -> subprocess.Popen:
    env = ros_environment(domain_id=domain_id)
    options = options or ("--no-record",)
    return subprocess.Popen(
        [str(SPLITTER), "launch", "spin_stabilization", "--out", str(out), *options],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )


def node_pids(out: Path) -> dict[str, int]:
    """PIDs of the node processes this launch started (their params files are in ``out``)."""
    pids = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        for arg in cmdline:
            text = arg.decode(errors="replace")
            if text.startswith(str(out / "params")):
                pids[Path(text).stem] = int(entry.name)
    return pids


def wait_for_stepping(out: Path, timeout_s: float = 120.0) -> None:
    log = out / "logs" / "simulator.log"
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if log.exists() and "stepping starts" in log.read_text():
            return
        time.sleep(0.2)
    raise AssertionError("the simulator never started stepping")


@pytest.mark.slow
def test_sigterm_stops_every_node_cleanly(tmp_path: Path) -> None:
    launcher = start_launcher(tmp_path, int(os.environ["ROS_DOMAIN_ID"]) + 10)
    try:
        wait_for_stepping(tmp_path)
        assert set(node_pids(tmp_path)) == {
            "inertial_morphing_mpc",
            "ik_tether_allocator",
            "gait_phase_manager",
            "graph_watchdog",
            "simulator",
        }
        launcher.send_signal(signal.SIGTERM)
        output, _ = launcher.communicate(timeout=60)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    assert launcher.returncode == 130, output
    assert node_pids(tmp_path) == {}, "a node outlived the launcher"
    for name in ("inertial_morphing_mpc", "ik_tether_allocator", "gait_phase_manager"):
        assert re.search(rf"{name}\s+exit code 0", output), output[-2000:]


@pytest.mark.slow
def test_a_node_that_dies_fails_the_launch(tmp_path: Path) -> None:
    launcher = start_launcher(tmp_path, int(os.environ["ROS_DOMAIN_ID"]) + 11)
    try:
        wait_for_stepping(tmp_path)
        os.kill(node_pids(tmp_path)["ik_tether_allocator"], signal.SIGKILL)
        output, _ = launcher.communicate(timeout=60)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    assert launcher.returncode == 1, output
    assert "ik_tether_allocator exited with code -9" in output
    assert node_pids(tmp_path) == {}, "a node outlived the launcher"


STALL_TIMEOUT_S = 3.0  # [s] wall


@pytest.mark.slow
def test_a_stalled_node_is_named_and_the_lockstep_run_fails_with_its_bag_finalized(
    tmp_path: Path,
) -> None:
    from splitter_bag.core.reader import read_messages

    launcher = start_launcher(
        tmp_path,
        int(os.environ["ROS_DOMAIN_ID"]) + 12,
        "--stall-timeout",
        str(STALL_TIMEOUT_S),
    )
    try:
        wait_for_stepping(tmp_path)
        time.sleep(1.0)
        os.kill(node_pids(tmp_path)["inertial_morphing_mpc"], signal.SIGSTOP)  # frozen
        stopped_at = time.monotonic()
        output, _ = launcher.communicate(timeout=90)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    assert launcher.returncode == 1, output[-3000:]
    assert re.search(
        r"inertial_morphing_mpc makes no progress \(no /splitter/inertia_setpoint", output
    )
    assert time.monotonic() - stopped_at < STALL_TIMEOUT_S + 30.0
    assert node_pids(tmp_path) == {}, "a node outlived the launcher"
    # the bag is finalized (readable to its end) and holds the states until the stall
    states = sum(1 for _ in read_messages(tmp_path / "bag", topics=["/splitter/imu"]))
    assert states > 10


@pytest.mark.slow
def test_in_real_time_a_stalled_node_is_reported_and_the_rest_keeps_running(
    tmp_path: Path,
) -> None:
    launcher = start_launcher(
        tmp_path,
        int(os.environ["ROS_DOMAIN_ID"]) + 13,
        "--no-record",
        "--real-time",
        "--rate",
        "2",
        "--stall-timeout",
        str(STALL_TIMEOUT_S),
    )
    try:
        wait_for_stepping(tmp_path)
        os.kill(node_pids(tmp_path)["inertial_morphing_mpc"], signal.SIGSTOP)
        output, _ = launcher.communicate(timeout=90)
    finally:
        if launcher.poll() is None:
            launcher.kill()
    assert (
        "inertial_morphing_mpc makes no progress" in output and "the rest keeps running" in output
    )
    assert "simulation finished (duration_s reached)" in output, output[-3000:]  # ran to its end
    assert "stalled:inertial_morphing_mpc" in output  # reported again at the end
    assert node_pids(tmp_path) == {}, "a node outlived the launcher"
