"""Fault detection from joint states against commands (:mod:`splitter_ik.core.joint_health`).

A synthetic servo stands in for the joints: the commands reach it after a latency,
through the robot's first-order lag (``CommandLag``), then a rate limit: the robot
errors the campaigns fly (20 ms, 50 ms), which the detector is told. Healthy, it is
never flagged, however its commands move; locked, it is found once commanded away;
limp, once it leaves its commands.
"""

from __future__ import annotations

import numpy as np
import pytest

from splitter_ik.core.joint_health import (
    NOT_FOLLOWING,
    STUCK,
    JointHealthConfig,
    JointHealthMonitor,
    ServoModel,
)
from splitter_model.actuators import CommandLag
from splitter_model.joints import JOINT_INDEX, N_JOINTS, TETHER_INDEX

PERIOD_NS = 10_000_000  # [ns] the control tick
STEP_NS = 5_000_000  # [ns] the simulator step
LATENCY_NS = 20_000_000
LAG_S = 0.05
SPEED_MAX = 8.0  # [rad/s] servo
# what the detector is told of the servos
SERVO_DATASHEET = JointHealthConfig(servo_lag_s=LAG_S, servo_latency_s=LATENCY_NS * 1e-9)


class LaggedServo:
    """Commands after a latency, through the robot's first-order lag, then a speed limit."""

    def __init__(self, start: np.ndarray) -> None:
        self.q = start.astype(float).copy()
        self.lag = CommandLag(LAG_S, PERIOD_NS * 1e-9)
        self.followed: tuple[int, np.ndarray, np.ndarray] | None = None
        self.queue: list[tuple[int, np.ndarray, np.ndarray]] = []
        self.frozen = np.zeros(N_JOINTS, dtype=bool)
        self.drift = np.zeros(N_JOINTS)  # [rad/s] of a limp joint swinging

    def command(self, t_ns: int, q: np.ndarray, v: np.ndarray) -> None:
        self.queue.append((t_ns, q.copy(), v.copy()))

    def step(self, t_ns: int) -> None:
        while self.queue and self.queue[0][0] + LATENCY_NS <= t_ns:
            stamp, q, v = self.queue.pop(0)
            self.followed = (stamp, *self.lag.apply(q, v))
        if self.followed is not None:
            stamp, q, v = self.followed
            target = q + v * min((t_ns - stamp) * 1e-9, 0.02)
            move = np.clip(target - self.q, -SPEED_MAX * 5e-3, SPEED_MAX * 5e-3)
            self.q = np.where(self.frozen, self.q, self.q + move)
        self.q += self.drift * STEP_NS * 1e-9


def _fly(commands, seconds: float, fault=None, monitor=None):
    """Closed loop of commands (a function of t [s] -> (q, v)) and the servo; the detections."""
    monitor = monitor or JointHealthMonitor(SERVO_DATASHEET)
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


def _fly_exact(commands, seconds: float, fault=None):
    """As :func:`_fly`, with servos that follow their commands at once (no latency, no
    lag: the nominal robot), which the detector is told (its defaults)."""
    global LATENCY_NS, LAG_S
    saved = LATENCY_NS, LAG_S
    LATENCY_NS, LAG_S = 0, 0.0
    try:
        return _fly(commands, seconds, fault, JointHealthMonitor())
    finally:
        LATENCY_NS, LAG_S = saved


def _sweep(t: float) -> tuple[np.ndarray, np.ndarray]:
    """Every joint still but one knee, sweeping at 3 rad/s from 0.5 s to 1.0 s."""
    q, v = _still(t)
    knee = JOINT_INDEX["hemi_b_z_pos_knee"]
    if 0.5 <= t < 1.0:
        q[knee] += 3.0 * (t - 0.5)
        v[knee] = 3.0
    elif t >= 1.0:
        q[knee] += 1.5
    return q, v


def test_exact_servos_following_a_fast_sweep_are_never_flagged() -> None:
    found, _ = _fly_exact(_sweep, 2.0)
    assert found == []


