"""Why a replayed setpoint differs from the recorded one: each differing tick classified.

ROS-free. ``splitter replay`` feeds a recorded run's inputs to a fresh MPC and
compares, tick by tick, the inertia setpoint it answers with the one in the bag.
Same code, parameters and inputs give the same setpoints, except where the
recorded run's solver met the wall clock (a real-time run): a solve that missed
its deadline, came back late or found its restarted worker not ready left the
recording executing its previous plan until the next usable solve, and every
solve after such a miss started from another warm start (the last usable
plan's), so it converged to a slightly different point. The replay itself gives
each solve a lockstep deadline, so it computes what the MPC answers with time.

:func:`account` compares the setpoints with a tolerance on the largest
component difference [kg m^2] and classifies each tick above it by the solves
that made the plans in force (the recorded ones are read from the MPC's
``/diagnostics``, published right after each re-planning tick; the replayed ones
from the replayed node):

* ``recorded_solve_timing``: the recorded solve at the tick's re-planning time
  failed for wall time (deadline missed, late, worker not ready) and the
  replayed one was usable: the recording executed an older plan. Explained.
* ``replayed_solve_timing``: the converse (the replaying machine was too slow).
  Explained.
* ``warm_start_after_miss``: both solves usable (or failed alike), after an
  earlier wall-time failure of either run: the solves started from different
  warm starts. Explained.
* ``parameters_changed_live``: the tick comes after the recorded MPC reported a
  live parameter change (``parameter_changes`` on its ``/diagnostics``); the bag
  carries its start-up parameters only. Explained.
* ``unexplained``: anything else (no wall-time failure before the tick, a solve
  outcome that differs for a reason other than time, or no recorded diagnostics
  for the solve).

Ticks the recorded MPC never answered (``skipped``: no setpoint in the bag) are
not fed to the replay either, so they are neither compared nor a cause.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from splitter_mpc.core.solver_worker import (
    STATUS_ABANDONED,
    STATUS_DEADLINE_MISSED,
    STATUS_WORKER_STARTING,
)

RECORDED_TIMING = "recorded_solve_timing"
REPLAYED_TIMING = "replayed_solve_timing"
WARM_START = "warm_start_after_miss"
LIVE_PARAMETERS = "parameters_changed_live"
UNEXPLAINED = "unexplained"
EXPLAINED_CAUSES = (RECORDED_TIMING, REPLAYED_TIMING, WARM_START, LIVE_PARAMETERS)
_TIMING_STATUSES = (STATUS_DEADLINE_MISSED, STATUS_WORKER_STARTING, STATUS_ABANDONED)


def is_timing_failure(status: str) -> bool:
    """True for a solve that failed because of the wall clock, not the problem."""
    return status in _TIMING_STATUSES or status.startswith("late")


@dataclass(frozen=True)
class Solve:
    """One MPC solve: usable or not, and its status text."""

    ok: bool
    status: str

    @property
    def timing_failure(self) -> bool:
        return not self.ok and is_timing_failure(self.status)


@dataclass(frozen=True)
class TickDifference:
    """A tick whose replayed setpoint differs from the recorded one beyond the tolerance."""

    t_ns: int
    diff_kg_m2: float  # largest component difference
    cause: str  # one of EXPLAINED_CAUSES or UNEXPLAINED
    detail: str

    @property
    def explained(self) -> bool:
        return self.cause in EXPLAINED_CAUSES


@dataclass(frozen=True)
class ReplayAccount:
    """The comparison of a replay: what matched, what differed and why."""

    ticks: int  # setpoints compared
    identical: int  # bit for bit
    within_tolerance: int  # |difference| <= tolerance (the identical ones included)
    tolerance_kg_m2: float
    max_abs_diff_kg_m2: float
    differences: tuple[TickDifference, ...]
    skipped_ticks: int  # control ticks the recorded MPC did not answer
    recorded_timing_failures: tuple[int, ...]  # [ns] recorded solves failed for wall time
    replayed_timing_failures: tuple[int, ...]

    @property
    def unexplained(self) -> tuple[TickDifference, ...]:
        return tuple(d for d in self.differences if not d.explained)

    @property
    def accounted_for(self) -> bool:
        """True when every tick beyond the tolerance has an explained cause."""
        return not self.unexplained

    def by_cause(self) -> dict[str, tuple[int, float]]:
        """cause -> (ticks, largest difference [kg m^2])."""
        counts = Counter(d.cause for d in self.differences)
        return {
            cause: (n, max(d.diff_kg_m2 for d in self.differences if d.cause == cause))
            for cause, n in sorted(counts.items())
        }


def count_skipped_ticks(stamps_ns: Sequence[int], control_period_ns: int) -> int:
    """Control ticks between the first and last answered one that have no answer."""
    if len(stamps_ns) < 2:
        return 0
    first, last = min(stamps_ns), max(stamps_ns)
    expected = (last - first) // control_period_ns + 1
    return int(expected - len(set(stamps_ns)))


def account(
    stamps_ns: ArrayLike,
    recorded_kg_m2: ArrayLike,
    replayed_kg_m2: ArrayLike,
    recorded_solves: Mapping[int, Solve],
    replayed_solves: Mapping[int, Solve],
    *,
    tolerance_kg_m2: float,
    control_period_ns: int,
    parameters_changed_ns: int | None = None,
) -> ReplayAccount:
    """Compare the setpoints tick by tick and classify every difference (module doc).

    ``recorded_solves`` / ``replayed_solves``: tick [ns] -> the solve made at that
    tick (the recorded ones as far as the bag's diagnostics tell).
    ``parameters_changed_ns``: when the recorded MPC first reported a live
    parameter change (None: never).
    """
    if not tolerance_kg_m2 >= 0.0:
        raise ValueError(f"tolerance must be >= 0, got {tolerance_kg_m2}")
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    recorded = np.asarray(recorded_kg_m2, dtype=float).reshape(len(stamps), 3)
    replayed = np.asarray(replayed_kg_m2, dtype=float).reshape(len(stamps), 3)
    diffs = np.max(np.abs(recorded - replayed), axis=1) if len(stamps) else np.zeros(0)
    solve_ticks = sorted(set(recorded_solves) | set(replayed_solves))
    rec_timing = tuple(t for t in sorted(recorded_solves) if recorded_solves[t].timing_failure)
    rep_timing = tuple(t for t in sorted(replayed_solves) if replayed_solves[t].timing_failure)
    differences = []
    for t, diff in zip(stamps.tolist(), diffs.tolist(), strict=True):
        if diff <= tolerance_kg_m2:
            continue
        if parameters_changed_ns is not None and t >= parameters_changed_ns:
            when = f"{parameters_changed_ns * 1e-9:.3f} s"
            detail = f"the recorded MPC's parameters were changed live by {when}"
            differences.append(TickDifference(t, diff, LIVE_PARAMETERS, detail))
            continue
        differences.append(
            _classify(
                t,
                diff,
                solve_ticks,
                (recorded_solves, replayed_solves),
                (rec_timing, rep_timing),
            )
        )
    return ReplayAccount(
        ticks=len(stamps),
        identical=int(np.sum(np.all(recorded == replayed, axis=1))),
        within_tolerance=int(np.sum(diffs <= tolerance_kg_m2)),
        tolerance_kg_m2=float(tolerance_kg_m2),
        max_abs_diff_kg_m2=float(diffs.max()) if len(diffs) else 0.0,
        differences=tuple(differences),
        skipped_ticks=count_skipped_ticks(stamps.tolist(), control_period_ns),
        recorded_timing_failures=rec_timing,
        replayed_timing_failures=rep_timing,
    )


def _classify(
    t_ns: int,
    diff: float,
    solve_ticks: list[int],
    solves: tuple[Mapping[int, Solve], Mapping[int, Solve]],
    timing_failures: tuple[tuple[int, ...], tuple[int, ...]],
) -> TickDifference:
    recorded_solves, replayed_solves = solves
    rec_timing, rep_timing = timing_failures
    at = [s for s in solve_ticks if s <= t_ns]
    if not at:
        return TickDifference(t_ns, diff, UNEXPLAINED, "no solve before this tick")
    r = at[-1]
    rec, rep = recorded_solves.get(r), replayed_solves.get(r)
    when = f"solve at {r * 1e-9:.3f} s"
    if rec is None or rep is None:
        side = "recorded" if rec is None else "replayed"
        return TickDifference(t_ns, diff, UNEXPLAINED, f"{when}: no {side} status")
    if rec.timing_failure and rep.ok:
        return TickDifference(
            t_ns, diff, RECORDED_TIMING, f"recorded {when}: {rec.status}; the previous plan ran"
        )
    if rep.timing_failure and rec.ok:
        return TickDifference(t_ns, diff, REPLAYED_TIMING, f"replayed {when}: {rep.status}")
    if rec.ok == rep.ok:
        earlier = [s for s in (*rec_timing, *rep_timing) if s < r]
        if earlier:
            first = min(earlier)
            return TickDifference(
                t_ns,
                diff,
                WARM_START,
                f"{when}: another warm start since the wall-time failure at {first * 1e-9:.3f} s",
            )
        return TickDifference(t_ns, diff, UNEXPLAINED, f"{when}: same outcome ({rec.status})")
    return TickDifference(
        t_ns, diff, UNEXPLAINED, f"{when}: recorded {rec.status!r}, replayed {rep.status!r}"
    )
