"""The gait's body-motion estimator against closed forms: free fall, a slide, rest."""

from __future__ import annotations

import numpy as np
import pytest

from splitter_mpc.core.gait_sensing import (
    BodyMotionEstimator,
    BodySensingConfig,
    ImuReading,
    leg_stance_force_n,
)

G = 1.62  # [m/s^2] the Moon
TICK_NS = 10_000_000
LEVEL = np.array([1.0, 0.0, 0.0, 0.0])
NO_RETURN = (np.inf, np.inf)


def _imu(specific_force, rate=(0.0, 0.0, 0.0)) -> ImuReading:
    return ImuReading(LEVEL, np.asarray(rate, dtype=float), np.asarray(specific_force, dtype=float))


def test_free_fall_integrates_gravity_and_the_ranges_pin_the_height() -> None:
    """Released at rest 3 m up: v_z = -g t, z = 3 - g t^2 / 2 (the accelerometer reads 0)."""
    body = BodyMotionEstimator(BodySensingConfig(gravity_m_s2=G, range_noise_m=1e-3))
    radius_x = 2.0
    for k in range(101):
        t = k * 0.01
        z = 3.0 - 0.5 * G * t * t
        motion = body.update(k * TICK_NS, _imu((0.0, 0.0, 0.0)), (z, z), (False, False), radius_x)
    assert motion.velocity_m_s[2] == pytest.approx(-G * 1.0, rel=1e-9)
    assert motion.position_m[2] == pytest.approx(3.0 - 0.5 * G, abs=2e-3)
    assert motion.height_measured and not motion.at_rest


def test_a_slide_decelerates_by_friction_and_is_not_taken_for_rest() -> None:
    """On its legs, sliding at 0.5 m/s against mu g = 0.8 m/s^2 of friction."""
    body = BodyMotionEstimator(BodySensingConfig(gravity_m_s2=G))
    body._horizontal[:] = (0.5, 0.0)
    for k in range(31):
        motion = body.update(k * TICK_NS, _imu((-0.8, 0.0, G)), (0.4, 0.4), (True, True), 2.0)
    assert not motion.at_rest
    assert motion.velocity_m_s[0] == pytest.approx(0.5 - 0.8 * 0.3, abs=1e-9)


def test_still_on_both_legs_is_rest_and_resets_the_velocity() -> None:
    body = BodyMotionEstimator(BodySensingConfig(gravity_m_s2=G))
    body._horizontal[:] = (0.2, -0.1)
    motion = body.update(0, _imu((0.0, 0.0, G)), (0.4, 0.4), (True, True), 2.0)
    assert motion.at_rest and not motion.velocity_m_s[:2].any()
    one_leg = BodyMotionEstimator(BodySensingConfig(gravity_m_s2=G))
    one_leg._horizontal[:] = (0.2, -0.1)
    assert not one_leg.update(0, _imu((0.0, 0.0, G)), NO_RETURN, (True, False), 2.0).at_rest
    spinning = BodyMotionEstimator(BodySensingConfig(gravity_m_s2=G))
    assert not spinning.update(
        0, _imu((0.0, 0.0, G), (0, 0.2, 0)), NO_RETURN, (True, True), 2.0
    ).at_rest


def test_time_going_back_is_refused_and_the_leg_force_is_its_magnitude() -> None:
    body = BodyMotionEstimator()
    body.update(TICK_NS, _imu((0.0, 0.0, 0.0)), NO_RETURN, (False, False), 2.0)
    with pytest.raises(ValueError, match="time went back"):
        body.update(0, _imu((0.0, 0.0, 0.0)), NO_RETURN, (False, False), 2.0)
    assert leg_stance_force_n((3.0, 0.0, 4.0)) == pytest.approx(5.0)
