"""Test-suite wide set-up: every test process runs with the loopback-only DDS profile.

The environment is fixed here, before any test imports rclpy, so that no test
depends on the caller having exported it (the Makefile does too). Each test run
picks its own ROS_DOMAIN_ID so that parallel runs on one machine never talk.
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from splitter_msgs_py.environment import apply_ros_environment

TEST_DOMAIN_ID = 100 + os.getpid() % 100
apply_ros_environment(domain_id=TEST_DOMAIN_ID)
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
