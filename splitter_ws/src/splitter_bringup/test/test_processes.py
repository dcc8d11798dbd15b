"""The supervisor of the node processes: outcomes, and the order in which it stops them.

ROS-free: the children are small Python processes that log when they get SIGINT and
when they exit, so the order is read from their own records, not from timing guesses.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from splitter_bringup.run.processes import ProcessSpec, Supervisor

# A child that appends "<name> signal <t>" on SIGINT, works `linger` seconds more (a node
# flushing its last messages) and appends "<name> exit <t>" just before it exits.
CHILD = """
import signal, sys, time
name, log, linger = sys.argv[1], sys.argv[2], float(sys.argv[3])
stop = []
signal.signal(signal.SIGINT, lambda *_: stop.append(time.monotonic()))
with open(log, "a") as f:
    f.write(f"{name} ready {time.monotonic()}\\n")
while not stop:
    time.sleep(0.01)
with open(log, "a") as f:
    f.write(f"{name} signal {stop[0]}\\n")
time.sleep(linger)
with open(log, "a") as f:
    f.write(f"{name} exit {time.monotonic()}\\n")
"""


def child(name: str, log: Path, linger_s: float, **flags: bool) -> ProcessSpec:
    argv = (sys.executable, "-c", CHILD, name, str(log), str(linger_s))
    return ProcessSpec(name, argv, {}, **flags)


def wait_until_ready(log: Path, names: list[str], timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        text = log.read_text() if log.exists() else ""
        if all(f"{n} ready" in text for n in names):
            return
        time.sleep(0.02)
    raise TimeoutError(f"children not ready: {log.read_text() if log.exists() else ''}")


def events(log: Path) -> dict[tuple[str, str], float]:
    out = {}
    for line in log.read_text().splitlines():
        name, what, t = line.split()
        out[(name, what)] = float(t)
    return out


def test_the_recorder_is_stopped_only_after_every_other_child_exited(tmp_path: Path) -> None:
    log = tmp_path / "events.log"
    supervisor = Supervisor(on_line=lambda name, line: None)
    supervisor.start(child("recorder", log, 0.0, stops_last=True))
    supervisor.start(child("mpc", log, 0.3))
    supervisor.start(child("simulator", log, 0.1))
    wait_until_ready(log, ["recorder", "mpc", "simulator"])
    codes = supervisor.stop_all(grace_s=20.0)
    assert codes == {"recorder": 0, "mpc": 0, "simulator": 0}
    seen = events(log)
    last_exit_of_others = max(seen[("mpc", "exit")], seen[("simulator", "exit")])
    assert seen[("recorder", "signal")] > last_exit_of_others


def test_wait_names_the_child_that_died_and_the_one_that_ended_the_run(tmp_path: Path) -> None:
    quick = (sys.executable, "-c", "raise SystemExit(3)")
    supervisor = Supervisor(on_line=lambda name, line: None)
    supervisor.start(ProcessSpec("mpc", quick, {}))
    assert supervisor.wait(timeout_s=30.0) == ("died:mpc", 3)
    supervisor.stop_all()

    supervisor = Supervisor(on_line=lambda name, line: None)
    supervisor.start(ProcessSpec("simulator", (sys.executable, "-c", "pass"), {}, ends_run=True))
    assert supervisor.wait(timeout_s=30.0) == ("ended", 0)
    supervisor.stop_all()
