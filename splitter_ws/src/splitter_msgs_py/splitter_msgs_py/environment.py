"""The ROS environment every process of the project runs with (DESIGN.md sections 6 and 8).

ROS-free: builds environment dictionaries for child processes and checks the
current one. Traffic stays on 127.0.0.1 unless a caller opts in to multi-host use.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Mapping
from importlib import resources
from pathlib import Path

RMW_IMPLEMENTATION = "rmw_fastrtps_cpp"
DEFAULT_DOMAIN_ID = 42


def loopback_profile_path() -> Path:
    """Path of the loopback-only Fast DDS profile shipped in this package."""
    return Path(str(resources.files("splitter_msgs_py.dds") / "fastdds_loopback.xml"))


def ros_environment(
    base: Mapping[str, str] | None = None,
    domain_id: int | None = None,
    multi_host: bool = False,
) -> dict[str, str]:
    """Environment for a process of the project.

    Loopback-only DDS unless ``multi_host`` is True (the explicit opt-in of
    DESIGN.md section 6). ``AMENT_PREFIX_PATH`` points at the running Python
    prefix, where the ROS wheels put ``share/``.
    """
    env = dict(os.environ if base is None else base)
    prefix = sys.prefix
    ament = env.get("AMENT_PREFIX_PATH", "")
    if prefix not in ament.split(os.pathsep):
        env["AMENT_PREFIX_PATH"] = os.pathsep.join(p for p in (prefix, ament) if p)
    env["RMW_IMPLEMENTATION"] = RMW_IMPLEMENTATION
    if domain_id is not None:
        if not 0 <= domain_id <= 232:
            raise ValueError(f"ROS_DOMAIN_ID must be in [0, 232], got {domain_id}")
        env["ROS_DOMAIN_ID"] = str(domain_id)
    env.setdefault("ROS_DOMAIN_ID", str(DEFAULT_DOMAIN_ID))
    # SUBNET is rmw_fastrtps's "use the XML profile as it is". LOCALHOST would make the rmw
    # add a transport of its own, which binds a socket on the host's external address
    # (seen on these machines): the loopback restriction is the profile's job.
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    env.pop("ROS_LOCALHOST_ONLY", None)
    if multi_host:
        env.pop("FASTRTPS_DEFAULT_PROFILES_FILE", None)
        env.pop("FASTDDS_DEFAULT_PROFILES_FILE", None)
    else:
        profile = str(loopback_profile_path())
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = profile
        env["FASTDDS_DEFAULT_PROFILES_FILE"] = profile
    return env


def apply_ros_environment(domain_id: int | None = None, multi_host: bool = False) -> None:
    """Set this process's environment (call before ``rclpy.init``)."""
    os.environ.update(ros_environment(domain_id=domain_id, multi_host=multi_host))


def uses_loopback_profile(env: Mapping[str, str] | None = None) -> bool:
    """True when ``env`` (default: this process) selects the shipped loopback profile."""
    env = os.environ if env is None else env
    profile = env.get("FASTRTPS_DEFAULT_PROFILES_FILE", "")
    return bool(profile) and Path(profile).resolve() == loopback_profile_path().resolve()
