"""SIGINT / SIGTERM stop a busy node between callbacks, with exit code 0.

Each case runs in its own process (signal handlers are process-wide). The node
publishes to itself every millisecond, so a signal lands while rclpy takes and
converts messages: the window where rclpy's own handler made nodes exit with 1.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from splitter_msgs_py.environment import ros_environment

# argv: signal name, then "project" (StopRequest + spin_until_stopped) or "twice" (two
# signals in one callback). Prints how spinning ended and how many messages arrived.
# (How rclpy's own handler ends such a node is a race inside rclpy, which no test here
# asserts: it failed fresh-clone runs either way.)
BUSY_NODE = """
import os, signal, sys, time
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String
from splitter_msgs_py.signals import StopRequest, spin_until_stopped

signum = signal.Signals[sys.argv[1]]
mode = sys.argv[2]
stop = StopRequest()
rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
node = rclpy.create_node("signal_probe")
received = []
publisher = node.create_publisher(String, "signal_probe", 10)
node.create_subscription(String, "signal_probe", received.append, 10)
node.create_timer(0.001, lambda: publisher.publish(String(data="x" * 100)))


def send_signal():
    os.kill(os.getpid(), signum)
    if mode == "twice":
        time.sleep(0.05)
        os.kill(os.getpid(), signum)
        time.sleep(0.05)


node.create_timer(0.3, send_signal)
try:
    spin_until_stopped(node, stop)
    print("stopped", len(received) > 0)
except ExternalShutdownException:
    print("external shutdown", len(received) > 0)
except KeyboardInterrupt:
    print("keyboard interrupt", len(received) > 0)
finally:
    node.destroy_node()
    rclpy.try_shutdown()
"""


def run_busy_node(signal_name: str, mode: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", BUSY_NODE, signal_name, mode],
        env=ros_environment(domain_id=int(os.environ["ROS_DOMAIN_ID"])),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


@pytest.mark.parametrize("signal_name", ["SIGINT", "SIGTERM"])
def test_a_stop_signal_ends_spinning_between_callbacks(signal_name: str) -> None:
    result = run_busy_node(signal_name, "project")
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "stopped True", result.stdout + result.stderr
    assert f"{signal_name}: stopping" in result.stderr


def test_a_second_signal_interrupts_a_stuck_callback() -> None:
    result = run_busy_node("SIGINT", "twice")
    assert result.stdout.strip() == "keyboard interrupt True", result.stdout + result.stderr
