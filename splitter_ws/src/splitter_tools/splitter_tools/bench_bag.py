"""``splitter bench bag``: sustained messages per second a bag records without loss.

Two figures, both counted back from the written bag (metadata.yaml, MCAP
statistics and a full read must all agree with what was sent):

1. writer: :class:`~splitter_bag.core.writer.BagWriter` alone, fed the graph's
   message mix as serialized CDR (one simulator step: clock, IMU, odometry,
   inertia, joint states, two contact wrenches; the control topics every second
   step; markers and diagnostics at their rates);
2. graph path: a publisher process sends that mix at a fixed rate with the
   graph's QoS over the loopback DDS profile to a :class:`RecorderNode` in this
   process; rates go up until a stage loses a message. The highest lossless
   rate is the figure.
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from splitter_bag.core.info import check_consistency
from splitter_bag.core.metadata import read_metadata
from splitter_bag.core.reader import read_messages
from splitter_bag.core.writer import BagWriter, WriterOptions
from splitter_msgs_py import names

_NS_PER_S = 1_000_000_000
SIM_STEP_NS = 5_000_000  # [ns] DESIGN.md section 7
DEFAULT_RATES = (2_000, 5_000, 10_000, 20_000, 30_000, 40_000, 60_000)  # [msg/s] graph-path stages


def graph_mix(n_steps: int = 200) -> list[tuple[str, str, bytes, int]]:
    """(topic, type, cdr, stamp_ns) of ``n_steps`` simulator steps, in publishing order."""
    from rclpy.serialization import serialize_message
    from visualization_msgs.msg import Marker, MarkerArray

    from splitter_msgs_py import conversions as cv

    rng = np.random.default_rng(0)
    out: list[tuple[str, str, bytes, int]] = []

    def add(topic: str, msg: object, t_ns: int) -> None:
        out.append((topic, names.TOPIC_TYPES[topic], serialize_message(msg), t_ns))

    for k in range(n_steps):
        t = k * SIM_STEP_NS
        w = rng.normal(size=3)
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        add(names.CLOCK, cv.clock_to_msg(t), t)
        add(
            names.JOINT_STATES,
            cv.joint_state_to_msg(t, rng.normal(size=25), rng.normal(size=25)),
            t,
        )
        add(names.INERTIA, cv.vector3_to_msg(t, rng.uniform(1, 50, size=3)), t)
        add(names.ODOM, cv.odom_to_msg(t, rng.normal(size=3), q, rng.normal(size=3), w), t)
        for topic in names.CONTACT_WRENCHES:
            add(topic, cv.wrench_to_msg(t, rng.normal(size=3), rng.normal(size=3), "world"), t)
        add(names.IMU, cv.imu_to_msg(t, q, w, rng.normal(size=3)), t)
        if k % 2 == 0:
            add(names.INERTIA_SETPOINT, cv.vector3_to_msg(t, rng.uniform(1, 50, size=3)), t)
            add(names.JOINT_COMMANDS, cv.joint_state_to_msg(t, rng.normal(size=25)), t)
            add(names.JUMP_COMMAND, cv.wrench_to_msg(t, np.zeros(3), np.zeros(3), "world"), t)
        if k % 8 == 0:
            markers = MarkerArray(markers=[Marker(id=i, ns="splitter") for i in range(12)])
            for m in markers.markers:
                m.header.stamp = cv.stamp_to_msg(t)
                m.header.frame_id = names.WORLD_FRAME
            add(names.MARKERS, markers, t)
        if k % 20 == 0:
            status = cv.DiagnosticStatusSample(
                "simulator: state", 0, "ok", {"energy_j": float(w @ w), "tension_n": 12.5}
            )
            add(names.DIAGNOSTICS, cv.diagnostics_to_msg(t, [status]), t)
    return out


def bench_writer(bag_dir: Path, min_messages: int = 200_000) -> dict[str, float | int | bool]:
    """Writer throughput on the graph mix; verified by reading the bag back."""
    mix = graph_mix()
    span_ns = len({m[3] for m in mix}) * SIM_STEP_NS
    sent: dict[str, int] = {}
    n_bytes = 0
    t0 = time.perf_counter()
    with BagWriter(bag_dir, WriterOptions()) as bag:
        for topic, type_name, _, _ in mix:
            bag.add_topic(topic, type_name)
        rep = 0
        while sum(sent.values()) < min_messages:
            offset = rep * span_ns
            for topic, _, data, t_ns in mix:
                bag.write(topic, data, t_ns + offset, t_ns + offset)
                sent[topic] = sent.get(topic, 0) + 1
                n_bytes += len(data)
            rep += 1
    elapsed = time.perf_counter() - t0
    total = sum(sent.values())
    read_back = sum(1 for _ in read_messages(bag_dir))
    metadata = read_metadata(bag_dir)
    counts_ok = (
        check_consistency(bag_dir).ok
        and read_back == total
        and all(metadata.topic(t).message_count == n for t, n in sent.items())
    )
    return {
        "messages": total,
        "seconds": elapsed,
        "messages_per_s": total / elapsed,
        "payload_mb_per_s": n_bytes / elapsed / 1e6,
        "bag_bytes": sum(p.stat().st_size for p in bag_dir.glob("*.mcap")),
        "lossless": counts_ok,
    }


def publish_main(rate: float, duration_s: float, domain_id: int) -> None:
    """Publisher process: the graph mix at ``rate`` msg/s; prints what it sent as JSON."""
    import rclpy

    from splitter_msgs_py import qos
    from splitter_msgs_py.conversions import message_class

    mix = graph_mix()
    rclpy.init(domain_id=domain_id)
    node = rclpy.create_node("bench_publisher")
    pubs = {
        topic: node.create_publisher(message_class(type_name), topic, qos.qos_for(topic))
        for topic, type_name, _, _ in mix
    }
    deadline = time.monotonic() + 20.0
    while any(p.get_subscription_count() == 0 for p in pubs.values()):
        if time.monotonic() > deadline:
            raise TimeoutError("the recorder did not subscribe to every topic within 20 s")
        time.sleep(0.05)
    print("READY", flush=True)
    sys.stdin.readline()  # the recorder says go
    sent: dict[str, int] = dict.fromkeys(pubs, 0)
    total_target = int(rate * duration_s)
    n = 0
    t0 = time.monotonic()
    while n < total_target:
        due = min(total_target, int(rate * (time.monotonic() - t0)) + 1)
        while n < due:
            topic, _, data, _ = mix[n % len(mix)]
            pubs[topic].publish(data)
            sent[topic] += 1
            n += 1
        time.sleep(0.0005)
    elapsed = time.monotonic() - t0
    time.sleep(1.0)  # let reliable delivery finish before the endpoints go away
    print(json.dumps({"sent": sent, "seconds": elapsed}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()


def bench_graph_stage(rate: float, duration_s: float, bag_dir: Path) -> dict[str, object]:
    """One stage: a publisher process at ``rate`` into a recorder in this process."""
    import rclpy
    from rclpy.parameter import Parameter

    from splitter_bag.recorder_node import RecorderNode, recorder_executor
    from splitter_msgs_py.environment import ros_environment

    domain_id = 150 + os.getpid() % 50
    env = ros_environment(domain_id=domain_id)
    code = (
        "import sys; from splitter_tools.bench_bag import publish_main; "
        f"publish_main({rate!r}, {duration_s!r}, {domain_id})"
    )
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=domain_id)
    proc = subprocess.Popen(
        [sys.executable, "-c", code],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        node = RecorderNode(
            context=context,
            parameter_overrides=[
                Parameter("output", value=str(bag_dir)),
                Parameter("regex", value="^/(splitter|clock|diagnostics)"),
                Parameter("discovery_period_s", value=0.1),
            ],
        )
        executor = recorder_executor(node)
        assert proc.stdout is not None and proc.stdin is not None
        lines: queue.Queue[str] = queue.Queue()
        reader = threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True)
        reader.start()
        while lines.empty():
            executor.spin_once(timeout_sec=0.01)
            if proc.poll() is not None and lines.empty():
                raise RuntimeError(f"publisher process ended early ({proc.returncode})")
        if lines.get().strip() != "READY":
            raise RuntimeError("unexpected output from the publisher process")
        proc.stdin.write("go\n")
        proc.stdin.flush()
        while proc.poll() is None:
            executor.spin_once(timeout_sec=0.01)
        for _ in range(100):  # drain what is still queued
            executor.spin_once(timeout_sec=0.01)
        reader.join(5.0)
        report = json.loads(lines.get(timeout=5.0))
        node.destroy_node()
    finally:
        if proc.poll() is None:
            proc.kill()
        context.try_shutdown()
    sent: dict[str, int] = report["sent"]
    metadata = read_metadata(bag_dir)
    recorded = {t.topic_metadata.name: t.message_count for t in metadata.topics_with_message_count}
    lost = {t: n - recorded.get(t, 0) for t, n in sent.items() if n != recorded.get(t, 0)}
    return {
        "target_messages_per_s": rate,
        "achieved_messages_per_s": sum(sent.values()) / report["seconds"],
        "sent": sum(sent.values()),
        "recorded": sum(recorded.get(t, 0) for t in sent),
        "lost_by_topic": lost,
        "lossless": not lost and check_consistency(bag_dir).ok,
    }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument(
        "--duration", type=float, default=2.0, help="seconds of publishing per stage [s]"
    )
    parser.add_argument(
        "--rates",
        type=float,
        nargs="+",
        default=list(DEFAULT_RATES),
        help="publisher rates of the graph-path stages [msg/s]",
    )
    parser.add_argument("--no-graph", action="store_true", help="writer figure only")


def main(args: argparse.Namespace) -> int:
    results: dict[str, object] = {}
    with tempfile.TemporaryDirectory(prefix="splitter_bench_bag_") as tmp:
        writer = bench_writer(Path(tmp) / "writer")
        results["writer"] = writer
        if not args.json:
            print(
                f"writer: {writer['messages_per_s']:.0f} msg/s "
                f"({writer['payload_mb_per_s']:.1f} MB/s of CDR), lossless={writer['lossless']}"
            )
        stages = []
        if not args.no_graph:
            for i, rate in enumerate(sorted(args.rates)):
                stage = bench_graph_stage(rate, args.duration, Path(tmp) / f"graph_{i}")
                stages.append(stage)
                if not args.json:
                    print(
                        f"graph path at {rate:.0f} msg/s (achieved "
                        f"{stage['achieved_messages_per_s']:.0f}): "
                        f"{stage['recorded']}/{stage['sent']} recorded"
                    )
                if not stage["lossless"]:
                    break
        lossless = [s["achieved_messages_per_s"] for s in stages if s["lossless"]]
        results["graph_path"] = {
            "stages": stages,
            "sustained_lossless_messages_per_s": max(lossless) if lossless else 0.0,
        }
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        print(
            "sustained lossless (publisher process -> recorder): "
            f"{results['graph_path']['sustained_lossless_messages_per_s']:.0f} msg/s"
        )
    return 0 if writer["lossless"] else 1
