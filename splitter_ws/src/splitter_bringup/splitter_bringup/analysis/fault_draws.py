"""Faults in campaigns: the random fault of a draw, and what its flight shows of detection.

``splitter campaign SCENARIO --fault RANDOM``: every draw has one fault
(:class:`~splitter_model.faults.JointFault`), from three numbers ``u`` uniform in
[0, 1) that every draw draws last (so the rest of a draw is the same with or
without faults):

* the kind, one of :data:`FAULT_ROWS` with equal chances (``u0``): a limb joint
  locked, a limb joint limp, or the tether reel locked (the reel would be one
  joint in 25 if joints were drawn alike; the rows are kept the same size);
* for a limb joint, which of the 24 (``u1``);
* when: ``u2`` times the latest fault time (2 s by default), simulated.

Detection (from the flight's series, ``joint_detected`` and ``joint_command``):
the first time the faulty joint was found, its latency from the first commanded
motion of that joint after the fault, and the joints found faulty that were not
(false detections). The first commanded motion: the start of the first stretch of
the detector's ``stuck_window_s`` (60 ms) over which the joint's command stays farther
than its "stuck" threshold from where the joint is (or, for a limp joint, the joint
has moved by as much by itself: its error to its command changed by as much; a limp
joint that happens to move with its command shows nothing). A joint locked while held
still shows nothing until then; a command that only grazes the threshold (a reel
locked at its end, held there within a millimetre) does not ask it to move.

ROS-free.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from splitter_ik.core.joint_health import JointHealthConfig
from splitter_model.faults import LIMP, LOCKED, JointFault
from splitter_model.joints import JOINT_NAMES, TETHER_INDEX, TETHER_JOINT

FAULT_TIME_MAX_S = 2.0  # [s] default latest fault time of --fault RANDOM
LIMB_LOCKED, LIMB_LIMP, REEL_LOCKED = "limb_locked", "limb_limp", "reel_locked"
FAULT_ROWS = (LIMB_LOCKED, LIMB_LIMP, REEL_LOCKED)


def fault_row(fault: JointFault | None) -> str:
    """The row of a campaign's table a fault belongs to ("" for none)."""
    if fault is None:
        return ""
    if fault.is_reel:
        return REEL_LOCKED
    return LIMB_LOCKED if fault.kind == LOCKED else LIMB_LIMP


def draw_fault(u: ArrayLike, time_max_s: float = FAULT_TIME_MAX_S) -> JointFault:
    """The fault of three uniform numbers in [0, 1) (module docstring)."""
    u0, u1, u2 = (float(v) for v in np.asarray(u, dtype=float).reshape(3))
    row = FAULT_ROWS[min(int(u0 * len(FAULT_ROWS)), len(FAULT_ROWS) - 1)]
    time_s = u2 * float(time_max_s)
    if row == REEL_LOCKED:
        return JointFault(TETHER_JOINT, LOCKED, time_s)
    joint = JOINT_NAMES[min(int(u1 * TETHER_INDEX), TETHER_INDEX - 1)]
    return JointFault(joint, LOCKED if row == LIMB_LOCKED else LIMP, time_s)


@dataclass(frozen=True)
class FaultDetection:
    """What a flight shows of a fault's detection (times [s], NaN: did not happen)."""

    detected_s: float  # first time the faulty joint was found
    first_motion_s: float  # first commanded (or own) motion of the joint after the fault
    false_detections: int  # joints found faulty that were not

    @property
    def latency_s(self) -> float:
        """From the first motion to the detection [s]."""
        return self.detected_s - self.first_motion_s


NO_DETECTION = FaultDetection(math.nan, math.nan, 0)  # nothing to detect, nothing found


def fault_detection(
    t_s: ArrayLike,
    joint_position: ArrayLike,
    joint_command: ArrayLike,
    joint_detected: ArrayLike,
    fault: JointFault | None,
) -> FaultDetection:
    """The detection figures of a flight (arrays (n,) and (n, 25) of its series)."""
    t = np.asarray(t_s, dtype=float)
    detected = np.asarray(joint_detected, dtype=float)
    found = np.flatnonzero(detected[-1] > 0.0) if len(t) else np.array([], dtype=int)
    faulty = None if fault is None else fault.joint_index
    false = int(sum(1 for j in found.tolist() if j != faulty))
    if fault is None:
        return FaultDetection(math.nan, math.nan, false)
    j = faulty
    rows = np.flatnonzero(detected[:, j] > 0.0)
    detected_s = float(t[rows[0]]) if rows.size else math.nan
    q = np.asarray(joint_position, dtype=float)[:, j]
    command = np.asarray(joint_command, dtype=float)[:, j]
    config = JointHealthConfig()
    threshold = config.stuck_error_m if j == TETHER_INDEX else config.stuck_error_rad
    after = np.flatnonzero(t >= fault.time_s)
    first_motion = math.nan
    if after.size:
        k0 = after[0]
        asked = np.abs(command[k0:] - q[k0:]) > threshold
        if fault.kind == LIMP:  # moved by itself: its error changed without its command
            error = command[k0:] - q[k0:]
            asked |= np.abs(error - error[0]) > threshold
        span = max(1, int(np.sum(t[k0:] <= t[k0] + config.stuck_window_s)))  # samples
        sustained = np.convolve(asked.astype(int), np.ones(span, dtype=int), "valid") == span
        moving = np.flatnonzero(sustained)
        if moving.size:
            first_motion = float(t[k0 + moving[0]])
    return FaultDetection(detected_s, first_motion, false)


def detection_table(
    rows: Sequence[str], successes: Sequence[bool], detections: Sequence[FaultDetection]
) -> dict[str, dict[str, float | int | None]]:
    """Per fault row: draws, successes, rate, detections missed, latency p95 and max [s]."""
    table: dict[str, dict[str, float | int | None]] = {}
    for row in (*FAULT_ROWS, ""):
        chosen = [i for i, r in enumerate(rows) if r == row]
        if not chosen:
            continue
        latencies = [detections[i].latency_s for i in chosen]
        measured = [v for v in latencies if math.isfinite(v)]
        missed = sum(
            1
            for i in chosen
            if math.isfinite(detections[i].first_motion_s)
            and not math.isfinite(detections[i].detected_s)
        )
        k = sum(1 for i in chosen if successes[i])
        table[row or "no_fault"] = {
            "draws": len(chosen),
            "successes": k,
            "success_rate": k / len(chosen),
            "detections_missed": missed,
            "detection_latency_p95_s": float(np.percentile(measured, 95)) if measured else None,
            "detection_latency_max_s": max(measured) if measured else None,
            "false_detections": sum(detections[i].false_detections for i in chosen),
        }
    return table
