"""The watchdog's judgement: which node stalls a lockstep graph, which one lags in real time."""

from __future__ import annotations

import pytest

from splitter_bringup.analysis.watchdog import ALLOCATOR, GAIT, MPC, SIMULATOR, GraphWatchdog

NODES = (SIMULATOR, GAIT, MPC, ALLOCATOR)
MS = 1_000_000  # [ns]


def answered(dog: GraphWatchdog, t_ms: int, wall_s: float, *nodes: str) -> None:
    for node in nodes:
        dog.on_output(node, t_ms * MS, wall_s)


def test_lockstep_names_the_first_node_of_the_data_path_that_did_not_answer() -> None:
    dog = GraphWatchdog(NODES, stall_timeout_s=2.0)
    assert dog.check(100.0) == []  # nothing before the simulator's first state
    answered(dog, 0, 0.0, *NODES)
    answered(dog, 10, 0.1, SIMULATOR, GAIT)  # the MPC does not answer t = 10 ms
    assert dog.check(2.0) == []  # not yet stalled for 2 s
    (stall,) = dog.check(2.2)
    # the allocator has not answered either, but it waits for the MPC
    assert stall.node == MPC and stall.t_ns == 10 * MS and stall.waited_s == pytest.approx(2.1)
    answered(dog, 10, 2.3, MPC)
    assert dog.check(2.4)[0].node == ALLOCATOR  # now the allocator holds the tick
    answered(dog, 10, 2.5, ALLOCATOR)
    assert dog.check(2.6)[0].node == SIMULATOR  # every node answered: the simulator stalls
    answered(dog, 15, 2.7, SIMULATOR)  # between ticks the state counts as progress
    assert dog.check(4.0) == []
    answered(dog, 10**12, 4.1, SIMULATOR, MPC)  # a corrupt stamp far ahead is no progress
    assert dog.stamp_ns(SIMULATOR) == 15 * MS and dog.stamp_ns(MPC) == 10 * MS


def test_real_time_reports_each_silent_node_once_until_it_publishes_again() -> None:
    dog = GraphWatchdog(NODES, lockstep=False, stall_timeout_s=1.0)
    answered(dog, 0, 0.0, SIMULATOR, GAIT, ALLOCATOR)  # the MPC never published
    answered(dog, 500, 0.5, SIMULATOR, GAIT, ALLOCATOR)
    answered(dog, 1000, 1.1, SIMULATOR, GAIT, ALLOCATOR)
    assert [s.node for s in dog.check(1.2)] == [MPC]
    assert dog.check(1.3) == [] and dog.stalled == {MPC}  # reported once
    answered(dog, 1300, 1.4, MPC)
    answered(dog, 1300, 1.4, SIMULATOR, GAIT, ALLOCATOR)
    assert dog.check(1.5) == [] and dog.stalled == set()
    assert [s.node for s in dog.check(2.6)] == [SIMULATOR, GAIT, MPC, ALLOCATOR]


def test_a_watchdog_needs_the_simulator_and_known_nodes() -> None:
    with pytest.raises(ValueError, match="simulator"):
        GraphWatchdog((MPC,))
    with pytest.raises(ValueError, match="no progress topic"):
        GraphWatchdog((SIMULATOR, "recorder"))
    with pytest.raises(ValueError, match="stall_timeout_s"):
        GraphWatchdog(NODES, stall_timeout_s=0.0)
