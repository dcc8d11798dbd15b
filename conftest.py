"""Test-suite wide set-up: every test process runs with the loopback-only DDS profile.

The environment is fixed here, before any test imports rclpy, so that no test
depends on the caller having exported it (the Makefile does too). Each test run
picks its own ROS_DOMAIN_ID so that parallel runs on one machine never talk.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest
from hypothesis import settings

from splitter_msgs_py.domains import hold_domains
from splitter_msgs_py.environment import apply_ros_environment

# Property tests draw the same examples on every run (the suite is deterministic, as the
# project's runs are): a failure reproduces, and CI never fails on a lucky draw.
settings.register_profile("deterministic", derandomize=True, database=None)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))

# Domains 0-101 are the ones ROS 2 documents as safe on Linux (higher ones reach the
# ephemeral port range, and above 232 Fast DDS calls exit(1): "port number is too
# high"). Tests that need a second domain add at most MAX_DOMAIN_OFFSET to this one.
MAX_DOMAIN_OFFSET = 20
# SPLITTER_TEST_DOMAIN_ID pins it (in [1, 81]) for suites that run side by side on one machine.
TEST_DOMAIN_ID = int(
    os.environ.get("SPLITTER_TEST_DOMAIN_ID", 1 + os.getpid() % (101 - MAX_DOMAIN_OFFSET))
)
if not 1 <= TEST_DOMAIN_ID <= 101 - MAX_DOMAIN_OFFSET:
    raise ValueError(f"SPLITTER_TEST_DOMAIN_ID must be in [1, 81], got {TEST_DOMAIN_ID}")
apply_ros_environment(domain_id=TEST_DOMAIN_ID)
# Mark the run's domains used (shared locks, held while pytest runs): a graph that
# chooses its own domain (`splitter run` with no domain named) never lands on them.
_HELD_DOMAINS = hold_domains(range(TEST_DOMAIN_ID, TEST_DOMAIN_ID + MAX_DOMAIN_OFFSET + 2))
os.environ.setdefault("MPLBACKEND", "Agg")


@pytest.fixture
def ros_context() -> Iterator[object]:
    """A fresh rclpy context on the test domain, shut down after the test."""
    import rclpy

    context = rclpy.Context()
    rclpy.init(context=context, domain_id=TEST_DOMAIN_ID)
    try:
        yield context
    finally:
        context.try_shutdown()
