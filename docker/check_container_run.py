"""Check a container run against a host run of the same scenario (`make container-test`).

Usage: python docker/check_container_run.py CONTAINER_DIR HOST_DIR

* both summaries hold the same metrics, equal within 1e-6 relative (the same wheels,
  the same compiled MPC code and glibc: the flights should agree to the last bits);
* the container's bag reads back with an independent rosbag2 reader (rosbags) and
  holds the whole flight.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from rosbags.highlevel import AnyReader

RELATIVE_TOLERANCE = 1e-6
ABSOLUTE_TOLERANCE = 1e-9


def metric_values(summary_path: Path) -> dict[str, float]:
    metrics = json.loads(summary_path.read_text())["metrics"]
    return {k: v["value"] for k, v in metrics.items() if isinstance(v.get("value"), float | int)}


def main(container_dir: Path, host_dir: Path) -> int:
    ours, theirs = (
        metric_values(container_dir / "summary.json"),
        metric_values(host_dir / "summary.json"),
    )
    problems = [f"metric {k} missing on one side" for k in sorted(set(ours) ^ set(theirs))]
    for key in sorted(set(ours) & set(theirs)):
        a, b = ours[key], theirs[key]
        if not math.isclose(a, b, rel_tol=RELATIVE_TOLERANCE, abs_tol=ABSOLUTE_TOLERANCE):
            problems.append(f"{key}: container {a!r}, host {b!r}")
    bags = sorted(container_dir.glob("*/bag"))
    if not bags:
        problems.append(f"no bag under {container_dir}")
    for bag in bags:
        with AnyReader([bag]) as reader:
            counts = {c.topic: c.msgcount for c in reader.connections}
            imu = [c for c in reader.connections if c.topic == "/splitter/imu"]
            last_ns = 0
            for connection, _, raw in reader.messages(connections=imu):
                msg = reader.deserialize(raw, connection.msgtype)
                last_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        print(
            f"{bag}: {sum(counts.values())} messages on {len(counts)} topics, "
            f"imu to t = {last_ns * 1e-9:.3f} s"
        )
        if counts.get("/splitter/imu", 0) < 100:
            problems.append(f"{bag}: only {counts.get('/splitter/imu', 0)} imu messages")
    print(f"{len(set(ours) & set(theirs))} metrics compared")
    for problem in problems:
        print(f"MISMATCH {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        print(__doc__, file=sys.stderr)
        raise SystemExit(2)
    raise SystemExit(main(Path(sys.argv[1]), Path(sys.argv[2])))
