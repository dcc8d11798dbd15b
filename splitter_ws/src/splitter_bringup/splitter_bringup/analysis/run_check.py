"""Check a recorded run's joint speeds and estimated torques against the actuator limits.

Input: sample times, the 25 joint positions (order of ``names.JOINT_NAMES``) and
the body angular velocity, e.g. from a ``splitter_bringup.analysis.series.RunSeries``.

* Speeds and accelerations: finite differences of ``joint_position`` (limb joints
  against ``RobotModel.joint_speed_max_rad_s`` / ``joint_acceleration_max_rad_s2``,
  the tether against the reel's ``tether_speed_max_m_s`` / ``tether_acceleration_max_m_s2``).
* Limb torques, free flight: each limb is massless with its lumped mass ``m_y`` or
  ``m_z`` at the tip. The limb pulls the tip with ``F = m a``, ``a`` the tip's
  acceleration relative to the freely falling centre of mass (gravity cancels):
  ``a = P'' + 2 w x P' + w' x P + w x (w x P)`` with ``P`` the tip in ``base``; the
  joints hold it with ``tau = J^T F`` (``J`` the limb Jacobian). Contact forces
  are not in the record, so stance phases are left out when the gait phase is
  recorded, and a jump thrust is checked with the sizing's rule
  (``|F| / legs * l1`` per joint).
* Tether reel torque: ``T * spool radius`` with ``T = M_h (r_x w_perp^2 - r_x'')``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_bringup.analysis.series import RunSeries
from splitter_ik.core.tether import hemi_mass_kg
from splitter_model.actuators import TETHER_INDEX
from splitter_model.kinematics import limb_forward_kinematics, limb_offsets_from_joint_positions
from splitter_model.model import (
    MOTOR_OUTPUT_CONTINUOUS_TORQUE_NM,
    MOTOR_OUTPUT_PEAK_TORQUE_NM,
    RobotModel,
)

FLIGHT_PHASES = ("IN_FLIGHT",)
_JACOBIAN_STEP_RAD = 1e-6


@dataclass(frozen=True)
class LimitCheck:
    """One quantity's worst value against its limit."""

    key: str
    value: float
    limit: float
    unit: str
    where: str  # joint name or "tether", and the time of the worst sample

    @property
    def ok(self) -> bool:
        """Within the limit."""
        return self.value <= self.limit

    @property
    def utilisation(self) -> float:
        """value / limit [-]."""
        return self.value / self.limit


def limb_jacobian(model: RobotModel, limb: int, joint_angles_rad: ArrayLike) -> NDArray[np.float64]:
    """d(tip)/d(hip_abduction, hip_pitch, knee) [m/rad] in ``base``, by central differences."""
    q = np.asarray(joint_angles_rad, dtype=float)
    jac = np.empty((3, 3))
    for j in range(3):
        dq = np.zeros(3)
        dq[j] = _JACOBIAN_STEP_RAD
        jac[:, j] = (
            limb_forward_kinematics(model, limb, q + dq)
            - limb_forward_kinematics(model, limb, q - dq)
        ) / (2.0 * _JACOBIAN_STEP_RAD)
    return jac


def tip_positions_m(model: RobotModel, joint_position: ArrayLike) -> NDArray[np.float64]:
    """Limb tips (n, 8, 3) [m] in ``base``: hemi body at (+-L/2, 0, 0) plus the limb FK."""
    q = np.atleast_2d(np.asarray(joint_position, dtype=float))
    hemi_side = np.where(np.arange(8) < 4, 1.0, -1.0)  # limbs 0-3 on hemi a (+x), 4-7 on b
    tips = np.empty((q.shape[0], 8, 3))
    for k in range(q.shape[0]):
        tips[k] = limb_offsets_from_joint_positions(model, q[k])
        tips[k, :, 0] += hemi_side * q[k, TETHER_INDEX] / 2.0
    return tips


def limb_joint_torques_nm(
    model: RobotModel,
    t_s: ArrayLike,
    joint_position: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
) -> NDArray[np.float64]:
    """Estimated limb joint torques (n, 24) [Nm] in free flight (see module doc)."""
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(joint_position, dtype=float)
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    tips = tip_positions_m(model, q)
    vel = np.gradient(tips, t, axis=0)
    acc = np.gradient(vel, t, axis=0)
    w_dot = np.gradient(w, t, axis=0)
    tip_masses = [model.limb_mass_y_kg, model.limb_mass_y_kg, model.limb_mass_z_kg,
                  model.limb_mass_z_kg] * 2  # fmt: skip
    torques = np.zeros((len(t), 24))
    for k in range(len(t)):
        wk = w[k]
        for limb in range(8):
            p, pd = tips[k, limb], vel[k, limb]
            a = acc[k, limb] + 2.0 * np.cross(wk, pd) + np.cross(w_dot[k], p)
            a = a + np.cross(wk, np.cross(wk, p))
            force = tip_masses[limb] * a
            jac = limb_jacobian(model, limb, q[k, 3 * limb : 3 * limb + 3])
            torques[k, 3 * limb : 3 * limb + 3] = jac.T @ force
    return torques


