"""A recorded bag read back into a :class:`RunSeries` (the same container the library loop fills).

Alignment is pure numpy (:func:`common_stamps`, :func:`values_at`,
:func:`forward_fill`) and :func:`series_from_samples`; ROS-free. Decoding a
bag into samples needs rclpy: :mod:`splitter_bringup.run.run_bag`
(``read_run_series``).

* State topics (IMU, odometry, inertia, joint states; 200 Hz) are aligned on
  their ``header.stamp``: a sample exists at every stamp all four carry. The body
  rate and the inertia are the ground truth (``/splitter/truth/imu``,
  ``/splitter/truth/inertia``; :func:`truth_topic`), so a noisy, biased gyro or an
  estimated inertia never enters the metrics; bags recorded before the truth
  topics existed fall back to ``/splitter/imu`` and ``/splitter/inertia``, which
  were the truth then.
* Inertia setpoints (100 Hz) and the jump command are forward-filled onto those
  stamps (the latest one stamped at or before; the first back-fills the start;
  without any setpoint the measured inertia stands in, as in the library loop's
  open-loop runs); the gait phase (latched, unstamped) by log time.
* The MPC node's counters on ``/diagnostics`` (solves not executed, deadlines
  missed) are forward-filled into ``extras["mpc_failures"]`` and
  ``extras["mpc_deadline_misses"]``, as the library loop records them.
* Radii come from the measured joint positions
  (:func:`splitter_model.kinematics.radii_from_joint_positions`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_bringup.analysis.series import RunSeries
from splitter_model.kinematics import radii_from_joint_positions
from splitter_model.model import RobotModel
from splitter_msgs_py import names

_log = logging.getLogger(__name__)
_NS_PER_S = 1_000_000_000
STATE_TOPICS = (names.IMU, names.ODOM, names.INERTIA, names.JOINT_STATES)
# the ground truth of a state topic, read instead of it when the bag has it
TRUTH_OF = {names.IMU: names.TRUTH_IMU, names.INERTIA: names.TRUTH_INERTIA}
GRAVITY_KEY = "gravity_m_s2"  # custom_data key a launcher may store in the bag
MPC_DIAGNOSTICS_PREFIX = "inertial_morphing_mpc"  # the MPC node's /diagnostics status name
# its cumulative counters, read into RunSeries.extras["mpc_<name>"] (the library loop's too)
MPC_COUNTS = ("failures", "deadline_misses")
SIM_DIAGNOSTICS_PREFIX = "simulator"  # the simulator node's /diagnostics status name
SIM_PEAK_G = "hemi_peak_acceleration_g"  # its running peak of the hemi specific force [G]
DIAGNOSTIC_KEYS = (*MPC_COUNTS, SIM_PEAK_G)


class BagSeriesError(ValueError):
    """A bag that cannot make a run series (missing topics, no common stamps, bad messages)."""


# --- pure alignment ---------------------------------------------------------------------
def common_stamps(*stamps_ns: ArrayLike) -> NDArray[np.int64]:
    """Sorted stamps present in every array."""
    if not stamps_ns:
        return np.zeros(0, dtype=np.int64)
    common = np.unique(np.asarray(stamps_ns[0], dtype=np.int64))
    for s in stamps_ns[1:]:
        common = np.intersect1d(common, np.asarray(s, dtype=np.int64), assume_unique=False)
    return common


def values_at(stamps_ns: ArrayLike, values: ArrayLike, grid_ns: ArrayLike) -> NDArray[Any]:
    """``values`` at exactly the ``grid_ns`` stamps (each must be present; last duplicate wins)."""
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    vals = np.asarray(values)
    grid = np.asarray(grid_ns, dtype=np.int64)
    # Last occurrence of each stamp: search in the reversed, stably sorted order.
    order = np.argsort(stamps, kind="stable")
    s_sorted = stamps[order]
    idx = np.searchsorted(s_sorted, grid, side="right") - 1
    if len(grid) and (np.any(idx < 0) or np.any(s_sorted[np.clip(idx, 0, None)] != grid)):
        raise BagSeriesError("values_at: a grid stamp has no sample")
    return vals[order[idx]]


def forward_fill(
    stamps_ns: ArrayLike, values: ArrayLike, grid_ns: ArrayLike, backfill: bool = True
) -> NDArray[Any]:
    """For each grid stamp, the latest value stamped at or before it.

    Before the first stamp the first value is used when ``backfill``; otherwise
    those rows are NaN (float values only).
    """
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    vals = np.asarray(values)
    grid = np.asarray(grid_ns, dtype=np.int64)
    if len(stamps) == 0:
        raise BagSeriesError("forward_fill: no samples")
    order = np.argsort(stamps, kind="stable")
    idx = np.searchsorted(stamps[order], grid, side="right") - 1
    before = idx < 0
    out = vals[order[np.clip(idx, 0, None)]]
    if np.any(before) and not backfill:
        out = out.astype(float)
        out[before] = np.nan
    return out


def forward_fill_labels(
    stamps_ns: Sequence[int], labels: Sequence[str], grid_ns: ArrayLike, before: str = ""
) -> list[str]:
    """Forward-filled strings; ``before`` ahead of the first label."""
    if not labels:
        return [before] * len(np.asarray(grid_ns))
    idx = np.searchsorted(np.asarray(stamps_ns, dtype=np.int64), grid_ns, side="right") - 1
    return [labels[i] if i >= 0 else before for i in idx]


def radii_series(model: RobotModel, joint_positions: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, 3) effective radii [m] from (n, 25) joint positions."""
    return np.array([radii_from_joint_positions(model, q) for q in joint_positions]).reshape(-1, 3)


