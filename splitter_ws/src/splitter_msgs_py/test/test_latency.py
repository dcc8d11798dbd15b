"""InputLatency: per-input latency statistics for /diagnostics."""

from __future__ import annotations

import pytest

from splitter_msgs_py.core.latency import InputLatency

MS = 1_000_000  # [ns]


def test_latency_statistics_per_input() -> None:
    latency = InputLatency()
    assert latency.values() == {}
    assert latency.record("joint_commands", 100 * MS, None) is None  # no clock: nothing
    assert latency.record("joint_commands", 100 * MS, 100 * MS) == 0
    assert latency.record("joint_commands", 110 * MS, 140 * MS) == 30 * MS
    assert latency.record("joint_commands", 120 * MS, 110 * MS) == 0  # early: clamped
    assert latency.record("imu", 0, 5 * MS) == 5 * MS
    values = latency.values()
    assert values["latency_joint_commands_count"] == 3
    assert values["latency_joint_commands_mean_ms"] == pytest.approx(10.0)
    assert values["latency_joint_commands_max_ms"] == pytest.approx(30.0)
    assert values["latency_joint_commands_last_ms"] == 0.0
    assert values["latency_imu_max_ms"] == pytest.approx(5.0)
    assert latency.max_ns("joint_commands") == 30 * MS
    assert latency.max_ns("unknown") == 0
