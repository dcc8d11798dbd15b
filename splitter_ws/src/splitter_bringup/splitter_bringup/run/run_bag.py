"""A recorded bag read back into a :class:`RunSeries`: the ROS side of :mod:`.core.bag_series`.

Messages are decoded with ``rclpy.serialization`` and validated by
:mod:`splitter_msgs_py.conversions`; the alignment is the ROS-free
:func:`splitter_bringup.analysis.bag_series.series_from_samples`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rclpy.serialization import deserialize_message

from splitter_bag.core.metadata import read_metadata
from splitter_bag.core.reader import read_messages
from splitter_bringup.analysis.bag_series import (
    DIAGNOSTIC_KEYS,
    GRAVITY_KEY,
    MPC_DIAGNOSTICS_PREFIX,
    SIM_DIAGNOSTICS_PREFIX,
    BagSeriesError,
    TopicSamples,
    series_from_samples,
    truth_topic,
)
from splitter_bringup.analysis.series import RunSeries
from splitter_model.model import RobotModel
from splitter_msgs_py import conversions as cv
from splitter_msgs_py import names
from splitter_msgs_py.conversions import TOPIC_MESSAGE_CLASSES

_log = logging.getLogger(__name__)
NS_PER_S = 1_000_000_000  # [ns/s]


def _decoders() -> dict[str, Callable[[Any, int, TopicSamples], None]]:
    def imu(msg: Any, _: int, out: TopicSamples) -> None:
        s = cv.imu_from_msg(msg)
        out.add(s.t_ns, w=s.angular_velocity_rad_s, q=s.orientation_wxyz)

    def odom(msg: Any, _: int, out: TopicSamples) -> None:
        s = cv.odom_from_msg(msg)
        out.add(s.t_ns, p=s.position_m, q=s.orientation_wxyz, v=s.velocity_world_m_s)

    def vector(msg: Any, _: int, out: TopicSamples) -> None:
        s = cv.vector3_from_msg(msg)
        out.add(s.t_ns, v=s.vector)

    def joints(msg: Any, _: int, out: TopicSamples) -> None:
        s = cv.joint_state_from_msg(msg)
        out.add(s.t_ns, q=s.position)

    def phase(msg: Any, log_ns: int, out: TopicSamples) -> None:
        out.add(log_ns, phase=str(msg.data))

    def jump(msg: Any, _: int, out: TopicSamples) -> None:
        s = cv.wrench_from_msg(msg)
        out.add(s.t_ns, f=s.force_n)

    def diagnostics(msg: Any, _: int, out: TopicSamples) -> None:
        t_ns = cv.stamp_from_msg(msg.header.stamp)
        for status in cv.diagnostics_from_msg(msg):
            if status.name.startswith((MPC_DIAGNOSTICS_PREFIX, SIM_DIAGNOSTICS_PREFIX)):
                # every key on every row (NaN where this node does not report it)
                out.add(t_ns, **{k: float(status.values.get(k, np.nan)) for k in DIAGNOSTIC_KEYS})

    return {
        names.IMU: imu,
        names.TRUTH_IMU: imu,
        names.ODOM: odom,
        names.INERTIA: vector,
        names.TRUTH_INERTIA: vector,
        names.JOINT_STATES: joints,
        names.INERTIA_SETPOINT: vector,
        names.GAIT_PHASE: phase,
        names.JUMP_COMMAND: jump,
        names.DIAGNOSTICS: diagnostics,
        names.CONTACT_WRENCH_A: jump,  # the same decoding: force [N], world
        names.CONTACT_WRENCH_B: jump,
        names.ESTIMATE_IMU: imu,
        names.ESTIMATE_INERTIA: vector,
        names.ESTIMATE_MASSES: vector,
        names.ESTIMATE_GYRO_BIAS: vector,
        names.ESTIMATE_HEMI_INERTIA: vector,
    }


def decode_bag(bag_dir: Path | str) -> dict[str, TopicSamples]:
    """Every message of the topics a run series needs, decoded and validated."""
    decoders = _decoders()
    out: dict[str, TopicSamples] = {topic: TopicSamples() for topic in decoders}
    for m in read_messages(bag_dir, topics=list(decoders)):
        msg = deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[m.topic])
        try:
            decoders[m.topic](msg, m.log_time_ns, out[m.topic])
        except ValueError as exc:
            raise BagSeriesError(
                f"{bag_dir}: {m.topic} at log time {m.log_time_ns} ns: {exc}"
            ) from exc
    return out


def read_run_series(
    bag_dir: Path | str,
    gravity_m_s2: float | None = None,
    model: RobotModel | None = None,
) -> RunSeries:
    """The run recorded in ``bag_dir``.

    ``gravity_m_s2`` defaults to the bag's ``custom_data['gravity_m_s2']``, else 0.
    """
    if gravity_m_s2 is None:
        custom = read_metadata(bag_dir).custom_data
        try:
            gravity_m_s2 = float(custom.get(GRAVITY_KEY, 0.0))
        except ValueError as exc:
            raise BagSeriesError(f"custom_data {GRAVITY_KEY}: {exc}") from exc
    series = series_from_samples(decode_bag(bag_dir), model, gravity_m_s2)
    series.extras.update(fault_extras_from_bag(bag_dir, series.t_s))
    return series


def fault_extras_from_bag(bag_dir: Path | str, t_s: NDArray[np.float64]) -> dict[str, NDArray]:
    """``joint_fault`` (the simulator's, ``splitter_model.faults.FAULT_CODES``) and
    ``joint_detected`` (1 once the allocator found a joint faulty), (n, 25) at the series
    times, from ``/splitter/truth/joint_faults`` and ``/splitter/joint_health``; the library
    loop's extras of the same names. Empty when neither was recorded."""
    from splitter_model.faults import FAULT_CODES

    grid = np.round(np.asarray(t_s) * NS_PER_S).astype(np.int64)
    out = {"joint_fault": np.zeros((len(grid), names.N_JOINTS)), "joint_detected": None}
    out["joint_detected"] = np.zeros_like(out["joint_fault"])
    recorded = False
    topics = {names.TRUTH_JOINT_FAULTS: "joint_fault", names.JOINT_HEALTH: "joint_detected"}
    for m in read_messages(bag_dir, topics=list(topics)):
        msg = deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[m.topic])
        since = grid >= cv.stamp_from_msg(msg.header.stamp)
        for status in cv.diagnostics_from_msg(msg):
            for key, value in status.values.items():
                j = names.JOINT_INDEX.get(key)
                if j is None:
                    continue
                recorded = True
                code = FAULT_CODES.get(str(value), 0) if m.topic == names.TRUTH_JOINT_FAULTS else 1
                out[topics[m.topic]][since, j] = code
    return out if recorded else {}


