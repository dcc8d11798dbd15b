"""The executor every node of the project spins on.

rclpy's ``SingleThreadedExecutor`` rebuilds its wait set in Python on every wake-up
and hands each message to Python through several layers. rclpy 7.1 (Jazzy) also
ships ``rclpy.experimental.EventsExecutor``, written in C++: it takes a message,
converts it and calls the callback with little Python in between. The lockstep
graph moves about ten messages per simulator step, so this is where its time goes:
a publish and a delivery of an Odometry cost 184 us with the former and 66 us
with the latter on the 2-core machine (a ping through one in-process
publisher-subscriber pair; 123 us and 17 us raw).

``SPLITTER_EXECUTOR`` (environment) chooses it for every process the project
starts: ``events`` (default) or ``single_threaded`` (rclpy's classic, to compare
with or to fall back on).
"""

from __future__ import annotations

import os

from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor

EXECUTOR_ENV = "SPLITTER_EXECUTOR"
EXECUTOR_KINDS = ("events", "single_threaded")
DEFAULT_EXECUTOR = "events"


def executor_kind(kind: str | None = None) -> str:
    """``kind``, else ``SPLITTER_EXECUTOR``, else the default; ValueError names a bad one."""
    chosen = kind if kind is not None else os.environ.get(EXECUTOR_ENV, DEFAULT_EXECUTOR)
    chosen = chosen.strip().lower() or DEFAULT_EXECUTOR
    if chosen not in EXECUTOR_KINDS:
        raise ValueError(
            f"{EXECUTOR_ENV} must be one of {', '.join(EXECUTOR_KINDS)}, got {chosen!r}"
        )
    return chosen


def make_executor(context: Context, kind: str | None = None) -> Executor:
    """A new executor on ``context`` of the chosen kind (:func:`executor_kind`)."""
    if executor_kind(kind) == "events":
        from rclpy.experimental.events_executor import EventsExecutor

        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)
