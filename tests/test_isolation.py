"""Graphs on one machine never see each other, and a graph dies with its launcher.

* Two ``splitter run`` started at the same instant with no domain named choose two
  domains; each bag holds only its own run and each summary equals a solo run's
  (every figure but the wall-time ones and the domain).
* ``splitter launch`` with a publisher of another tool joining its domain (read from
  the run folder) on one of its topics: the watchdog reports it. Then the launcher is
  killed with SIGKILL mid-flight: within 2 s no process of its
  graph is left (the nodes and the MPC's solver worker: found by the run folder in
  their environment), and ``splitter bag recover`` makes the bag one that rosbags,
  an independent rosbag2 reader, reads to the last message.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import Imu

from splitter_bag.core.reader import read_messages
from splitter_bringup.scenario.definition import scenario_dir
from splitter_msgs_py import names

SPLITTER = Path(sys.executable).with_name("splitter")
DURATION_S = 2.0  # [s] simulated: the shortest flight that still re-plans 20 times
SIM_DT_S = 0.005  # [s]
WALL_KEYS = {"wall_time_s", "startup_s", "flight_wall_time_s", "flight_real_time_factor"}
RUN_TIMEOUT_S = 300.0  # [s] wall, both runs sharing the 2 cores
LEFT_OVER_WITHIN_S = 2.0  # [s] the bound for the graph to end with its launcher


def unnamed_domain_env() -> dict[str, str]:
    """This suite's environment (loopback DDS profile, ...) with no ROS domain named."""
    env = dict(os.environ)
    env.pop("ROS_DOMAIN_ID", None)
    return env


def short_scenario(tmp_path: Path) -> Path:
    """spin_stabilization (the mpc variant) flown for DURATION_S."""
    data = yaml.safe_load((scenario_dir() / "spin_stabilization.yaml").read_text())
    data["duration_s"] = DURATION_S
    data["variants"] = {"mpc": data["variants"]["mpc"]}
    path = tmp_path / "spin_short.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def run_command(scenario: Path, out: Path) -> list[str]:
    return [str(SPLITTER), "run", str(scenario), "--out", str(out), "--no-plots", "--no-animation"]


def without_wall_time(summary: dict) -> dict:
    variant = dict(summary["variants"]["mpc"])
    for key in (*WALL_KEYS, "domain_id"):
        variant.pop(key)
    return variant


def imu_stamps(bag: Path) -> list[int]:
    stamps = []
    for message in read_messages(bag, topics=[names.IMU]):
        stamp = deserialize_message(message.data, Imu).header.stamp
        stamps.append(stamp.sec * 1_000_000_000 + stamp.nanosec)
    return stamps


