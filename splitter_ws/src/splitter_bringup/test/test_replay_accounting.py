"""Why a replayed setpoint differs: the accounting of ``splitter replay`` on synthetic series."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_bringup.analysis.replay_accounting import (
    LIVE_PARAMETERS,
    RECORDED_TIMING,
    REPLAYED_TIMING,
    UNEXPLAINED,
    WARM_START,
    Solve,
    account,
    count_skipped_ticks,
    is_timing_failure,
)

MS = 1_000_000  # [ns]
CONTROL_NS = 10 * MS
REPLAN_NS = 100 * MS


def series(n_ticks: int, skipped: tuple[int, ...] = ()):
    """Ticks every 10 ms (some skipped), identical recorded and replayed setpoints, solves."""
    stamps = [k * CONTROL_NS for k in range(n_ticks) if k not in skipped]
    rng = np.random.default_rng(3)
    recorded = rng.uniform(0.5, 3.0, size=(len(stamps), 3))
    solves = {t: Solve(True, "converged") for t in stamps if t % REPLAN_NS == 0}
    return stamps, recorded, recorded.copy(), solves, dict(solves)


def run(stamps, recorded, replayed, rec, rep, *, tolerance=1e-9, changed=None):
    return account(
        stamps,
        recorded,
        replayed,
        rec,
        rep,
        tolerance_kg_m2=tolerance,
        control_period_ns=CONTROL_NS,
        parameters_changed_ns=changed,
    )


def test_identical_series_is_accounted_for_with_nothing_to_explain() -> None:
    stamps, recorded, replayed, rec, rep = series(50, skipped=(7, 8, 23))
    acc = run(stamps, recorded, replayed, rec, rep)
    assert acc.ticks == 47 and acc.identical == 47 and acc.within_tolerance == 47
    assert acc.skipped_ticks == 3
    assert acc.differences == () and acc.accounted_for
    assert acc.max_abs_diff_kg_m2 == 0.0


def test_a_recorded_deadline_miss_explains_its_plan_period_and_the_warm_start_after() -> None:
    stamps, recorded, replayed, rec, rep = series(50)
    miss = 2 * REPLAN_NS
    rec[miss] = Solve(False, "deadline_missed")
    index = {t: i for i, t in enumerate(stamps)}
    # the recording ran its previous plan from 200 to 290 ms; after it, other warm starts
    for t in range(miss, miss + REPLAN_NS, CONTROL_NS):
        replayed[index[t]] += 0.3
    for t in range(miss + REPLAN_NS, stamps[-1] + 1, CONTROL_NS):
        replayed[index[t]] += 2e-7
    acc = run(stamps, recorded, replayed, rec, rep)
    causes = acc.by_cause()
    assert causes[RECORDED_TIMING][0] == 10
    assert causes[RECORDED_TIMING][1] == pytest.approx(0.3)
    assert causes[WARM_START][0] == len(stamps) - index[miss + REPLAN_NS]
    assert acc.recorded_timing_failures == (miss,)
    assert acc.accounted_for and acc.unexplained == ()
    assert acc.identical == index[miss]
    first = acc.differences[0]
    assert first.t_ns == miss and "deadline_missed" in first.detail


def test_a_late_solve_and_a_replay_side_miss_are_timing_causes() -> None:
    assert is_timing_failure("late (95 ms > 80)")
    assert is_timing_failure("worker_starting")
    assert not is_timing_failure("Maximum_Iterations_Exceeded")
    stamps, recorded, replayed, rec, rep = series(30)
    rep[REPLAN_NS] = Solve(False, "deadline_missed")
    replayed[10:20] += 0.1
    acc = run(stamps, recorded, replayed, rec, rep)
    assert {d.cause for d in acc.differences} == {REPLAYED_TIMING}
    assert acc.replayed_timing_failures == (REPLAN_NS,) and acc.accounted_for


def test_a_difference_without_a_wall_time_cause_is_unexplained() -> None:
    stamps, recorded, replayed, rec, rep = series(30)
    replayed[15] += 1e-3  # same solves, no miss anywhere: a real regression
    acc = run(stamps, recorded, replayed, rec, rep)
    assert len(acc.unexplained) == 1 and acc.unexplained[0].cause == UNEXPLAINED
    assert acc.unexplained[0].t_ns == stamps[15]
    assert not acc.accounted_for
    # a solver outcome that differs for a reason other than time is no excuse either
    rec[REPLAN_NS] = Solve(False, "Maximum_Iterations_Exceeded")
    acc = run(stamps, recorded, replayed, rec, rep)
    assert not acc.accounted_for and "Maximum_Iterations_Exceeded" in acc.unexplained[0].detail


def test_the_tolerance_compares_the_largest_setpoint_component() -> None:
    stamps, recorded, replayed, rec, rep = series(20)
    replayed[4, 2] += 5e-7
    assert run(stamps, recorded, replayed, rec, rep, tolerance=1e-6).accounted_for
    acc = run(stamps, recorded, replayed, rec, rep, tolerance=1e-7)
    assert not acc.accounted_for
    assert acc.identical == 19 and acc.within_tolerance == 19
    assert acc.max_abs_diff_kg_m2 == pytest.approx(5e-7)
    with pytest.raises(ValueError):
        run(stamps, recorded, replayed, rec, rep, tolerance=float("nan"))


def test_skipped_ticks_are_counted_on_the_control_grid() -> None:
    assert count_skipped_ticks([0, 10 * MS, 40 * MS, 50 * MS], CONTROL_NS) == 2
    assert count_skipped_ticks([30 * MS], CONTROL_NS) == 0


def test_ticks_after_a_live_parameter_change_are_put_down_to_it() -> None:
    stamps, recorded, replayed, rec, rep = series(30)
    replayed[12] += 1e-3
    replayed[25:] += 0.2
    acc = run(stamps, recorded, replayed, rec, rep, changed=stamps[20])
    assert [d.cause for d in acc.differences] == [UNEXPLAINED] + [LIVE_PARAMETERS] * 5
    assert not acc.accounted_for  # the tick before the change is still unexplained
