"""A tick's inputs gathered from several topics: complete, late, skipped, dropped, last good."""

from __future__ import annotations

import pytest

from splitter_mpc.core.tick_inputs import TickAssembler

MS = 1_000_000  # [ns]


def test_a_tick_completes_with_its_last_input_and_late_ones_are_ignored() -> None:
    ticks = TickAssembler(10 * MS, ("odom", "contact"))
    assert ticks.add("odom", 0, "o0").completed is None
    assert ticks.add("odom", 5 * MS, "between ticks").completed is None  # not a tick
    events = ticks.add("contact", 0, "c0")
    assert events.completed == (0, {"odom": "o0", "contact": "c0"})
    assert ticks.pending == {} and ticks.last_tick_ns == 0
    assert ticks.add("odom", 0, "repeat") == ticks.add("contact", 0, "late")  # both ignored
    assert ticks.pending == {}


def test_a_rejected_input_counts_and_takes_its_topics_last_good_message() -> None:
    ticks = TickAssembler(10 * MS, ("odom", "contact"))
    ticks.add("odom", 0, "o0")
    ticks.add("contact", 0, "c0")
    ticks.add("odom", 10 * MS, None)  # rejected
    t, inputs = ticks.add("contact", 10 * MS, "c1").completed
    assert t == 10 * MS and ticks.samples(inputs) == {"odom": "o0", "contact": "c1"}


def test_a_later_tick_completing_first_skips_the_older_ones_and_overflow_drops() -> None:
    ticks = TickAssembler(10 * MS, ("odom", "contact"), max_pending=2)
    ticks.add("odom", 0, "o0")
    ticks.add("odom", 10 * MS, "o1")
    events = ticks.add("odom", 20 * MS, "o2")  # three incomplete ticks: the oldest goes
    assert events.dropped == ((0, ("odom",)),) and sorted(ticks.pending) == [10 * MS, 20 * MS]
    events = ticks.add("contact", 20 * MS, "c2")
    assert events.completed[0] == 20 * MS and events.skipped == ((10 * MS, ("odom",)),)
    assert ticks.pending == {}


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="period_ns"):
        TickAssembler(0, ("odom",))
    with pytest.raises(ValueError, match="input"):
        TickAssembler(10 * MS, ())
