"""No DDS socket of a test process can reach beyond 127.0.0.1.

A process with the project's environment talks pub/sub, then every UDP socket
it owns is read from /proc: all must be bound to 127.0.0.1. Without the
profile Fast DDS binds 0.0.0.0 (every interface) and sends multicast discovery
on the external interface; that control run is not made here (it would send
traffic beyond loopback): instead a socket bound to 0.0.0.0, which sends
nothing, proves the check can fail.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

from splitter_msgs_py.environment import ros_environment

PROBE = textwrap.dedent(
    """
    import json, os, socket, struct, time
    import rclpy
    from std_msgs.msg import String

    def udp_sockets():
        inodes = set()
        for fd in os.listdir("/proc/self/fd"):
            try:
                link = os.readlink(f"/proc/self/fd/{fd}")
            except OSError:
                continue
            if link.startswith("socket:["):
                inodes.add(link[8:-1])
        found = []
        for proto in ("udp", "udp6"):
            with open(f"/proc/net/{proto}") as table:
                next(table)
                for line in table:
                    cols = line.split()
                    if cols[9] in inodes:
                        address = cols[1].split(":")[0]
                        if proto == "udp":
                            address = socket.inet_ntoa(struct.pack("<I", int(address, 16)))
                        found.append(address)
        return found

    if os.environ.get("PROBE_BIND_ANY"):
        extra = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        extra.bind(("0.0.0.0", 0))
    rclpy.init()
    node = rclpy.create_node("loopback_probe")
    received = []
    node.create_subscription(String, "probe", lambda m: received.append(m.data), 10)
    pub = node.create_publisher(String, "probe", 10)
    deadline = time.monotonic() + 5.0
    while not received and time.monotonic() < deadline:
        pub.publish(String(data="ping"))
        rclpy.spin_once(node, timeout_sec=0.05)
    print(json.dumps({"received": len(received), "addresses": udp_sockets()}))
    node.destroy_node()
    rclpy.shutdown()
    """
)


def run_probe(env: dict[str, str]) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", PROBE],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_project_environment_binds_only_loopback() -> None:
    result = run_probe(ros_environment(domain_id=int(os.environ["ROS_DOMAIN_ID"])))
    assert result["received"] > 0, "pub/sub must work with the loopback profile"
    assert result["addresses"], "the probe should own DDS sockets"
    assert set(result["addresses"]) == {"127.0.0.1"}, result["addresses"]


def test_a_socket_open_to_every_interface_is_detected() -> None:
    env = ros_environment(domain_id=int(os.environ["ROS_DOMAIN_ID"]))
    env["PROBE_BIND_ANY"] = "1"
    assert "0.0.0.0" in run_probe(env)["addresses"]
