"""Tether / limb allocator: principal-inertia setpoints to joint commands.

Each control tick :meth:`TetherLimbAllocator.allocate`

1. projects the setpoint onto the reachable set (:func:`project_inertia`),
2. moves the three drive coordinates toward the projected radii with a second-order
   limiter (:func:`limited_step`): the tether length ``L = 2 r_x`` within the reel's
   speed and acceleration (``RobotModel.tether_speed_max_m_s``,
   ``tether_acceleration_max_m_s2``) and the knee angles of the y and z limbs
   within the joint speed (800 RPM after the 10:1 gearbox) and acceleration limits
   (derated by the hip pitch / knee speed ratio so that the hip pitch, which turns
   with the knee, obeys them too), each scaled by its share in :class:`AllocatorConfig`,
3. reels the tether out only as fast as keeps it taut: ``r_x'' <= r_x w_perp^2 -
   T_min / M_h`` (:mod:`splitter_ik.core.tether`), which also bounds how hard a
   reel-in can be braked, so reel-in speeds are planned with the braking available
   on the way to the target, the spin there predicted from conserved angular
   momentum (``w_i I_i`` constant). A reel-in that could not be braked taut is not
   started. ``T_min`` is the configured margin; reeling in, it is at most half the
   centripetal load ``M_h r_x w_perp^2`` (:meth:`TetherLimbAllocator.required_tension_n`),
   so that a spin too slow for the margin can still be reeled in (which only adds
   tension) and braked by the spin-up the reel-in brings; paying out keeps the full
   margin, and when the spin cannot hold it even at rest the tether is held. The
   reel follows the setpoints' own velocity (their mean over
   ``AllocatorConfig.reference_velocity_window_s``, one re-plan period) and closes
   the gap on top of it, so a planned reel-in runs at the plan's speed; if the plan
   then stops faster than the spin can brake taut, the reel overshoots, braking
   taut, and still stops taut before its end. These limits are free-fall physics:
   once the accelerometer has said for a while that the robot is held by more than
   its tether (feet on the ground; ``AllocatorConfig.supported_specific_force_m_s2``
   and ``supported_dwell_s``) the reel brakes at the actuator's limits,
4. turns the radii into the 25 joint positions with
   ``splitter_model.kinematics.joint_positions_from_radii``.

An allocation is a point of a piecewise-linear joint trajectory: ``joint_position``
is where the joints are planned to be at ``t_ns`` (the previous allocation's
position plus its velocity times ``control_period_s``), ``joint_velocity`` the
constant velocity that takes them to the next planned position by
``t_ns + control_period_s``. So ``q_{k+1} = q_k + v_k dt`` exactly, and a servo that
follows ``q_k + v_k (t - t_k)`` (the simulator's command extrapolation) tracks a
continuous reference. The response to a new setpoint therefore shows in the
velocity at once and in the position one tick later.

Deterministic, numpy and math only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_ik.core.projection import project_inertia
from splitter_ik.core.radial_kinematics import hip_pitch_speed_ratio_max, knee_from_radius
from splitter_ik.core.rate_limit import AxisLimits, limited_step
from splitter_ik.core.tether import (
    hemi_mass_kg,
    max_taut_radius_acceleration,
    reeling_tether_tension,
)
from splitter_model.actuators import TETHER_INDEX
from splitter_model.joints import LIMB_JOINTS, limb_joints
from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import RobotModel, principal_inertia, tether_tension_3d
from splitter_model.redundancy import RemainingShape, held_limb_command, mirror_limb_command
from splitter_msgs_py.core.parameter_fields import FRACTION, parameter_field

KNEE_Y_INDEX = 2  # hemi_a_y_pos_knee
KNEE_Z_INDEX = 8  # hemi_a_z_pos_knee
_PATH_SAMPLES = 17  # points on the way to a reel-in target where the braking is checked
_PATH_FRACTIONS = np.linspace(0.0, 1.0, _PATH_SAMPLES)  # 0: the target, 1: the tether now
_PATH_FRACTIONS.flags.writeable = False
_RATE_LIMIT_TOLERANCE = 1e-12  # [m, rad] drive-coordinate gap counted as "rate limited"


@dataclass(frozen=True)
class AllocatorConfig:
    """Allocator settings (validated on construction); every field is a node parameter."""

    control_period_s: float = parameter_field(  # [s] one command per control tick (100 Hz)
        0.01,
        "control tick: one command per setpoint, joint velocities over this period [s]",
        bounds=(1e-4, 10.0),
    )
    # [N] least tether tension kept while reeling; 1 N keeps a light tether straight
    # and is 4 % of the tension of the paper's spin (9 kg * 2.8 m * 1 rad^2/s^2).
    tension_margin_n: float = parameter_field(
        1.0,
        "least tether tension kept while reeling (the tether only pulls) [N]",
        bounds=(1e-6, 1e4),
        live=True,
    )
    # [-] share of the centripetal load kept as tension when that load is under the
    # margin (a slow spin across the tether): the requirement is then
    # ``min(tension_margin_n, fraction * M_h r_x w_perp^2)``, still taut. A reel-in
    # only adds tension (inward acceleration, then a faster spin), so a slow spin may
    # be reeled in, which is how its rate is raised. With the margin alone the tether
    # was held whenever M_h r_x w_perp^2 < 1 N (|H| < ~28 kg m^2/s at r_x = 2.8 m).
    low_spin_tension_fraction: float = parameter_field(
        0.5,
        "share of the centripetal tether load kept as tension when the load is under "
        "tension_margin_n (slow spin across the tether) [-]",
        bounds=FRACTION,
        live=True,
    )
    # [s] the reel follows the setpoint's mean velocity over this window (one re-plan
    # period: a new plan restarts from the measured radii) and closes the gap on top
    # of it; 0: every setpoint is approached as if it were to rest there. A reel-in is
    # braked taut, so a plan that stops its reel-in faster than the spin allows is
    # overshot. With 0, a slow spin's reel-in crept at what could stop taut at the
    # next 10 ms setpoint (2.8 -> 1.55 m in 12 s where the MPC planned 2.5 s).
    reference_velocity_window_s: float = parameter_field(
        0.1,
        "the reel follows the setpoints' mean velocity over this window (one MPC re-plan "
        "period), braking taut; 0: each setpoint approached as a resting target [s]",
        bounds=(0.0, 10.0),
        live=True,
    )
    # [m/s^2] the taut-tether limits are free-fall physics: only the tether holds the
    # hemis together, so a reel-in a slow spin cannot brake taut must coast. A robot
    # whose feet are on the ground (or pushing) is held by them too, and its
    # accelerometer says so: in free fall the specific force at the COM is zero (the
    # tether is internal), standing it is g (1.62 m/s^2 on the Moon). Above this the
    # reel brakes at the actuator's limits. With the free-fall rule on the ground a
    # coasting reel-in took r_x from 2.87 to 2.30 m after a landing, the setpoint
    # constant at 2.93 m (draw 12 of `splitter campaign lunar_jumping --seed 0`).
    supported_specific_force_m_s2: float = parameter_field(
        0.5,
        "measured specific force above which the robot is held by more than its tether "
        "(feet on the ground, a push) [m/s^2]",
        bounds=(1e-3, 1e3),
        live=True,
    )
    # [s] one accelerometer cannot tell both hemis standing from one hemi touching down
    # while the other still flies on its tether, which a braked reel-in would have to
    # push: the limits are lifted only once the support has lasted this long. Lifted at
    # once, a touchdown with the tether 22 deg from level (draw 33 of the same campaign)
    # braked the reel under the flying hemi, rolled the robot at 0.68 rad/s (0.15 with
    # the dwell) and hit 347 N (190 N with it). Lift-off restores them at once.
    supported_dwell_s: float = parameter_field(
        0.5,
        "the support must last this long before the free-fall taut-tether limits on the "
        "reel are lifted (and no tension is reported); lift-off restores them at once [s]",
        bounds=(0.0, 60.0),
        live=True,
    )
    speed_fraction: float = parameter_field(  # [-] share of the joint and reel speed limits
        1.0,
        "share of the actuator speed limits (800 RPM joints, tether reel) used [-]",
        bounds=FRACTION,
    )
    # Shares of the acceleration limits commanded, (0, 1]. The limits are the actuators'
    # (143 rad/s^2: peak torque with no load; 5 m/s^2 reel start-up); a servo that
    # follows the reference needs headroom. Measured with the simulator's servos in the
    # spin_stabilization set-up (setpoint steps, test_allocator_with_simulator.py):
    # limbs at 1.0 / 0.5 / 0.25: hip-knee mismatch up to 234 / 1.3 / 0.5 mrad, least
    # tether tension -61 / -3.4 N (slack) / +38.6 N; tether at 1.0 / 0.9: the reel
    # overshoots a stop by 59 / 0.5 mm.
    limb_acceleration_fraction: float = parameter_field(
        0.25,
        "share of the joint acceleration limit (143 rad/s^2) commanded; the rest is servo "
        "headroom that keeps hip and knee in step [-]",
        bounds=FRACTION,
    )
    tether_acceleration_fraction: float = parameter_field(
        0.9, "share of the reel start-up acceleration limit (5 m/s^2) used [-]", bounds=FRACTION
    )
    # The live ones are read on every tick; the speed and acceleration shares size the
    # limiters when the allocator is built (read-only).

    def __post_init__(self) -> None:
        for name in ("control_period_s", "tension_margin_n", "supported_specific_force_m_s2"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ValueError(f"AllocatorConfig.{name} must be finite and > 0, got {value!r}")
        for name in ("reference_velocity_window_s", "supported_dwell_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"AllocatorConfig.{name} must be finite and >= 0, got {value!r}")
        for name in (
            "low_spin_tension_fraction",
            "speed_fraction",
            "limb_acceleration_fraction",
            "tether_acceleration_fraction",
        ):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0.0 < value <= 1.0):
                raise ValueError(f"AllocatorConfig.{name} must be in (0, 1], got {value!r}")


@dataclass(frozen=True)
class Allocation:
    """Joint commands for one control tick and what limited them."""

    t_ns: int  # [ns] stamp of the setpoint answered
    joint_position: NDArray[np.float64]  # (25,) [rad, m] planned at t_ns, names.JOINT_NAMES order
    joint_velocity: NDArray[np.float64]  # (25,) [rad/s, m/s] held until t_ns + control period
    radii_m: NDArray[np.float64]  # (3,) (r_x, r_y, r_z) of joint_position [m]
    requested_inertia_kg_m2: NDArray[np.float64]  # (3,) the setpoint as received
    achieved_inertia_kg_m2: NDArray[np.float64]  # (3,) inertia of radii_m
    saturated: bool  # the setpoint was outside the reachable set (projected)
    rate_limited: bool  # limits keep the next planned radii short of the projected setpoint
    tension_n: float  # [N] tether tension at t_ns (planned reel acceleration); NaN without w
    required_tension_n: float  # [N] least tension kept this tick (AllocatorConfig); NaN without w
    tension_margin_n: float  # [N] tension_n - required_tension_n (< 0: requirement missed)
    supported: bool = False  # held by more than the tether: no taut limits, tension NaN


@dataclass(frozen=True)
class _State:
    t_ns: int | None
    drive: NDArray[np.float64]  # (L, knee_y, knee_z) [m, rad, rad]
    drive_rate: NDArray[np.float64]  # their rates
    joint_position: NDArray[np.float64]  # (25,)
    joint_rate: NDArray[np.float64] | None = None  # (25,) of the segment that led here


def _frozen(a: ArrayLike) -> NDArray[np.float64]:
    out = np.array(a, dtype=float)
    out.flags.writeable = False
    return out


class TetherLimbAllocator:
    """Turns principal-inertia setpoints into rate-limited joint commands, tick by tick.

    Without ``initial_radii_m`` the first allocation places the robot at the
    projected setpoint at rest; with them, it starts from rest at those radii.
    Allocating a stamp equal to the last one recomputes that tick from the state
    before it (a later setpoint for the same tick replaces the earlier answer);
    an earlier stamp raises ``ValueError``.
    """

    def __init__(
        self,
        model: RobotModel,
        config: AllocatorConfig = AllocatorConfig(),
        initial_radii_m: ArrayLike | None = None,
    ) -> None:
        self.model = model
        self.config = config
        ratio = max(1.0, hip_pitch_speed_ratio_max(model))
        knee_limits = AxisLimits(
            lower=model.knee_min_rad,
            upper=model.knee_max_rad,
            speed_max=model.joint_speed_max_rad_s / ratio * config.speed_fraction,
            acceleration_max=model.joint_acceleration_max_rad_s2
            / ratio
            * config.limb_acceleration_fraction,
        )
        self._limits = (
            AxisLimits(
                lower=model.tether_length_min_m,
                upper=model.tether_length_max_m,
                speed_max=model.tether_speed_max_m_s * config.speed_fraction,
                acceleration_max=model.tether_acceleration_max_m_s2
                * config.tether_acceleration_fraction,
            ),
            knee_limits,
            knee_limits,
        )
        self._speed = np.full(25, model.joint_speed_max_rad_s * config.speed_fraction)
        self._speed[TETHER_INDEX] = self._limits[0].speed_max
        limb_min = [-model.hip_abduction_limit_rad, -model.hip_pitch_limit_rad, model.knee_min_rad]
        limb_max = [model.hip_abduction_limit_rad, model.hip_pitch_limit_rad, model.knee_max_rad]
        self._q_min = np.array(limb_min * 8 + [model.tether_length_min_m])
        self._q_max = np.array(limb_max * 8 + [model.tether_length_max_m])
        self._state: _State | None = None
        self._previous: _State | None = None
        self._tether_targets: list[tuple[int, float]] = []  # (t_ns, L) setpoints in the window
        # After a fault (splitter_model.redundancy): what remains, where the joints are
        # (measured), and the joints the drive coordinates are read from.
        self._remaining: RemainingShape | None = None
        self._remaining_set = None
        self._measured_q = np.zeros(25)
        self._drive_index = [TETHER_INDEX, KNEE_Y_INDEX, KNEE_Z_INDEX]
        if initial_radii_m is not None:
            radii = np.asarray(initial_radii_m, dtype=float)
            if radii.shape != (3,) or not np.all(np.isfinite(radii)):
                raise ValueError(f"initial_radii_m must be 3 finite numbers, got {initial_radii_m}")
            lo, hi = model.radii_min_m, model.radii_max_m
            if np.any(radii < lo - 1e-12) or np.any(radii > hi + 1e-12):
                raise ValueError(
                    f"initial_radii_m {radii.tolist()} outside [{lo.tolist()}, {hi.tolist()}] m"
                )
            self._state = self._rest_state(None, np.clip(radii, lo, hi))

    # --- state -------------------------------------------------------------------
    def _drive_from_radii(self, radii: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array(
            [
                2.0 * radii[0],
                knee_from_radius(self.model, float(radii[1])),
                knee_from_radius(self.model, float(radii[2])),
            ]
        )

    def _rest_state(self, t_ns: int | None, radii: NDArray[np.float64]) -> _State:
        q = self._joint_positions(radii)
        drive = q[[TETHER_INDEX, KNEE_Y_INDEX, KNEE_Z_INDEX]].copy()
        return _State(t_ns=t_ns, drive=drive, drive_rate=np.zeros(3), joint_position=q)

    def _joint_positions(self, radii: NDArray[np.float64]) -> NDArray[np.float64]:
        """IK of the radii, clipped by the rounding of acos at the knee-range ends."""
        return np.clip(joint_positions_from_radii(self.model, radii), self._q_min, self._q_max)

    @property
    def radii_m(self) -> NDArray[np.float64] | None:
        """Radii planned for the next tick (or the initial radii), None before any."""
        if self._state is None:
            return None
        return self._radii_from_drive(self._state.drive)

    def _radii_from_drive(self, drive: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.array(
            [
                drive[0] / 2.0,
                self.model.limb_reach_m(float(drive[1])),
                self.model.limb_reach_m(float(drive[2])),
            ]
        )

    def reset(self, radii_m: ArrayLike | None = None) -> None:
        """Forget the history; restart from rest at ``radii_m`` (or at the next setpoint)."""
        fresh = TetherLimbAllocator(self.model, self.config, radii_m)
        self._state, self._previous = fresh._state, None
        self._tether_targets = []

    # --- faults ------------------------------------------------------------------
    def set_remaining(
        self, remaining: RemainingShape | None, measured_joint_position: ArrayLike
    ) -> None:
        """Re-plan with what a fault left (None: all healthy); call every tick after one.

        Held limbs are commanded where ``measured_joint_position`` (25) has them, their
        mirrors copy them (but for a z limb's limp hip pitch swing), the free limbs carry
        the rest of each radius; a locked reel holds the tether where it stopped
        (:mod:`splitter_model.redundancy`).
        """
        q = np.asarray(measured_joint_position, dtype=float)
        if q.shape != (25,) or not np.all(np.isfinite(q)):
            raise ValueError(
                f"measured joint positions must be 25 finite numbers, got {q.tolist()}"
            )
        if remaining is not None and remaining.roles.healthy:
            remaining = None
        changed = remaining != self._remaining
        self._remaining = remaining
        self._measured_q = q.copy()
        if not changed:
            return
        self._remaining_set = None if remaining is None else remaining.reachable(self.model)
        index = [TETHER_INDEX, KNEE_Y_INDEX, KNEE_Z_INDEX]
        if remaining is not None:
            for axis in (1, 2):
                free = remaining.roles.free_limbs(axis)
                if free:
                    index[axis] = limb_joints(free[0]).start + LIMB_JOINTS.index("knee")
        self._drive_index = index
        for state in (self._state, self._previous):  # read the drive from its new joints
            if state is None:
                continue
            state.drive[:] = state.joint_position[index]
            if remaining is not None and remaining.roles.reel_locked:
                state.drive[0] = remaining.tether_length_m
                state.drive_rate[0] = 0.0

    def _fault_target(self, requested: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
        """(drive target, saturated) of a setpoint in the reachable set that remains."""
        remaining, reachable = self._remaining, self._remaining_set
        assert remaining is not None and reachable is not None
        s = reachable.project(requested)
        saturated = not reachable.contains(requested)
        target = np.empty(3)
        target[0] = (
            2.0 * float(np.sqrt(s[0]))
            if remaining.tether_length_m is None
            else remaining.tether_length_m
        )
        state = self._state
        for axis in (1, 2):
            free = remaining.free_radius_m(axis, float(s[axis]))
            if free is None:  # no free limb: hold
                target[axis] = float(state.drive[axis]) if state is not None else 1.0
            else:
                lo, hi = self.model.limb_radius_min_m, self.model.limb_radius_max_m
                target[axis] = knee_from_radius(self.model, min(max(free, lo), hi))
        return target, saturated

    def _fault_joint_positions(self, drive: NDArray[np.float64]) -> NDArray[np.float64]:
        """The 25 joint positions of a drive after a fault: free limbs by IK, the others copied."""
        remaining = self._remaining
        assert remaining is not None
        reach = self.model.limb_reach_m
        radii = np.array([drive[0] / 2.0, reach(float(drive[1])), reach(float(drive[2]))])
        q = self._joint_positions(radii)
        q[TETHER_INDEX] = drive[0]
        measured = self._measured_q
        failed = remaining.failed_joints
        start = self._state
        before = start.joint_position if start is not None else measured
        rate = start.joint_rate if start is not None and start.joint_rate is not None else None
        for limb in remaining.roles.held:
            held = held_limb_command(
                self.model, limb, measured[limb_joints(limb)], remaining.moving_faults
            )
            q[limb_joints(limb)] = held
        for mirror, limb in remaining.roles.mirrors:
            q[limb_joints(mirror)] = mirror_limb_command(
                limb, q[limb_joints(limb)], before[limb_joints(mirror)], remaining.moving_faults
            )
        # towards their poses within the knees' speed and acceleration (as the free limbs
        # move), from the speed they had: a joint stopped at once would overshoot its stop
        dt, knee = self.config.control_period_s, self._limits[1]
        for limb in remaining.roles.copied:
            for j in range(limb_joints(limb).start, limb_joints(limb).stop):
                limits = AxisLimits(
                    self._q_min[j], self._q_max[j], knee.speed_max, knee.acceleration_max
                )
                v = 0.0 if rate is None else float(rate[j])
                q[j] = limited_step(float(before[j]), v, float(q[j]), dt, limits)[0]
        for joint in failed:  # what it is: its servo does not act
            if joint != TETHER_INDEX:
                q[joint] = measured[joint]
        return np.clip(q, self._q_min, self._q_max)

    def _effective_radii(self, drive: NDArray[np.float64]) -> NDArray[np.float64]:
        """(r_x, r_y, r_z) [m] of a drive, the y and z radii effective after a fault."""
        radii = self._radii_from_drive(drive)
        remaining = self._remaining
        if remaining is None:
            return radii
        for axis in (1, 2):
            radii[axis] = np.sqrt(remaining.radius_squared(axis, float(radii[axis])))
        return radii

    # --- the tick ----------------------------------------------------------------
    def allocate(
        self,
        t_ns: int,
        inertia_setpoint_kg_m2: ArrayLike,
        angular_velocity_rad_s: ArrayLike | None = None,
        setpoint_stamp_ns: int | None = None,
        *,
        supported: bool = False,
    ) -> Allocation:
        """Joint commands stamped ``t_ns`` answering the setpoint stamped ``setpoint_stamp_ns``.

        ``setpoint_stamp_ns`` (default ``t_ns``) places the setpoint in the history the
        reel's reference velocity is taken from: commands stamped ahead of their
        setpoint (real time, :mod:`.command_lead`), or several from one setpoint, see
        the setpoints' own velocity.

        ``angular_velocity_rad_s`` (body frame) enables the taut-tether limit and the
        tension report, both free-fall physics: ``supported`` (the robot is held by
        more than its tether, feet on the ground) lifts them. Raises ``ValueError`` for a
        non-finite setpoint or angular velocity, or a stamp earlier than the last one; the
        state is then unchanged.
        """
        t_ns = int(t_ns)
        requested = np.asarray(inertia_setpoint_kg_m2, dtype=float)
        projection = project_inertia(self.model, requested)  # validates the setpoint
        w = None
        if angular_velocity_rad_s is not None:
            w = np.asarray(angular_velocity_rad_s, dtype=float)
            if w.shape != (3,) or not np.all(np.isfinite(w)):
                raise ValueError(f"angular velocity must be 3 finite numbers, got {w.tolist()}")
        start = self._start_state(t_ns)
        saturated = projection.saturated
        if self._remaining is not None and start is not None:
            target, saturated = self._fault_target(requested)
        else:
            target = self._drive_from_radii(projection.radii_m)
        dt = self.config.control_period_s
        if start is None:  # first tick without initial radii: at the target, at rest
            state = self._rest_state(t_ns, projection.radii_m)
            here = state
            joint_velocity = np.zeros(25)
            rate_limited = False
            radius_x_prev, radius_x_accel = float(projection.radii_m[0]), 0.0
            reeling_in = False
        else:
            drive = np.empty(3)
            rate = np.empty(3)
            radius_x_prev = float(start.drive[0]) / 2.0
            taut_cap = taut_brake = math.inf
            lower_brake = None
            tether_velocity = self._tether_reference_velocity(
                t_ns if setpoint_stamp_ns is None else int(setpoint_stamp_ns), float(target[0])
            )
            # toward a shorter tether, or still moving in (braking is the same physics)
            reeling_in = bool(
                target[0] < start.drive[0] or start.drive_rate[0] < 0.0 or tether_velocity < 0.0
            )
            if w is not None and not supported:  # on the tether length L = 2 r_x
                margin = self.required_tension_n(w, radius_x_prev, reeling_in)
                taut_cap = 2.0 * max_taut_radius_acceleration(self.model, w, radius_x_prev, margin)
                taut_brake = self._reel_in_braking(start.drive, target, w, reeling_in)
                if reeling_in:  # a taut stop before the reel's end
                    end = target.copy()
                    end[0] = self._limits[0].lower
                    lower_brake = self._reel_in_braking(start.drive, end, w, reeling_in)
            for i in range(3):
                drive[i], rate[i] = limited_step(
                    float(start.drive[i]),
                    float(start.drive_rate[i]),
                    float(target[i]),
                    dt,
                    self._limits[i],
                    positive_acceleration_max=taut_cap if i == 0 else math.inf,
                    approach_braking_max=taut_brake if i == 0 else None,
                    target_velocity=tether_velocity if i == 0 else 0.0,
                    lower_braking_max=lower_brake if i == 0 else None,
                )
            if self._remaining is None:
                radii = self._radii_from_drive(drive)
                q = self._joint_positions(radii)
            else:
                q = self._fault_joint_positions(drive)
            drive = q[self._drive_index].copy()
            rate = (drive - start.drive) / dt
            here = start
            state = _State(
                t_ns=t_ns,
                drive=drive,
                drive_rate=rate,
                joint_position=q,
                joint_rate=(q - here.joint_position) / dt,
            )
            # (q_next - q) / dt, clipped by the rounding of x + v dt: consumers (the
            # simulator's servo) reject any command over the speed limit
            joint_velocity = np.clip((q - here.joint_position) / dt, -self._speed, self._speed)
            rate_limited = bool(np.any(np.abs(drive - target) > _RATE_LIMIT_TOLERANCE))
            radius_x_accel = float(rate[0] - start.drive_rate[0]) / (2.0 * dt)
        self._previous, self._state = start, state
        radii = self._effective_radii(here.drive)
        if w is None or supported:
            tension = required = math.nan
        else:
            tension = reeling_tether_tension(self.model, w, radius_x_prev, radius_x_accel)
            required = self.required_tension_n(w, radius_x_prev, reeling_in)
        return Allocation(
            t_ns=t_ns,
            joint_position=_frozen(here.joint_position),
            joint_velocity=_frozen(joint_velocity),
            radii_m=_frozen(radii),
            requested_inertia_kg_m2=_frozen(requested),
            achieved_inertia_kg_m2=_frozen(principal_inertia(self.model, radii)),
            saturated=saturated,
            rate_limited=rate_limited,
            tension_n=tension,
            required_tension_n=required,
            tension_margin_n=tension - required,
            supported=supported,
        )

    def required_tension_n(
        self, angular_velocity_rad_s: ArrayLike, radius_x_m: float, reeling_in: bool = False
    ) -> float:
        """Least tension [N] kept at this spin and tether half-length.

        The configured margin; on the way in, the configured share of the centripetal
        load ``M_h r_x w_perp^2`` when the spin across the tether is too slow for the
        margin (a reel-in raises the tension; paying out keeps the full margin).
        """
        if not reeling_in:
            return self.config.tension_margin_n
        steady = tether_tension_3d(self.model, angular_velocity_rad_s, radius_x_m)
        return min(self.config.tension_margin_n, self.config.low_spin_tension_fraction * steady)

    def _tether_reference_velocity(self, t_ns: int, length_m: float) -> float:
        """Mean velocity [m/s] of the tether-length setpoints over the configured window.

        ``length_m`` (the projected setpoint at ``t_ns``) joins the history; a repeated
        stamp replaces its entry. 0 without a window or an earlier setpoint in it.
        """
        window_ns = round(self.config.reference_velocity_window_s * 1e9)
        history = [(t, x) for t, x in self._tether_targets if t < t_ns and t >= t_ns - window_ns]
        history.append((t_ns, length_m))
        self._tether_targets = history
        t_first, x_first = history[0]
        if window_ns <= 0 or t_first >= t_ns:
            return 0.0
        speed_max = self._limits[0].speed_max
        velocity = (length_m - x_first) / ((t_ns - t_first) * 1e-9)
        return min(max(velocity, -speed_max), speed_max)

    def _reel_in_braking(
        self,
        drive: NDArray[np.float64],
        target: NDArray[np.float64],
        w: NDArray[np.float64],
        reeling_in: bool,
    ) -> float:
        """Constant deceleration [m/s^2 of L] equivalent to the taut braking left to the target.

        The taut bound on ``r_x''`` is sampled on the way from the target back to the
        tether's current length, with the spin predicted there from conserved angular
        momentum about each principal axis (``w_i I_i`` constant) and the tension
        required at that spin (:meth:`required_tension_n`). Where it is
        positive the tether may brake at it (capped by the reel); where it is not, it
        may only coast. Integrating ``d(v^2) = 2 a dL`` from rest at the target gives
        the highest reel-in speed from which the tether still stops taut; it is
        returned as the constant deceleration that gives the same speed.
        """
        distance = float(drive[0] - target[0])
        i_now = principal_inertia(self.model, self._radii_from_drive(drive))
        # every sample at once, with the scalar path's operations (same rounding)
        points = target + _PATH_FRACTIONS[:, None] * (drive - target)
        reach = self.model.limb_reach_m
        radii = np.empty((_PATH_SAMPLES, 3))
        radii[:, 0] = points[:, 0] / 2.0
        radii[:, 1] = [reach(knee) for knee in points[:, 1].tolist()]
        radii[:, 2] = [reach(knee) for knee in points[:, 2].tolist()]
        w_f = w * i_now / principal_inertia(self.model, radii)
        radius_x = radii[:, 0]
        w_perp2 = w_f[:, 1] ** 2 + w_f[:, 2] ** 2
        margin_n = np.full(_PATH_SAMPLES, self.config.tension_margin_n)
        if reeling_in:  # required_tension_n, sample by sample
            steady = self.model.hemi_mass_kg * radius_x * w_perp2
            margin_n = np.minimum(margin_n, self.config.low_spin_tension_fraction * steady)
        caps = (2.0 * (radius_x * w_perp2 - margin_n / self.model.hemi_mass_kg)).tolist()
        lengths = points[:, 0].tolist()
        if distance <= 0.0:
            return caps[-1]
        reel_max = self._limits[0].acceleration_max
        speed_squared = sum(
            2.0 * min(reel_max, max(0.0, min(caps[i], caps[i + 1]))) * (lengths[i + 1] - lengths[i])
            for i in range(len(caps) - 1)
        )
        return speed_squared / (2.0 * distance)

    def _start_state(self, t_ns: int) -> _State | None:
        """State the tick starts from (the one before the last tick if it is repeated)."""
        state = self._state
        if state is None or state.t_ns is None:
            return state
        if t_ns == state.t_ns:
            return self._previous
        if t_ns < state.t_ns:
            raise ValueError(f"stamp {t_ns} ns is earlier than the last allocation {state.t_ns} ns")
        return state

    @property
    def hemi_mass_kg(self) -> float:
        """Mass the tether holds on each side [kg]."""
        return hemi_mass_kg(self.model)
