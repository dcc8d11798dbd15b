"""The one actuator-lag model the simulated servos follow."""

import math

import numpy as np
import pytest

from splitter_model.actuators import CommandLag

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


@pytest.mark.parametrize("tau, period", [(-0.1, 0.01), (math.nan, 0.01), (0.05, 0.0)])
def test_invalid_lag_is_refused(tau, period):
    with pytest.raises(ValueError, match="finite"):
        CommandLag(tau, period)