@pytest.mark.slow
def test_two_runs_at_once_with_no_domain_named_never_see_each_other(tmp_path: Path) -> None:
    scenario = short_scenario(tmp_path)
    env = unnamed_domain_env()
    solo = subprocess.run(
        run_command(scenario, tmp_path / "solo"),
        env=env,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
        check=False,
    )
    assert solo.returncode == 0, solo.stderr[-3000:]
    pair = [
        subprocess.Popen(
            run_command(scenario, tmp_path / name),
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for name in ("first", "second")
    ]
    outputs = [p.communicate(timeout=RUN_TIMEOUT_S) for p in pair]
    for process, (_, err) in zip(pair, outputs, strict=True):
        assert process.returncode == 0, err[-3000:]

    reference = json.loads((tmp_path / "solo" / "summary.json").read_text())
    solo_imu = imu_stamps(tmp_path / "solo" / "mpc" / "bag")
    steps = round(DURATION_S / SIM_DT_S)
    assert len(solo_imu) >= steps  # every step, the initial state included
    domains = []
    for name, (_, err) in zip(("first", "second"), outputs, strict=True):
        run = tmp_path / name
        summary = json.loads((run / "summary.json").read_text())
        foreign = [line for line in err.splitlines() if "FOREIGN publisher" in line]
        assert summary["variants"]["mpc"]["foreign_publishers"] == 0, (name, foreign)
        assert without_wall_time(summary) == without_wall_time(reference), name
        domain = summary["variants"]["mpc"]["domain_id"]
        assert int((run / "mpc" / "domain_id").read_text()) == domain
        assert f"ROS domain {domain} (chosen" in err
        domains.append(domain)
        stamps = imu_stamps(run / "mpc" / "bag")
        # only its own run: no stamp twice, none out of order, as many as the solo run's
        assert stamps == sorted(set(stamps)), name
        assert stamps == solo_imu, name
    assert domains[0] != domains[1]
    print(f"domains {domains}, {len(solo_imu)} imu messages in each bag, summaries equal")
    held = range(int(os.environ["ROS_DOMAIN_ID"]), int(os.environ["ROS_DOMAIN_ID"]) + 22)
    assert not set(domains) & set(held), "a run chose a domain this test suite uses"


def graph_processes(run_dir: Path) -> dict[int, str]:
    """pid -> command line of every process whose environment names ``run_dir``."""
    marker = f"SPLITTER_RUN_DIR={run_dir.resolve()}".encode()
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            environ = (entry / "environ").read_bytes().split(b"\0")
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:  # ended meanwhile, or not ours
            continue
        if marker in environ:
            found[int(entry.name)] = cmdline
    return found


INTRUDER = """
import sys, time
import rclpy
from visualization_msgs.msg import MarkerArray
rclpy.init(domain_id=int(sys.argv[1]))
node = rclpy.create_node("intruder")
node.create_publisher(MarkerArray, "/splitter/markers", 10)
print("ready", flush=True)
time.sleep(120)
"""


def join_with_an_intruder(run_dir: Path, timeout_s: float = 60.0) -> subprocess.Popen:
    """A process of another tool joining the graph's domain (read from its run folder)
    with a publisher on one of the graph's topics (it publishes nothing)."""
    deadline = time.monotonic() + timeout_s
    while not (run_dir / "domain_id").exists():
        assert time.monotonic() < deadline, "the launcher wrote no domain_id"
        time.sleep(0.05)
    domain = (run_dir / "domain_id").read_text().strip()
    return subprocess.Popen(
        [sys.executable, "-c", INTRUDER, domain], stdout=subprocess.PIPE, text=True
    )


def wait_for_line(path: Path, text: str, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if path.exists() and text in path.read_text():
            return
        time.sleep(0.1)
    raise AssertionError(f"no {text!r} in {path}")


def wait_for_bag_data(run_dir: Path, timeout_s: float = 120.0) -> None:
    """Until the simulator steps and the bag holds a written chunk."""
    log = run_dir / "logs" / "simulator.log"
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if log.exists() and "stepping starts" in log.read_text():
            break
        time.sleep(0.1)
    else:
        raise AssertionError("the simulator never started stepping")
    time.sleep(1.5)  # mid-flight: ~1-2 s of the 8 s flight


@pytest.mark.slow
def test_a_graph_dies_with_its_launcher_killed_and_its_bag_recovers(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    run_dir = tmp_path / "launch"
    launcher = subprocess.Popen(
        [str(SPLITTER), "launch", "spin_stabilization", "--variant", "mpc", "--out", str(run_dir)],
        env=unnamed_domain_env(),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # its own process group, as a shell job
    )
    intruder = None
    try:
        intruder = join_with_an_intruder(run_dir)
        wait_for_line(
            run_dir / "logs" / "graph_watchdog.log",
            "FOREIGN publisher /intruder on /splitter/markers: not a node of this graph",
        )
        wait_for_bag_data(run_dir)
        graph = graph_processes(run_dir)
        commands = " ".join(graph.values())
        # the six nodes and the MPC's solver worker
        assert len(graph) == 7, graph
        assert "splitter_mpc.core.solver_worker" in commands
        os.killpg(launcher.pid, signal.SIGKILL)
        killed = time.monotonic()
        launcher.wait()
        while graph_processes(run_dir) and time.monotonic() - killed < LEFT_OVER_WITHIN_S:
            time.sleep(0.05)
        left = graph_processes(run_dir)
        gone_after_s = time.monotonic() - killed
    finally:
        if intruder is not None:
            intruder.kill()
            intruder.wait()
        if launcher.poll() is None:
            launcher.kill()
        for pid in graph_processes(run_dir):  # never leave orphans, even when failing
            os.kill(pid, signal.SIGKILL)
    assert not left, f"left {gone_after_s:.2f} s after the launcher's SIGKILL: {left}"
    print(f"graph of {len(graph)} processes gone {gone_after_s:.3f} s after the SIGKILL")
    bag = run_dir / "bag"
    recovered = subprocess.run(
        [str(SPLITTER), "bag", "recover", str(bag)],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert recovered.returncode == 0, recovered.stdout + recovered.stderr
    typestore = get_typestore(Stores.ROS2_JAZZY)
    counts: dict[str, int] = {}
    imu_ns = []
    with Reader(bag) as reader:
        assert reader.message_count > 0
        for connection, _, raw in reader.messages():
            message = typestore.deserialize_cdr(raw, connection.msgtype)
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
            if connection.topic == names.IMU:
                imu_ns.append(
                    message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
                )
        assert sum(counts.values()) == reader.message_count
    assert imu_ns == sorted(set(imu_ns))
    print(f"recovered bag: {sum(counts.values())} messages, imu to t = {imu_ns[-1] * 1e-9:.3f} s")
    assert len(imu_ns) >= 50, counts  # mid-flight: a good part of a second was recorded
    assert imu_ns[-1] < 8_000_000_000, "the flight was not killed mid-way"