def truth_topic(topic: str, available: Sequence[str] | set[str]) -> str:
    """The ground-truth topic of ``topic`` if ``available`` has it, else ``topic`` itself."""
    truth = TRUTH_OF.get(topic)
    return truth if truth is not None and truth in available else topic


# --- decoding -----------------------------------------------------------------------------
@dataclass
class TopicSamples:
    """Decoded samples of one topic: stamp [ns] (header, else log time) and fields."""

    stamps_ns: list[int] = field(default_factory=list)
    fields: dict[str, list[Any]] = field(default_factory=dict)

    def add(self, t_ns: int, **values: Any) -> None:
        self.stamps_ns.append(int(t_ns))
        for key, value in values.items():
            self.fields.setdefault(key, []).append(value)

    def array(self, key: str) -> NDArray[np.float64]:
        return np.asarray(self.fields[key], dtype=float)


def _latest_report(samples: TopicSamples, key: str, grid: NDArray[np.int64]) -> NDArray:
    """The latest finite report of ``key`` at or before each grid stamp (0 before the first)."""
    values = samples.array(key)
    keep = np.isfinite(values)
    stamps = np.asarray(samples.stamps_ns)[keep]
    if not keep.any():
        return np.zeros(len(grid))
    filled = forward_fill(stamps, values[keep], grid, backfill=False)
    return np.nan_to_num(filled.astype(float), nan=0.0)


def estimate_extras(samples: dict[str, TopicSamples]) -> dict[str, NDArray[np.float64]]:
    """The flight estimator's answers (``/splitter/estimate/*``) as the library loop
    records them: one row per control tick it answered (none without an estimator)."""
    topics = (names.ESTIMATE_IMU, names.ESTIMATE_INERTIA, names.ESTIMATE_MASSES)
    topics += (names.ESTIMATE_GYRO_BIAS, names.ESTIMATE_HEMI_INERTIA)
    if not all(t in samples and samples[t].stamps_ns for t in topics):
        return {}
    grid = common_stamps(*(samples[t].stamps_ns for t in topics))

    def at(topic: str, key: str) -> NDArray[np.float64]:
        s = samples[topic]
        return values_at(s.stamps_ns, s.array(key), grid).astype(float)

    masses = at(names.ESTIMATE_MASSES, "v")
    return {
        "estimate_t_s": grid.astype(float) / _NS_PER_S,
        "estimate_rate_rad_s": at(names.ESTIMATE_IMU, "w"),
        "estimate_gyro_bias_rad_s": at(names.ESTIMATE_GYRO_BIAS, "v"),
        "estimate_mass_ratios": masses[:, 1:] / masses[:, :1],
        "estimate_masses_kg": masses,
        "estimate_inertia_kg_m2": at(names.ESTIMATE_INERTIA, "v"),
        "estimate_hemi_inertia_kg_m2": at(names.ESTIMATE_HEMI_INERTIA, "v"),
    }


