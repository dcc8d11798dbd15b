"""The transport floor carries the lockstep graph's traffic: same subscriptions, same chain."""

from __future__ import annotations

import os

import pytest
import rclpy

from splitter_bringup.run.inprocess import start_graph
from splitter_bringup.scenario.definition import load_scenario
from splitter_msgs_py import names
from splitter_tools.transport_floor import (
    RECORDED_TOPICS,
    STATE_TOPICS,
    SUBSCRIPTIONS,
    TICK_ANSWERS,
    graph_subscriptions,
    measure_transport_floor,
)

TEST_DOMAIN_ID = int(os.environ["ROS_DOMAIN_ID"])  # set by the root conftest.py
# Subscriptions every node has whatever it does.
HOUSEKEEPING = {names.CLOCK, "/parameter_events"}


def subscribers(topic: str) -> int:
    """How many of the floor's subscriptions take a message of ``topic``."""
    return sum(topic in topics for topics in SUBSCRIPTIONS.values()) + (topic in RECORDED_TOPICS)


def test_every_step_and_tick_goes_through_the_chain() -> None:
    floor = measure_transport_floor(0.1, domain_id=TEST_DOMAIN_ID)
    steps, ticks = 20, 11  # t = 0 .. 0.1 s: 21 states published, a tick every 2nd
    assert floor.steps == steps
    assert floor.simulated_s == 0.1
    assert floor.published == (steps + 1) * len(STATE_TOPICS) + ticks * len(TICK_ANSWERS)
    answers = [topic for topic, _ in TICK_ANSWERS.values()]
    assert floor.delivered == (steps + 1) * sum(subscribers(t) for t in STATE_TOPICS) + ticks * sum(
        subscribers(t) for t in answers
    )
    assert floor.wall_s > 0.0 and floor.real_time_factor == 0.1 / floor.wall_s


def test_the_duration_must_be_whole_control_periods() -> None:
    with pytest.raises(ValueError, match="duration_s"):
        measure_transport_floor(0.105)


@pytest.mark.parametrize("scenario_name", ["lunar_jumping", "orientation_tracking"])
def test_the_floor_subscribes_as_the_graph_does(scenario_name: str) -> None:
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=TEST_DOMAIN_ID)
    try:
        scenario = load_scenario(scenario_name)
        graph = start_graph(scenario, context)
        takes_inertia = scenario.controller.attitude_reference == "momentum_aligned"
        try:
            for name, topics in graph_subscriptions(takes_inertia).items():
                node = graph.nodes[name]
                subscribed = {s.topic_name for s in node.subscriptions} - HOUSEKEEPING
                assert subscribed == set(topics), name
        finally:
            graph.shutdown()
    finally:
        context.try_shutdown()
