"""Actuator limits of SPLITTER's 25 actuated coordinates, derived from a :class:`RobotModel`.

8 limbs x (hip abduction, hip pitch, knee), then the prismatic tether
(:data:`splitter_model.joints.JOINT_NAMES` order; ``N_JOINTS`` and ``TETHER_INDEX``
are that module's): position range, speed and
acceleration bounds. The simulator's servo (``splitter_sim.core.actuators``)
never exceeds them; the allocator plans within them.
"""

from __future__ import annotations

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
