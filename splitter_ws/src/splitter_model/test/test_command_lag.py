"""The one actuator-lag model: the servos' side (apply) and the allocator's (lead)."""

import math

import numpy as np
import pytest

from splitter_model.actuators import CommandLag, actuator_limits
from splitter_model.joints import N_JOINTS
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel

PERIOD_S = 0.01  # [s] the control tick
TAU_S = 0.05  # [s]


def test_apply_is_the_exact_first_order_step_response():
    lag = CommandLag(TAU_S, PERIOD_S)
    zero = np.zeros(1)
    lag.apply(zero)  # the first command passes through
    for k in range(1, 31):
        (x,) = lag.apply(np.ones(1))
        assert x[0] == pytest.approx(1.0 - math.exp(-k * PERIOD_S / TAU_S), rel=1e-12)


def test_no_lag_passes_commands_through():
    lag = CommandLag(0.0, PERIOD_S)
    assert lag.alpha == 1.0
    q, qd = lag.apply(np.array([1.0]), np.array([2.0]))
    assert q[0] == 1.0 and qd[0] == 2.0


def test_lead_makes_the_lagged_command_the_wanted_one():
    model = RobotModel()
    limits = actuator_limits(model)
    rng = np.random.default_rng(3)
    lead, servo = CommandLag(TAU_S, PERIOD_S), CommandLag(TAU_S, PERIOD_S)
    start = joint_positions_from_radii(model, (2.0, 0.25, 0.25))
    for k in range(50):  # a smooth path well inside the joint range
        wanted = joint_positions_from_radii(
            model, (2.0 + 0.3 * math.sin(0.1 * k), 0.25 + 0.05 * math.sin(0.2 * k), 0.25)
        )
        velocity = 0.1 * rng.standard_normal(N_JOINTS)
        sent = lead.lead(wanted, velocity, limits)
        followed = servo.apply(*sent)
        np.testing.assert_allclose(followed[0], wanted, atol=1e-12)
        np.testing.assert_allclose(followed[1], velocity, atol=1e-12)
    assert start.shape == (N_JOINTS,)


def test_lead_stays_within_the_joint_range_and_catches_up():
    model = RobotModel()
    limits = actuator_limits(model)
    lead, servo = CommandLag(TAU_S, PERIOD_S), CommandLag(TAU_S, PERIOD_S)
    low = limits.position_min + 0.01
    high = limits.position_max - 0.01
    servo.apply(*lead.lead(low, np.zeros(N_JOINTS), limits))
    for _ in range(100):  # a jump across the range: the lead would leave it, clipped
        sent = lead.lead(high, np.zeros(N_JOINTS), limits)
        assert np.all(sent[0] >= limits.position_min) and np.all(sent[0] <= limits.position_max)
        followed = servo.apply(*sent)
        np.testing.assert_allclose(followed[0], lead.state[0], atol=1e-12)  # honest state
    np.testing.assert_allclose(followed[0], high, atol=1e-9)


@pytest.mark.parametrize("tau, period", [(-0.1, 0.01), (math.nan, 0.01), (0.05, 0.0)])
def test_invalid_lag_is_refused(tau, period):
    with pytest.raises(ValueError, match="finite"):
        CommandLag(tau, period)
