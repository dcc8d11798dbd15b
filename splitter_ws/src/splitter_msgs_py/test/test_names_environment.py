"""Names are unique and complete; every test process runs with the loopback DDS profile."""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET

from splitter_msgs_py import names
from splitter_msgs_py.environment import (
    loopback_profile_path,
    ros_environment,
    uses_loopback_profile,
)


def test_joint_names_are_unique_and_complete() -> None:
    assert len(names.JOINT_NAMES) == 25 == len(set(names.JOINT_NAMES))
    assert names.JOINT_NAMES[-1] == names.TETHER_JOINT
    assert all(names.JOINT_INDEX[n] == i for i, n in enumerate(names.JOINT_NAMES))


def test_every_topic_is_typed() -> None:
    constants = {k: v for k, v in vars(names).items() if k.isupper() and isinstance(v, str)}
    topics = {v for v in constants.values() if v.startswith("/")}
    assert topics == set(names.TOPIC_TYPES)
    assert all("/msg/" in message_type for message_type in names.TOPIC_TYPES.values())


def test_profile_whitelists_only_loopback() -> None:
    tree = ET.parse(loopback_profile_path())
    ns = {"d": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
    addresses = [a.text for a in tree.getroot().iterfind(".//d:address", ns)]
    assert addresses and set(addresses) == {"127.0.0.1"}
    builtin = tree.getroot().find(".//d:useBuiltinTransports", ns)
    assert builtin is not None and builtin.text == "false"


def test_this_test_process_uses_the_loopback_profile() -> None:
    assert uses_loopback_profile()
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET"
    assert os.environ["RMW_IMPLEMENTATION"] == "rmw_fastrtps_cpp"


def test_child_processes_inherit_the_profile() -> None:
    code = "import os; print(os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'])"
    out = subprocess.run(
        [sys.executable, "-c", code],
        env=ros_environment(),
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == str(loopback_profile_path())


def test_multi_host_is_an_explicit_opt_in() -> None:
    env = ros_environment(base={}, multi_host=True)
    assert not uses_loopback_profile(env)
    assert uses_loopback_profile(ros_environment(base={}))