def series_from_samples(
    samples: dict[str, TopicSamples],
    model: RobotModel | None = None,
    gravity_m_s2: float = 0.0,
) -> RunSeries:
    """Align decoded topics into a :class:`RunSeries` (see the module doc)."""
    model = model or RobotModel()
    present = {t for t, s in samples.items() if s.stamps_ns}
    rate_topic, inertia_topic = (truth_topic(t, present) for t in (names.IMU, names.INERTIA))
    state_topics = (rate_topic, names.ODOM, inertia_topic, names.JOINT_STATES)
    missing = [t for t in state_topics if t not in present]
    if missing:
        raise BagSeriesError(f"the bag has no messages on {', '.join(missing)}")
    grid = common_stamps(*(samples[t].stamps_ns for t in state_topics))
    if len(grid) == 0:
        raise BagSeriesError("the state topics share no header stamp")
    for t in state_topics:
        dropped = len(set(samples[t].stamps_ns)) - len(grid)
        if dropped:
            _log.warning("%s: %d stamps not on all state topics, left out", t, dropped)

    def at(topic: str, key: str) -> NDArray[np.float64]:
        s = samples[topic]
        return values_at(s.stamps_ns, s.array(key), grid).astype(float)

    inertia = at(inertia_topic, "v")
    setpoints = samples.get(names.INERTIA_SETPOINT)
    if setpoints is not None and setpoints.stamps_ns:
        setpoint = forward_fill(setpoints.stamps_ns, setpoints.array("v"), grid).astype(float)
    else:
        _log.info("no inertia setpoints in the bag: the measured inertia stands in")
        setpoint = inertia.copy()
    joints = at(names.JOINT_STATES, "q")
    phase = samples.get(names.GAIT_PHASE)
    phases = (
        forward_fill_labels(phase.stamps_ns, phase.fields.get("phase", []), grid)
        if phase is not None and phase.stamps_ns
        else []
    )
    jump = samples.get(names.JUMP_COMMAND)
    jump_force = None
    if jump is not None and jump.stamps_ns:
        jump_force = forward_fill(jump.stamps_ns, jump.array("f"), grid, backfill=False)
        jump_force = np.nan_to_num(jump_force.astype(float), nan=0.0)  # no thrust before
    extras = {}
    diagnostics = samples.get(names.DIAGNOSTICS)
    if diagnostics is not None and diagnostics.stamps_ns:
        for key, name in ((k, f"mpc_{k}") for k in MPC_COUNTS):
            extras[name] = _latest_report(diagnostics, key, grid)
        if np.isfinite(diagnostics.array(SIM_PEAK_G)).any():
            extras[SIM_PEAK_G] = _latest_report(diagnostics, SIM_PEAK_G, grid)
    wrenches = [samples.get(topic) for topic in names.CONTACT_WRENCHES]
    if all(w is not None and w.stamps_ns for w in wrenches):
        extras["contact_force_n"] = np.stack(
            [values_at(w.stamps_ns, w.array("f"), grid).astype(float) for w in wrenches], axis=1
        )
    extras.update(estimate_extras(samples))
    return RunSeries(
        t_s=grid.astype(float) / _NS_PER_S,
        angular_velocity_rad_s=at(rate_topic, "w"),
        orientation_wxyz=at(names.ODOM, "q"),
        principal_inertia_kg_m2=inertia,
        inertia_setpoint_kg_m2=setpoint,
        radii_m=radii_series(model, joints),
        position_m=at(names.ODOM, "p"),
        velocity_m_s=at(names.ODOM, "v"),
        joint_position=joints,
        gravity_m_s2=float(gravity_m_s2),
        gait_phase=phases,
        jump_force_n=jump_force,
        extras=extras,
    )