def test_a_limp_joint_trailing_its_moving_command_is_found_at_once() -> None:
    """Limp while sweeping: its momentum carries it along, slower than its command (a
    servo with lag would trail the same way, so only a detector that knows the servos
    can tell)."""
    knee = JOINT_INDEX["hemi_b_z_pos_knee"]

    def limp(t_ns: int, servo: LaggedServo) -> None:
        if t_ns >= 600_000_000:
            servo.frozen[knee] = True
            servo.drift[knee] = 2.0  # [rad/s] coasting, against the 3 rad/s asked

    found, _ = _fly_exact(_sweep, 1.2, limp)
    assert [(d.joint, d.symptom) for d in found] == [(knee, NOT_FOLLOWING)]
    assert found[0].t_ns * 1e-9 - 0.6 <= 0.06  # 1 rad/s off: 10 mrad in 10 ms, then 30 ms


def test_a_joint_locked_while_moving_is_stuck_not_limp() -> None:
    knee = JOINT_INDEX["hemi_b_z_pos_knee"]

    def lock(t_ns: int, servo: LaggedServo) -> None:
        servo.frozen[knee] = t_ns >= 700_000_000

    found, monitor = _fly_exact(_sweep, 1.2, lock)
    assert [(d.joint, d.symptom) for d in found] == [(knee, STUCK)]
    assert found[0].t_ns * 1e-9 - 0.7 <= 0.2
    assert monitor.symptoms == {knee: STUCK}


def test_a_creeping_limp_joint_is_found_within_the_bound() -> None:
    """Limp at rest, then creeping at 10 mrad/s away from its still command: too fast to
    look stuck, far too slow to leave its commands' envelope (0.02 rad) in time."""
    knee = JOINT_INDEX["hemi_a_y_neg_knee"]

    def creep(t_ns: int, servo: LaggedServo) -> None:
        if t_ns >= 500_000_000:
            servo.frozen[knee] = True
            servo.drift[knee] = 0.01  # [rad/s]

    found, _ = _fly_exact(_still, 3.0, creep)
    assert [(d.joint, d.symptom) for d in found] == [(knee, NOT_FOLLOWING)]
    asked = 0.5 + JointHealthConfig().stuck_error_rad / 0.01  # its error passes "asked"
    assert found[0].t_ns * 1e-9 - asked <= 0.2


def test_a_fault_before_a_window_of_commands_is_found() -> None:
    """Limp from the first tick on: the servo held where it was first measured."""
    pitch = JOINT_INDEX["hemi_b_y_neg_hip_pitch"]

    def limp(t_ns: int, servo: LaggedServo) -> None:
        if t_ns >= 20_000_000:
            servo.frozen[pitch] = True
            servo.drift[pitch] = -1.0  # [rad/s]

    found, _ = _fly(_still, 0.3, limp)
    assert [d.joint for d in found] == [pitch]
    assert found[0].t_ns * 1e-9 - 0.02 <= 0.1


def test_the_servo_model_is_the_robots_lag_after_its_latency() -> None:
    """ServoModel against CommandLag: a command reaches it after the latency, through the
    lag; between two commands it holds the target and the one before."""
    lag = CommandLag(LAG_S, PERIOD_NS * 1e-9)
    model = ServoModel(LAG_S, LATENCY_NS * 1e-9)
    rng = np.random.default_rng(3)
    start = np.zeros(N_JOINTS)
    for k in range(30):
        q, v = rng.normal(size=N_JOINTS), np.zeros(N_JOINTS)
        model.on_command(k * PERIOD_NS, q, v)
        expected = lag.apply(q, v)[0]
        now, _ = model.targets(k * PERIOD_NS + LATENCY_NS, 0.02, start)
        np.testing.assert_allclose(now, expected, atol=1e-12)


def test_one_stray_joint_state_is_not_a_fault() -> None:
    """A joint state from elsewhere (every joint at 0.1 rad) between two true ones: every
    joint is off its commands for one sample, none for the 30 ms a fault must last."""
    monitor = JointHealthMonitor()
    for k in range(100):
        t_ns = k * STEP_NS
        q, _ = _sweep(t_ns * 1e-9 + 0.4)
        stray = k == 60
        assert monitor.on_measurement(t_ns, np.full(N_JOINTS, 0.1) if stray else q) == []
        if t_ns % PERIOD_NS == 0:
            monitor.on_command(t_ns, *_sweep(t_ns * 1e-9 + 0.4))
    assert monitor.faulty_joints == frozenset()