def read_wall_timing(bag_dir: Path | str) -> tuple[float, float]:
    """(wall clock [s, epoch] of the simulator's first step, its stepping wall time [s]).

    From the simulator's last report on /diagnostics (``run_start_unix_s``,
    ``flight_wall_time_s``); :class:`BagSeriesError` when the bag has none.
    """
    latest: dict[str, str] = {}
    for m in read_messages(bag_dir, topics=[names.DIAGNOSTICS]):
        msg = deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[names.DIAGNOSTICS])
        for status in cv.diagnostics_from_msg(msg):
            if status.name.startswith(SIM_DIAGNOSTICS_PREFIX):
                if "flight_wall_time_s" in status.values:
                    latest = dict(status.values)
    if not latest:
        raise BagSeriesError(f"{bag_dir}: no simulator wall-time report on /diagnostics")
    return float(latest["run_start_unix_s"]), float(latest["flight_wall_time_s"])


# What a run's nodes report about time on /diagnostics (their last report of each key):
# input latency, commands that came after their stamps, the allocator's command lead,
# the simulator falling behind the wall clock, and the tether.
TIMING_KEY_PREFIXES = ("latency_",)
TIMING_KEYS = (
    "late_joint_commands",
    "real_time_backlog_drops",
    "real_time_behind_s",
    "command_lead_ms",
    "slack_events",
    "tether_tension_min_n",
    "lockstep_timeouts",
)