def check_run(
    model: RobotModel,
    t_s: ArrayLike,
    joint_position: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    *,
    gait_phase: list[str] | None = None,
    jump_force_n: ArrayLike | None = None,
    joint_names: tuple[str, ...] | None = None,
    legs: int = 4,
) -> list[LimitCheck]:
    """Worst joint speed, acceleration and torque of a run against the actuator limits."""
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(joint_position, dtype=float)
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    if t.ndim != 1 or len(t) < 3 or q.shape != (len(t), 25) or w.shape != (len(t), 3):
        raise ValueError(
            "need >= 3 samples of t_s (n,), joint_position (n, 25), angular velocity (n, 3)"
        )
    if np.any(np.diff(t) <= 0.0) or not (np.all(np.isfinite(q)) and np.all(np.isfinite(w))):
        raise ValueError("t_s must increase strictly and every sample must be finite")
    names = joint_names or tuple(f"joint_{i}" for i in range(25))
    speed = np.gradient(q, t, axis=0)
    accel = np.gradient(speed, t, axis=0)

    def worst(key: str, values: NDArray[np.float64], labels: list[str], limit: float,
              unit: str) -> LimitCheck:  # fmt: skip
        block = np.abs(values)
        k, j = np.unravel_index(int(np.argmax(block)), block.shape)
        return LimitCheck(key, float(block[k, j]), limit, unit, f"{labels[j]} at t = {t[k]:.3f} s")

    limb_names = list(names[:TETHER_INDEX])
    out = [
        worst("limb_joint_speed", speed[:, :TETHER_INDEX], limb_names,
              model.joint_speed_max_rad_s, "rad/s"),
        worst("limb_joint_acceleration", accel[:, :TETHER_INDEX], limb_names,
              model.joint_acceleration_max_rad_s2, "rad/s^2"),
        worst("tether_speed", speed[:, TETHER_INDEX:], [names[TETHER_INDEX]],
              model.tether_speed_max_m_s, "m/s"),
        worst("tether_acceleration", accel[:, TETHER_INDEX:], [names[TETHER_INDEX]],
              model.tether_acceleration_max_m_s2, "m/s^2"),
    ]  # fmt: skip
    flight = np.ones(len(t), dtype=bool)
    if gait_phase:
        flight = np.array([p in FLIGHT_PHASES for p in gait_phase])
    if np.any(flight):
        torques = np.where(flight[:, None], limb_joint_torques_nm(model, t, q, w), 0.0)
        out.append(worst("limb_torque_flight", torques, limb_names,
                         MOTOR_OUTPUT_CONTINUOUS_TORQUE_NM, "Nm"))  # fmt: skip
    tension = hemi_mass_kg(model) * (
        q[:, TETHER_INDEX] / 2.0 * (w[:, 1] ** 2 + w[:, 2] ** 2) - accel[:, TETHER_INDEX] / 2.0
    )
    reel = np.abs(tension)[:, None] * model.tether_spool_radius_m
    out.append(worst("tether_reel_torque", reel, ["tether reel"],
                     MOTOR_OUTPUT_CONTINUOUS_TORQUE_NM, "Nm"))  # fmt: skip
    if jump_force_n is not None:
        thrust = np.linalg.norm(np.asarray(jump_force_n, dtype=float), axis=1)
        jump_tau = (thrust / legs * model.thigh_length_m)[:, None]
        out.append(worst("jump_joint_torque", jump_tau, ["pushing leg"],
                         MOTOR_OUTPUT_PEAK_TORQUE_NM, "Nm"))  # fmt: skip
    return out


def run_check_arrays(series: RunSeries) -> dict[str, Any]:
    """What :func:`check_run` reads, from a run's series (time, joints, rate, gait, thrust)."""
    return {
        "t_s": series.t_s,
        "joint_position": series.joint_position,
        "angular_velocity_rad_s": series.angular_velocity_rad_s,
        "gait_phase": list(series.gait_phase) or None,
        "jump_force_n": series.jump_force_n,
    }
