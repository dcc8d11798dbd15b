"""Actuator limits of SPLITTER's 25 actuated coordinates, derived from a :class:`RobotModel`.

8 limbs x (hip abduction, hip pitch, knee), then the prismatic tether
(:data:`splitter_model.joints.JOINT_NAMES` order; ``N_JOINTS`` and ``TETHER_INDEX``
are that module's): position range, speed and
acceleration bounds. The simulator's servo (``splitter_sim.core.actuators``)
never exceeds them; the allocator plans within them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from splitter_model.joints import N_JOINTS, N_LIMBS, TETHER_INDEX, limb_joints
from splitter_model.model import RobotModel


@dataclass(frozen=True)
class ActuatorLimits:
    """Per-joint bounds, arrays of length 25 in ``joints.JOINT_NAMES`` order."""

    position_min: NDArray[np.float64]  # [rad] / [m] tether
    position_max: NDArray[np.float64]  # [rad] / [m]
    speed_max: NDArray[np.float64]  # [rad/s] / [m/s]
    acceleration_max: NDArray[np.float64]  # [rad/s^2] / [m/s^2]


def actuator_limits(model: RobotModel) -> ActuatorLimits:
    """Joint and tether limits of ``model``."""
    lo = np.empty(N_JOINTS)
    hi = np.empty(N_JOINTS)
    for limb in range(N_LIMBS):  # (hip abduction, hip pitch, knee)
        lo[limb_joints(limb)] = (
            -model.hip_abduction_limit_rad,
            -model.hip_pitch_limit_rad,
            model.knee_min_rad,
        )
        hi[limb_joints(limb)] = (
            model.hip_abduction_limit_rad,
            model.hip_pitch_limit_rad,
            model.knee_max_rad,
        )
    lo[TETHER_INDEX], hi[TETHER_INDEX] = model.tether_length_min_m, model.tether_length_max_m
    speed = np.full(N_JOINTS, model.joint_speed_max_rad_s)
    speed[TETHER_INDEX] = model.tether_speed_max_m_s
    accel = np.full(N_JOINTS, model.joint_acceleration_max_rad_s2)
    accel[TETHER_INDEX] = model.tether_acceleration_max_m_s2
    return ActuatorLimits(lo, hi, speed, accel)


class CommandLag:
    """A first-order lag between the joint commands sent and what the servos follow.

    ``dx/dt = (u - x) / tau`` on every command (position and velocity alike),
    ``u`` held over a command period ``period_s``: exactly
    ``x_{k+1} = x_k + alpha (u_k - x_k)``, ``alpha = 1 - exp(-period / tau)``
    (``tau = 0``: no lag, ``alpha = 1``). The simulated robot's servos follow
    :meth:`apply`. The controllers expect it by commanding ahead: a first-order lag
    delays a smooth command by about ``tau``, so the MPC sends each setpoint ``tau``
    early on its plan (``ControllerConfig.actuator_lag_s``). Inverting the lag in the
    allocator instead (``u = x + (d - x) / alpha``, 5.5x for 50 ms at 10 ms) hits the
    joint limits and the actuator speed and breaks hip-knee step (measured: tether
    slack down to -27 N on the paper's tumble; none with the preview).
    """

    def __init__(self, time_constant_s: float, period_s: float) -> None:
        if not (math.isfinite(time_constant_s) and time_constant_s >= 0.0):
            raise ValueError(f"lag time constant must be finite and >= 0, got {time_constant_s!r}")
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"command period must be finite and > 0, got {period_s!r}")
        self.time_constant_s = float(time_constant_s)  # [s]
        self.alpha = 1.0 if time_constant_s == 0.0 else -math.expm1(-period_s / time_constant_s)
        self._state: tuple[NDArray[np.float64], ...] | None = None

    @property
    def state(self) -> tuple[NDArray[np.float64], ...] | None:
        """The lagged commands now (None before the first)."""
        return self._state

    def apply(self, *command: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        """The lagged values of the commands ``u_k`` just sent (the first passes through)."""
        u = tuple(np.array(c, dtype=float) for c in command)
        if self._state is None or self.alpha == 1.0:
            self._state = u
        else:
            self._state = tuple(
                x + self.alpha * (c - x) for x, c in zip(self._state, u, strict=True)
            )
        return self._state