def read_timing_report(bag_dir: Path | str) -> dict[str, dict[str, float]]:
    """Per node (its /diagnostics status name), the last value of each timing key.

    See :data:`TIMING_KEYS`; latencies are ``latency_<input>_{mean,max,last}_ms`` and
    ``latency_<input>_count`` (:class:`splitter_msgs_py.core.latency.InputLatency`).
    """
    report: dict[str, dict[str, float]] = {}
    for m in read_messages(bag_dir, topics=[names.DIAGNOSTICS]):
        msg = deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[names.DIAGNOSTICS])
        for status in cv.diagnostics_from_msg(msg):
            for key, value in status.values.items():
                if key in TIMING_KEYS or key.startswith(TIMING_KEY_PREFIXES):
                    try:
                        report.setdefault(status.name, {})[key] = float(value)
                    except ValueError:
                        continue  # not a number: not a timing figure
    return report


def contact_forces_from_bag(bag_dir: Path, t_s: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """(n, 2, 3) contact force of each hemi [N] at the series times, or None if not recorded."""
    from splitter_bringup.analysis.bag_series import forward_fill
    from splitter_msgs_py.conversions import wrench_from_msg

    stamps: dict[str, list[int]] = {t: [] for t in names.CONTACT_WRENCHES}
    forces: dict[str, list[NDArray[np.float64]]] = {t: [] for t in names.CONTACT_WRENCHES}
    for m in read_messages(bag_dir, topics=list(names.CONTACT_WRENCHES)):
        sample = wrench_from_msg(deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[m.topic]))
        stamps[m.topic].append(sample.t_ns)
        forces[m.topic].append(np.asarray(sample.force_n, dtype=float))
    if not all(stamps.values()):
        _log.info("%s: no contact wrenches recorded, no contact arrows", bag_dir)
        return None
    grid = np.round(np.asarray(t_s) * NS_PER_S).astype(np.int64)
    return np.stack(
        [
            forward_fill(stamps[t], np.array(forces[t]), grid).astype(float)
            for t in names.CONTACT_WRENCHES
        ],
        axis=1,
    )


def run_check_arrays_from_bag(bag_dir: Path) -> dict[str, Any]:
    """Measured joint states, true body rate, gait phase and jump thrust of a graph bag.

    By stamp. The rate is ``/splitter/truth/imu``'s (``/splitter/imu``'s in a bag
    recorded before the truth topics). What
    :func:`splitter_bringup.analysis.run_check.check_run` reads; ValueError when fewer
    than 3 stamps carry both joint states and the rate.
    """
    from splitter_msgs_py.conversions import (
        imu_from_msg,
        joint_state_from_msg,
        stamp_from_msg,
        wrench_from_msg,
    )

    topics = (
        names.JOINT_STATES,
        names.IMU,
        names.TRUTH_IMU,
        names.GAIT_PHASE,
        names.JUMP_COMMAND,
    )
    joints: dict[int, np.ndarray] = {}
    rates_of: dict[str, dict[int, np.ndarray]] = {names.IMU: {}, names.TRUTH_IMU: {}}
    thrust: dict[int, np.ndarray] = {}
    phase_at: dict[int, str] = {}
    phase = ""
    for m in read_messages(bag_dir, topics=topics):
        msg = deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[m.topic])
        if m.topic == names.GAIT_PHASE:
            phase = msg.data
        elif m.topic == names.JOINT_STATES:
            sample = joint_state_from_msg(msg)
            joints[sample.t_ns] = sample.position
            phase_at[sample.t_ns] = phase
        elif m.topic in rates_of:
            imu = imu_from_msg(msg)
            rates_of[m.topic][imu.t_ns] = imu.angular_velocity_rad_s
        else:
            wrench = wrench_from_msg(msg)
            thrust[stamp_from_msg(msg.header.stamp)] = wrench.force_n
    rates = rates_of[truth_topic(names.IMU, [t for t, r in rates_of.items() if r])]
    stamps = sorted(t for t in joints if t in rates)
    if len(stamps) < 3:
        raise ValueError(f"{bag_dir}: fewer than 3 stamps with both joint_states and imu")
    last = np.zeros(3)
    jump = []
    for t in stamps:  # the latest jump command stays in force until the next
        last = thrust.get(t, last)
        jump.append(last)
    phases = [phase_at[t] for t in stamps]
    return {
        "t_s": np.array(stamps, dtype=float) * 1e-9,
        "joint_position": np.array([joints[t] for t in stamps]),
        "angular_velocity_rad_s": np.array([rates[t] for t in stamps]),
        "gait_phase": phases if any(phases) else None,
        "jump_force_n": np.array(jump) if thrust else None,
    }
