"""Fault detection from joint states against commands (:mod:`splitter_ik.core.joint_health`).

A synthetic servo stands in for the joints: the commands reach it after a latency,
through a first-order lag, then a rate limit: the robot errors the campaigns fly
(20 ms, 50 ms). Healthy, it is never flagged, however its commands move; locked, it
is found once commanded away; limp, once it leaves its commands.
"""

from __future__ import annotations

import numpy as np
import pytest

from splitter_ik.core.joint_health import NOT_FOLLOWING, STUCK, JointHealthMonitor
from splitter_model.joints import JOINT_INDEX, N_JOINTS, TETHER_INDEX

PERIOD_NS = 10_000_000  # [ns] the control tick
STEP_NS = 5_000_000  # [ns] the simulator step
LATENCY_NS = 20_000_000
LAG_S = 0.05
SPEED_MAX = 8.0  # [rad/s] servo


class LaggedServo:
    """Commands after a latency, through a first-order lag and a speed limit."""

    def __init__(self, start: np.ndarray) -> None:
        self.q = start.astype(float).copy()
        self.lagged = start.astype(float).copy()
        self.queue: list[tuple[int, np.ndarray, np.ndarray]] = []
        self.frozen = np.zeros(N_JOINTS, dtype=bool)
        self.drift = np.zeros(N_JOINTS)  # [rad/s] of a limp joint swinging

    def command(self, t_ns: int, q: np.ndarray, v: np.ndarray) -> None:
        self.queue.append((t_ns + LATENCY_NS, q.copy(), v.copy()))

    def step(self, t_ns: int) -> None:
        due = [c for c in self.queue if c[0] <= t_ns]
        if due:
            stamp, q, v = due[-1]
            target = q + v * min((t_ns - stamp) * 1e-9, 0.02)
            alpha = 1.0 - np.exp(-STEP_NS * 1e-9 / LAG_S)
            self.lagged += alpha * (target - self.lagged)
        move = np.clip(self.lagged - self.q, -SPEED_MAX * 5e-3, SPEED_MAX * 5e-3)
        self.q = np.where(self.frozen, self.q, self.q + move)
        self.q += self.drift * STEP_NS * 1e-9


def _fly(commands, seconds: float, fault=None, monitor=None):
    """Closed loop of commands (a function of t [s] -> (q, v)) and the servo; the detections."""
    monitor = monitor or JointHealthMonitor()
    q0, _ = commands(0.0)
    servo = LaggedServo(q0)
    found = []
    for k in range(round(seconds * 1e9 / STEP_NS)):
        t_ns = k * STEP_NS
        if fault is not None:
            fault(t_ns, servo)
        servo.step(t_ns)
        if t_ns % PERIOD_NS == 0:
            found += monitor.on_measurement(t_ns, servo.q)
            q, v = commands(t_ns * 1e-9)
            monitor.on_command(t_ns, q, v)
            servo.command(t_ns, q, v)
    return found, monitor


def _morphing(t: float) -> tuple[np.ndarray, np.ndarray]:
    """Every joint on its own sine: amplitudes up to 1 rad, speeds up to 3 rad/s."""
    i = np.arange(N_JOINTS)
    amplitude = 0.2 + 0.8 * (i % 5) / 4.0
    omega = 1.0 + 2.0 * (i % 3) / 2.0 / np.maximum(amplitude, 1.0)
    q = 1.0 + amplitude * np.sin(omega * t + i)
    v = amplitude * omega * np.cos(omega * t + i)
    q[TETHER_INDEX] = 4.0 + 0.5 * np.sin(0.8 * t)
    v[TETHER_INDEX] = 0.4 * np.cos(0.8 * t)
    return q, v


def _still(t: float) -> tuple[np.ndarray, np.ndarray]:
    return np.full(N_JOINTS, 1.0), np.zeros(N_JOINTS)


def test_healthy_joints_with_latency_and_lag_are_never_flagged() -> None:
    found, _ = _fly(_morphing, 20.0)
    assert found == []


def test_a_joint_locked_at_rest_shows_nothing_until_it_is_asked_to_move() -> None:
    knee = JOINT_INDEX["hemi_a_y_pos_knee"]

    def commands(t: float) -> tuple[np.ndarray, np.ndarray]:
        q, v = _still(t)
        if t >= 1.0:  # the knee is asked to move at 0.5 rad/s from 1 s
            q[knee] += 0.5 * (t - 1.0)
            v[knee] = 0.5
        return q, v

    def lock(t_ns: int, servo: LaggedServo) -> None:
        servo.frozen[knee] = t_ns >= 200_000_000

    found, _ = _fly(commands, 0.99, lock)
    assert found == []
    found, _ = _fly(commands, 2.0, lock)
    assert [(d.joint, d.symptom) for d in found] == [(knee, STUCK)]
    latency = found[0].t_ns * 1e-9 - 1.0
    assert 0.0 < latency <= 0.2  # [s] after the first commanded motion


def test_a_locked_reel_is_found_in_metres() -> None:
    def lock(t_ns: int, servo: LaggedServo) -> None:
        servo.frozen[TETHER_INDEX] = t_ns >= 1_000_000_000

    found, _ = _fly(_morphing, 3.0, lock)
    assert [d.joint for d in found] == [TETHER_INDEX]
    assert found[0].t_ns * 1e-9 - 1.0 <= 0.2


def test_a_limp_joint_swinging_away_does_not_follow() -> None:
    pitch = JOINT_INDEX["hemi_b_z_neg_hip_pitch"]

    def limp(t_ns: int, servo: LaggedServo) -> None:
        if t_ns >= 500_000_000:
            servo.frozen[pitch] = True
            servo.drift[pitch] = 1.5  # [rad/s] the centrifugal swing

    found, monitor = _fly(_still, 2.0, limp)
    assert [(d.joint, d.symptom) for d in found] == [(pitch, NOT_FOLLOWING)]
    assert found[0].t_ns * 1e-9 - 0.5 <= 0.2
    assert monitor.symptoms == {pitch: NOT_FOLLOWING}


def test_a_stuck_joint_that_moves_later_is_limp_after_all() -> None:
    knee = JOINT_INDEX["hemi_a_z_pos_knee"]

    def commands(t: float) -> tuple[np.ndarray, np.ndarray]:
        q, v = _still(t)
        q[knee] += 0.3 * min(t, 1.0)
        v[knee] = 0.3 if t < 1.0 else 0.0
        return q, v

    def limp_later(t_ns: int, servo: LaggedServo) -> None:
        servo.frozen[knee] = True  # no torque: at rest it stays
        servo.drift[knee] = -0.5 if t_ns >= 1_500_000_000 else 0.0  # then loaded

    found, monitor = _fly(commands, 1.4, limp_later)
    assert [(d.joint, d.symptom) for d in found] == [(knee, STUCK)]
    _, monitor = _fly(commands, 2.5, limp_later)
    assert monitor.symptoms == {knee: NOT_FOLLOWING}
    assert len(monitor.detections) == 1


def test_detection_off_reports_nothing() -> None:
    def lock(t_ns: int, servo: LaggedServo) -> None:
        servo.frozen[:] = True

    found, monitor = _fly(_morphing, 1.0, lock, JointHealthMonitor(enabled=False))
    assert found == [] and monitor.faulty_joints == frozenset()


def test_non_finite_joint_states_are_refused() -> None:
    with pytest.raises(ValueError, match="finite"):
        JointHealthMonitor().on_measurement(0, np.full(N_JOINTS, np.nan))
