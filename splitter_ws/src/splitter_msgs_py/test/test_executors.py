"""The project's executor choice: rclpy's EventsExecutor unless told otherwise."""

from __future__ import annotations

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

from splitter_msgs_py.executors import EXECUTOR_ENV, executor_kind, make_executor


def test_the_default_is_the_events_executor(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(EXECUTOR_ENV, raising=False)
    assert executor_kind() == "events"
    monkeypatch.setenv(EXECUTOR_ENV, " Single_Threaded ")
    assert executor_kind() == "single_threaded"
    assert executor_kind("events") == "events"  # an explicit kind wins over the environment


def test_a_bad_kind_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(EXECUTOR_ENV, "multi")
    with pytest.raises(ValueError, match=f"{EXECUTOR_ENV} must be one of .*'multi'"):
        executor_kind()


def test_make_executor_builds_the_kind_on_the_context() -> None:
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        events = make_executor(context, "events")
        assert not isinstance(events, SingleThreadedExecutor)
        assert type(events).__name__ == "EventsExecutor"
        assert isinstance(make_executor(context, "single_threaded"), SingleThreadedExecutor)
        events.shutdown()
    finally:
        context.try_shutdown()
