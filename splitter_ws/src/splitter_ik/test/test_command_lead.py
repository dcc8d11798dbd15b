"""CommandLead: commands stamped ahead of their inputs by the latency measured."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_ik.core.command_lead import CommandLead
from splitter_model.model import angular_velocity_after_morphing

MS = 1_000_000  # [ns]
PERIOD = 10 * MS


def test_no_latency_no_lead_every_input_answered_with_its_own_stamp() -> None:
    lead = CommandLead(PERIOD)
    last = None
    for k in range(50):
        t = k * PERIOD
        assert lead.record(t, t) == 0
        assert lead.output_stamps(t, last) == [t]
        last = t
    assert lead.lead_ns == 0
    # a repeated tick is answered again, as in lockstep
    assert lead.output_stamps(last, last) == [last]


def test_a_clock_behind_the_stamp_counts_as_no_latency() -> None:
    lead = CommandLead(PERIOD)
    assert lead.record(100 * MS, 95 * MS) == 0
    assert lead.record(100 * MS, None) == 0
    assert lead.lead_ns == 0


def test_lead_covers_the_largest_latency_with_factor_and_margin_in_whole_periods() -> None:
    lead = CommandLead(PERIOD, margin_ns=2 * MS, factor=1.5)
    lead.record(0, 0)
    lead.record(10 * MS, 10 * MS + 12 * MS)  # 12 ms late: 1.5 * 12 + 2 = 20 ms
    assert lead.lead_ns == 20 * MS
    lead.record(20 * MS, 20 * MS + 13 * MS)  # 21.5 ms -> 30 ms
    assert lead.lead_ns == 30 * MS


def test_lead_is_capped() -> None:
    lead = CommandLead(PERIOD, max_lead_ns=45 * MS)
    lead.record(0, 400 * MS)
    assert lead.lead_ns == 40 * MS  # whole periods under the cap


def test_a_growing_lead_fills_every_period_and_a_shrinking_one_pauses() -> None:
    lead = CommandLead(PERIOD, margin_ns=0, factor=1.0, window_ns=50 * MS)
    lead.record(0, 0)
    assert lead.output_stamps(0, None) == [0]
    lead.record(10 * MS, 40 * MS)  # 30 ms late: lead 30 ms
    stamps = lead.output_stamps(10 * MS, 0)
    assert stamps == [10 * MS, 20 * MS, 30 * MS, 40 * MS]  # no period skipped
    assert np.all(np.diff(stamps) == PERIOD)
    # the late sample leaves the window: lead back to 0, answers pause until the input
    # catches up with the last stamp sent, which never goes back
    last = stamps[-1]
    for t in range(20 * MS, 100 * MS, PERIOD):
        lead.record(t, t)
        out = lead.output_stamps(t, last)
        assert all(s > last or (s == last == t) for s in out)
        if out:
            last = out[-1]
    assert lead.lead_ns == 0
    assert last == 90 * MS


def test_invalid_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="period_ns"):
        CommandLead(0)
    with pytest.raises(ValueError, match="margin_ns"):
        CommandLead(PERIOD, margin_ns=-1)


def test_predicted_rate_follows_the_planned_inertia() -> None:
    w = np.array([0.1, 1.2, -0.3])
    then = np.array([50.0, 150.0, 160.0])
    later = np.array([50.0, 165.0, 176.0])  # paying out: Iyy, Izz grow
    predicted = angular_velocity_after_morphing(w, then, later)
    np.testing.assert_allclose(predicted * later, w * then)  # each w_i I_i kept
    assert abs(predicted[1]) < abs(w[1])
