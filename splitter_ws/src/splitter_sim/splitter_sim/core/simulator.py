"""The SPLITTER simulator: a morphing ten-mass rigid body with ground contact (ROS-free).

Paper section V and DESIGN.md section 3. One :class:`Simulator` owns the state
of the body (COM position and velocity, attitude, body angular momentum), the
25 actuators (joint / tether servos with rate and acceleration limits) and the
latest commands; :meth:`Simulator.step` advances by ``SimConfig.dt_s`` with
classical RK4 and :meth:`Simulator.state` returns a frozen :class:`SimState`.

Numerics (why the defaults are what they are):

* Flight: one RK4 step of 5 ms (the paper's). The joints move with constant
  acceleration within a step, so the shape (mass positions, inertia tensor,
  relative momentum) is evaluated exactly at every RK4 stage time.
* Contact: when a mass can reach the ground within the coming step, the step is
  split into ``contact_substeps`` RK4 sub-steps (default 2, i.e. 2.5 ms). The
  smallest effective mass behind one contact point is ~3 kg (a limb tip rolling
  the body about its thin x axis, Ixx / r^2). With the default contact (50 kN/m,
  1 kN s/m per mass, friction slope 1 kN s/m) that gives, per sub-step,
  ``omega h = 0.32``, ``c h / m = 0.83`` and ``c_t h / m = 0.83``, inside RK4's
  stability interval (2.78 on the negative real axis) with a factor 3 margin.
  Measured on the drop scenario of the tests: one 5 ms step with a 2 kN s/m
  friction slope limit-cycles at rest (``c_t h / m = 3.3``); two sub-steps settle
  to exact rest. An undamped drop bounces back to its height within 0.1%, so the
  contact neither creates nor loses energy numerically. Penetration at rest is
  M g / (n k): 18 kg on four feet under Earth gravity 0.88 mm, on the Moon 0.15 mm.

Speed: the servo, the shapes at the RK4 stage times and the RK4 (sub-)steps run
as compiled C (:mod:`.kernels`: the same formulas in the same order of operations
as the Python code here, which stays the reference and the fallback without a
compiler); the decisions between steps (contact candidates, thrust, legs,
sub-steps) and the outputs (:meth:`Simulator.state`) are Python.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.actuators import N_JOINTS, TETHER_INDEX, ActuatorLimits, actuator_limits
from splitter_model.faults import FAULT_CODES, LIMP, LOCKED, JointFault, faults_from_parameters
from splitter_model.joints import JOINT_NAMES, LIMB_JOINT_SLICE, N_LIMBS
from splitter_model.kinematics import joint_positions_from_radii, limb_joint_torques
from splitter_model.model import STANDARD_GRAVITY, RobotModel
from splitter_model.terrain import SLOPE_MAX_DEG, Terrain
from splitter_msgs_py.core.parameter_fields import parameter_field
from splitter_sim.core import actuators, kernels
from splitter_sim.core.contact import contact_reach_m, mass_heights_m
from splitter_sim.core.joint_faults import limp_joint_accelerations
from splitter_sim.core.legs import (
    LegImpedance,
    foot_hold_force,
    leg_compression_m,
    leg_stance_force,
    legs_face_ground,
    roll_load_share,
    slipped_anchor,
)
from splitter_sim.core.rigid_body import (
    DynamicsParameters,
    angular_velocity,
    rk4_step,
    rotation_matrix,
    state_derivative,
)
from splitter_sim.core.shape import HEMI_OF_MASS, Shape, ShapeKinematics

HEMI_BODY_INDEX = (0, 5)  # mass index of each hemi body (a, b)
# mass indices of each hemi's y limbs (y_pos, y_neg): its feet spread sideways under them
HEMI_FOOT_INDEX = ((1, 2), (6, 7))
HEMI_LABELS = ("a", "b")
ALL_MASSES = tuple(range(10))


# [N] The tension is computed from the accelerations of a hemi's five masses (9 kg). In
# free fall without spin, where it is zero (DESIGN.md section 3: nothing pulls the hemis
# apart), it scatters about 0 by up to 0.07 N (lunar_jumping's flights, measured): such
# a value is zero, not a tether pushing. Below this it counts as slack.
TETHER_SLACK_TOLERANCE_N = 0.1


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"SimConfig.{name} must be finite and > 0, got {value!r}")


def _non_negative(name: str, value: float) -> None:
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"SimConfig.{name} must be finite and >= 0, got {value!r}")


def _boolean(name: str, value: object) -> None:
    if not isinstance(value, bool):
        raise ValueError(f"SimConfig.{name} must be a bool, got {value!r}")


# [m] a hemi whose legs are within this of the crouch compression starts its push
CROUCH_TOLERANCE_M = 0.005
# [N/m] or [N s/m] the range of a leg stiffness and of a (contact or leg) damping
_GAIN_RANGE = (0.0, 1e6)
# What SimConfig's fields must be, besides the range of their node parameter (which a
# config built in code does not pass through).
_POSITIVE = ("dt_s", "contact_stiffness_n_m", "friction_damping_n_s_m", "leg_force_max_n")
_NON_NEGATIVE = (
    "gravity_m_s2",
    "contact_damping_n_s_m",
    "friction_coefficient",
    "thrust_stroke_m",
    "leg_stiffness_n_m",
    "leg_damping_n_s_m",
    "leg_tangential_damping_n_s_m",
    "leg_roll_stiffness_nm_rad",
    "leg_roll_damping_nm_s_rad",
    "leg_hold_stiffness_n_m",
    "leg_hold_damping_n_s_m",
    "leg_posture_stiffness_n_m",
    "leg_posture_damping_n_s_m",
    "leg_posture_mass_kg",
    "leg_ride_height_m",
    "leg_crouch_height_m",
    "command_extrapolation_s",
    "knot_blend_s",
)
_BOOLEAN = ("ground_contact", "compliant_legs", "leg_full_stroke_stop")


def _finite_force(value: ArrayLike, what: str) -> tuple[float, float, float]:
    """``value`` as a force (3 finite numbers); ValueError naming ``what`` otherwise."""
    f = np.array(value, dtype=float).reshape(-1)
    if f.shape != (3,) or not np.all(np.isfinite(f)):
        raise ValueError(f"{what} must be 3 finite numbers, got {value!r}")
    return float(f[0]), float(f[1]), float(f[2])


def _along(normal: tuple[float, float, float], x: float, y: float, z: float) -> float:
    """``normal . (x, y, z)``; on level ground exactly ``z``."""
    nx, ny, nz = normal
    if nx == 0.0 and ny == 0.0:
        return z
    return nx * x + ny * y + nz * z


@dataclass(frozen=True)
class SimConfig:
    """Integrator, gravity and contact settings; validated on construction.

    Contact defaults: stiffness and damping per lumped mass (a foot) give a
    critically damped contact on ~5 kg, about the effective mass behind a foot
    of this body; ``friction_coefficient`` 0.8 is regolith-like (lunar soil
    friction angles are 30-50 deg, tan = 0.6-1.2). ``friction_damping_n_s_m`` is the
    slope of the regularised Coulomb law below the cone (creep of 1 mm/s per
    newton of tangential load). ``thrust_stroke_m`` is the leg push-off stroke: a
    hemi pushes (jump thrust) while its lowest mass is within this height of the
    ground, the limb length the paper sizes the push-off with (section IV).
    """

    dt_s: float = parameter_field(0.005, "simulation step [s] (paper Table I)", bounds=(1e-4, 0.05))
    gravity_m_s2: float = 0.0  # [m/s^2] magnitude, along -z world (the node's ``gravity``)
    ground_contact: bool = parameter_field(True, "spring-damper ground (splitter_model.terrain)")
    # The ground (splitter_model.terrain.Terrain): level z = 0 by default.
    ground_slope_deg: float = parameter_field(
        0.0,
        "slope of the ground's base plane [deg] (splitter_model.terrain)",
        bounds=(0.0, SLOPE_MAX_DEG),
    )
    ground_slope_azimuth_deg: float = parameter_field(
        0.0,
        "direction in which the ground rises, from world x about world z [deg]",
        bounds=(-360.0, 360.0),
    )
    ground_steps_m: tuple[float, ...] = parameter_field(
        (),
        "steps on the ground, 5 values each: x_min, x_max, y_min, y_max, height [m] "
        "(boxes raised above the base plane)",
    )
    contact_stiffness_n_m: float = parameter_field(
        5.0e4, "ground stiffness per lumped mass [N/m]", bounds=(1.0, 1e8)
    )
    contact_damping_n_s_m: float = parameter_field(
        1.0e3, "ground damping per lumped mass [N s/m]", bounds=_GAIN_RANGE
    )
    friction_coefficient: float = parameter_field(
        0.8, "Coulomb friction coefficient mu [-]", bounds=(0.0, 10.0)
    )
    friction_damping_n_s_m: float = parameter_field(
        1.0e3, "slope of the regularised friction law below the cone [N s/m]", bounds=(1e-3, 1e6)
    )
    contact_substeps: int = parameter_field(
        2, "RK4 sub-steps per step while a mass can touch the ground [-]", bounds=(1, 100)
    )
    thrust_stroke_m: float = parameter_field(  # the paper's 0.4 m limb
        0.4,
        "push-off stroke: a hemi pushes while within this height of the ground [m]",
        bounds=(0.0, 10.0),
    )
    # Compliant legs (splitter_sim.core.legs): off, the lumped masses touch the ground directly.
    # The defaults: a lunar hemi (14.6 N) stands crouched, 4 cm up; 0.95 m/s down saturates
    # the force cap; the hip impedance holds the feet planted; the cap is below the limbs'
    # 196 N dynamic limit (paper VII.C).
    compliant_legs: bool = parameter_field(
        False, "stance legs under impedance control over the stroke (splitter_sim.core.legs)"
    )
    leg_stiffness_n_m: float = parameter_field(
        40.0, "stiffness of a hemi's legs in stance [N/m]", bounds=_GAIN_RANGE
    )
    leg_damping_n_s_m: float = parameter_field(
        200.0, "vertical damping of a hemi's legs in stance [N s/m]", bounds=_GAIN_RANGE
    )
    leg_tangential_damping_n_s_m: float = parameter_field(
        20.0, "horizontal damping of a hemi's planted legs in stance [N s/m]", bounds=_GAIN_RANGE
    )
    leg_force_max_n: float = parameter_field(
        190.0, "largest stance force of a hemi's legs (the limbs' limit) [N]", bounds=(1e-3, 1e5)
    )
    # splitter_sim.core.legs ("posture"): two hemis stand on two points of the tether axis,
    # which alone would leave the robot free to roll about it; the feet spread sideways
    # under the y limbs give the legs a roll moment. Per hemi, with the robot's I_xx of
    # 0.48 kg m^2 at the stance shape: 10 rad/s, critically damped.
    leg_roll_stiffness_nm_rad: float = parameter_field(
        24.0,
        "a hemi's legs level its body about the tether axis with this moment per radian of "
        "roll, shifting load between the left and right feet [N m/rad]",
        bounds=_GAIN_RANGE,
    )
    leg_roll_damping_nm_s_rad: float = parameter_field(
        4.8, "roll damping of a hemi's legs in stance [N m s/rad]", bounds=_GAIN_RANGE
    )
    # splitter_sim.core.legs (planted feet): a lunar hemi (14.6 N) on a 10 deg slope
    # leans 6 mm on this spring; 9 kg on it: 6.7 rad/s. 0: the hip damper alone.
    leg_hold_stiffness_n_m: float = parameter_field(
        400.0,
        "spring of a hemi's planted feet along the ground, from where they stand; they "
        "slip at the friction cone's edge [N/m]",
        bounds=_GAIN_RANGE,
    )
    leg_hold_damping_n_s_m: float = parameter_field(
        120.0,
        "damping of a hemi's planted feet along the ground (0.8 of critical on a lunar "
        "hemi's 15 kg and the hold spring) [N s/m]",
        bounds=_GAIN_RANGE,
    )
    # splitter_sim.core.legs ("Ride height"): the legs stand a hemi at the ride height, so
    # a limb tip clears a step in a slide; they crouch before a push. The posture holds
    # the nominal hemi (m_x + 2 m_y + 2 m_z = 9 kg: the leg controller's
    # model, not the simulated robot's masses): 300 N/m is 5.8 rad/s, 0.58 of critical.
    # Off by default (0; a scenario's leg_posture_stiffness_n_m turns it on): measured,
    # not yet the default (README "Ride height").
    leg_posture_stiffness_n_m: float = parameter_field(
        0.0,
        "stiffness of the legs' ride posture (a hemi stands at leg_ride_height_m, crouches "
        "to leg_crouch_height_m before a push); 0: no posture, the spring and damper "
        "alone [N/m]",
        bounds=_GAIN_RANGE,
    )
    leg_posture_damping_n_s_m: float = parameter_field(
        60.0, "damping of the legs' ride posture along the leg axis [N s/m]", bounds=_GAIN_RANGE
    )
    leg_posture_mass_kg: float = parameter_field(
        9.0, "the nominal hemi's mass the leg controller knows: the weight the ride "
        "posture holds, the mass the whole-stroke stop is computed for [kg]",
        bounds=(0.0, 1e3),
    )  # fmt: skip
    # splitter_sim.core.legs ("The whole stroke"): a fast touchdown also gets the force
    # that stops it at the end of the stroke: a 9 kg hemi from 3.95 m/s instead of 3.86.
    leg_full_stroke_stop: bool = parameter_field(
        True,
        "a hemi coming down also gets the force that stops it at the end of the stroke "
        "(m (g + v^2 / 2 d), the nominal hemi's mass), where that is stronger than the "
        "spring and damper",
    )
    leg_ride_height_m: float = parameter_field(
        0.2,
        "height of a standing hemi's lowest mass above the ground that the posture holds, "
        "within the stroke [m]",
        bounds=(0.0, 10.0),
    )
    leg_crouch_height_m: float = parameter_field(
        0.02,
        "height of a hemi's lowest mass above the ground to which its legs crouch before "
        "a push, which then starts from there [m]",
        bounds=(0.0, 10.0),
    )
    # splitter_sim.core.legs: a 0.4 m leg clears a 0.2 m half-wide body up to 90 - 30 deg.
    leg_cone_half_angle_deg: float = parameter_field(
        60.0,
        "workspace cone of the legs: largest angle between a hemi's belly normal (body +z) "
        "and the ground normal at which its legs reach the ground and push [deg]",
        bounds=(1.0, 89.0),
    )
    # Lockstep: a point every control period. Real time: long enough for a late point
    # (actuators.command_target).
    command_extrapolation_s: float = parameter_field(
        actuators.COMMAND_EXTRAPOLATION_S,
        "a joint command's velocity is followed this long past its stamp when no newer "
        "point arrives, then its position is held (real time: cover a late point) [s]",
        bounds=(0.0, 10.0),
    )
    # Real time: the servos then see a reference with continuous velocity.
    knot_blend_s: float = parameter_field(
        0.0,
        "a corner of the joint trajectory whose next point is queued ahead (real time) "
        "is rounded by a parabolic blend this long (0: off) [s]",
        bounds=(0.0, 1.0),
    )
    # Faults (splitter_model.faults): joint fault_joints[i] fails as fault_kinds[i] at
    # fault_times_s[i]. More can be injected while running (Simulator.inject_fault).
    fault_joints: tuple[str, ...] = parameter_field(
        (), "joints that fail (names of /splitter/joint_states)", item_type=str, choices=JOINT_NAMES
    )
    fault_kinds: tuple[str, ...] = parameter_field(
        (),
        "how each of fault_joints fails: locked or limp",
        item_type=str,
        choices=("locked", "limp"),
    )
    fault_times_s: tuple[float, ...] = parameter_field(
        (), "simulated time at which each of fault_joints fails [s]", bounds=(0.0, 1e6)
    )

    def __post_init__(self) -> None:
        for name in _POSITIVE:
            _positive(name, getattr(self, name))
        for name in _NON_NEGATIVE:
            _non_negative(name, getattr(self, name))
        for name in _BOOLEAN:
            _boolean(name, getattr(self, name))
        if self.dt_s > 0.1:
            raise ValueError(f"SimConfig.dt_s must be <= 0.1 s, got {self.dt_s!r}")
        for name in ("leg_ride_height_m", "leg_crouch_height_m"):
            if not (0.0 <= getattr(self, name) <= self.thrust_stroke_m):
                raise ValueError(
                    f"SimConfig.{name} must be in [0, thrust_stroke_m] = "
                    f"[0, {self.thrust_stroke_m}] m, got {getattr(self, name)!r}"
                )
        cone = self.leg_cone_half_angle_deg
        if not (isinstance(cone, (int, float)) and 1.0 <= cone <= 89.0):
            raise ValueError(
                f"SimConfig.leg_cone_half_angle_deg must be in [1, 89] deg, got {cone!r}"
            )
        try:  # the plane alone, then the steps alone: the error names its parameter
            Terrain(self.ground_slope_deg, self.ground_slope_azimuth_deg)
        except ValueError as exc:
            raise ValueError(f"SimConfig.ground_{exc}") from exc
        try:
            Terrain.from_parameters(0.0, 0.0, self.ground_steps_m)
        except ValueError as exc:
            text = str(exc).removeprefix("ground_steps_m: ")
            raise ValueError(f"SimConfig.ground_steps_m: {text}") from exc
        try:
            self.faults  # noqa: B018  (validates the three fault parameters together)
        except ValueError as exc:
            raise ValueError(f"SimConfig.{exc}") from exc
        if round(self.dt_s * 1e9) < 1:
            raise ValueError("SimConfig.dt_s must be at least 1 ns")
        if not (isinstance(self.contact_substeps, int) and 1 <= self.contact_substeps <= 100):
            raise ValueError(
                "SimConfig.contact_substeps must be an int in [1, 100], "
                f"got {self.contact_substeps!r}"
            )

    @property
    def terrain(self) -> Terrain:
        """The ground of ``ground_slope_deg``, ``ground_slope_azimuth_deg``, ``ground_steps_m``."""
        return Terrain.from_parameters(
            self.ground_slope_deg, self.ground_slope_azimuth_deg, self.ground_steps_m
        )

    @property
    def faults(self) -> tuple[JointFault, ...]:
        """The scheduled faults of ``fault_joints``, ``fault_kinds``, ``fault_times_s``."""
        return faults_from_parameters(self.fault_joints, self.fault_kinds, self.fault_times_s)

    @property
    def legs(self) -> LegImpedance:
        """The legs' impedance (used when ``compliant_legs``)."""
        return LegImpedance(
            stiffness_n_m=self.leg_stiffness_n_m,
            damping_n_s_m=self.leg_damping_n_s_m,
            tangential_damping_n_s_m=self.leg_tangential_damping_n_s_m,
            friction_coefficient=self.friction_coefficient,
            force_max_n=self.leg_force_max_n,
            cone_half_angle_deg=self.leg_cone_half_angle_deg,
            roll_stiffness_nm_rad=self.leg_roll_stiffness_nm_rad,
            roll_damping_nm_s_rad=self.leg_roll_damping_nm_s_rad,
            hold_stiffness_n_m=self.leg_hold_stiffness_n_m,
            hold_damping_n_s_m=self.leg_hold_damping_n_s_m,
            posture_stiffness_n_m=self.leg_posture_stiffness_n_m,
            posture_damping_n_s_m=self.leg_posture_damping_n_s_m,
            posture_weight_n=self.leg_posture_mass_kg * self.gravity_m_s2,
            ride_compression_m=self.thrust_stroke_m - self.leg_ride_height_m,
            crouch_compression_m=self.thrust_stroke_m - self.leg_crouch_height_m,
            stop_mass_kg=self.leg_posture_mass_kg if self.leg_full_stroke_stop else 0.0,
            stop_gravity_m_s2=self.gravity_m_s2,
            stroke_m=self.thrust_stroke_m,
        )

    @property
    def dt_ns(self) -> int:
        """Step length in integer nanoseconds."""
        return round(self.dt_s * 1e9)


def _vector(name: str, value: ArrayLike, size: int) -> NDArray[np.float64]:
    try:
        arr = np.array(value, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"InitialState.{name}: expected {size} numbers, got {value!r}") from exc
    if arr.shape != (size,):
        raise ValueError(f"InitialState.{name}: expected {size} numbers, got {arr.size}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"InitialState.{name} must be finite, got {arr}")
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True)
class InitialState:
    """Where the body starts; joints start at the radii's joint positions, at rest."""

    position_m: ArrayLike = (0.0, 0.0, 0.0)  # [m] world, centre of mass
    velocity_m_s: ArrayLike = (0.0, 0.0, 0.0)  # [m/s] world
    orientation_wxyz: ArrayLike = (1.0, 0.0, 0.0, 0.0)  # world <- base
    angular_velocity_rad_s: ArrayLike = (0.0, 0.0, 0.0)  # [rad/s] body
    radii_m: ArrayLike = (2.8, 0.2, 0.2)  # [m] r_x, r_y, r_z (paper Table I)

    def __post_init__(self) -> None:
        for name, size in (
            ("position_m", 3),
            ("velocity_m_s", 3),
            ("orientation_wxyz", 4),
            ("angular_velocity_rad_s", 3),
            ("radii_m", 3),
        ):
            object.__setattr__(self, name, _vector(name, getattr(self, name), size))
        q = np.asarray(self.orientation_wxyz)
        norm = float(np.linalg.norm(q))
        if abs(norm - 1.0) > 1e-6:
            raise ValueError(
                f"InitialState.orientation_wxyz must be a unit quaternion, |q| = {norm}"
            )
        object.__setattr__(self, "orientation_wxyz", _vector("orientation_wxyz", q / norm, 4))


@dataclass(frozen=True)
class SimState:
    """Frozen snapshot of the simulator at ``t_ns`` (arrays are read-only copies)."""

    t_ns: int
    position_m: NDArray[np.float64]  # (3,) world COM [m]
    velocity_m_s: NDArray[np.float64]  # (3,) world [m/s]
    orientation_wxyz: NDArray[np.float64]  # (4,) world <- base
    angular_velocity_rad_s: NDArray[np.float64]  # (3,) body [rad/s]
    linear_acceleration_m_s2: NDArray[np.float64]  # (3,) body specific force at the COM [m/s^2]
    inertia_tensor_kg_m2: NDArray[np.float64]  # (3, 3) body, about the COM [kg m^2]
    principal_inertia_kg_m2: NDArray[np.float64]  # (3,) diagonal of the tensor [kg m^2]
    joint_position: NDArray[np.float64]  # (25,) [rad] / tether [m]
    joint_velocity: NDArray[np.float64]  # (25,) [rad/s] / [m/s]
    joint_effort: NDArray[np.float64]  # (25,) limb torques [N m] (J^T F) / tether tension [N]
    radii_m: NDArray[np.float64]  # (3,) effective r_x, r_y, r_z [m]
    mass_positions_world_m: NDArray[np.float64]  # (10, 3) [m]
    hemi_acceleration_g: NDArray[np.float64]  # (2,) specific-force magnitude per hemi body [G]
    contact_force_n: NDArray[np.float64]  # (2, 3) ground on hemi, world [N]
    in_contact: NDArray[np.bool_]  # (2,)
    rotational_energy_j: float  # 1/2 w' I w [J] (the paper's)
    kinetic_energy_j: float  # total: COM + rotation + morphing motion [J]
    angular_momentum_world: NDArray[np.float64]  # (3,) about the COM [kg m^2/s]
    tether_tension_n: float  # [N] > 0 taut
    tether_slack: bool  # tension below -TETHER_SLACK_TOLERANCE_N: the tether would push
    actuator_power_w: float  # rate of actuator work on the system [W]
    # Extensions beyond the shared API:
    actuator_work_j: float = 0.0  # actuator work since t = 0 [J]
    contact_torque_n_m: NDArray[np.float64] = field(
        default_factory=lambda: np.zeros((2, 3))
    )  # (2, 3) ground on hemi about the hemi body, world [N m]
    thrust_force_n: NDArray[np.float64] = field(
        default_factory=lambda: np.zeros((2, 3))
    )  # (2, 3) jump thrust applied through each hemi body, world [N]
    leg_force_n: NDArray[np.float64] = field(
        default_factory=lambda: np.zeros((2, 3))
    )  # (2, 3) each hemi's legs on it (stance force and jump thrust), world [N]
    in_thrust_range: NDArray[np.bool_] = field(
        default_factory=lambda: np.zeros(2, dtype=bool)
    )  # (2,) hemi within the leg stroke of the ground
    kinetic_energy_about_com_j: float = 0.0  # rotation + morphing motion [J]
    joint_fault: NDArray[np.int8] = field(
        default_factory=lambda: np.zeros(N_JOINTS, dtype=np.int8)
    )  # (25,) ground truth: splitter_model.faults.FAULT_CODES per joint, 0 healthy

    def is_finite(self) -> bool:
        """Every number in the snapshot is finite."""
        # A finite sum of all the numbers has no NaN or infinity among them (either would
        # make it NaN or infinite); a sum that overflows is checked number by number.
        total = 0.0
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is checked below
            for name in _SIM_STATE_FIELDS:
                value = getattr(self, name)
                if isinstance(value, np.ndarray):
                    if value.dtype != bool:
                        total += float(value.sum())
                elif isinstance(value, float):
                    total += value
        return math.isfinite(total) or self._each_finite()

    def _each_finite(self) -> bool:
        for name in _SIM_STATE_FIELDS:
            value = getattr(self, name)
            if isinstance(value, np.ndarray) and value.dtype != bool:
                if not np.isfinite(value).all():
                    return False
            elif isinstance(value, float) and not math.isfinite(value):
                return False
        return True


_SIM_STATE_FIELDS = tuple(f.name for f in fields(SimState))


def _readonly(a: ArrayLike) -> NDArray:
    arr = np.array(a)
    arr.flags.writeable = False
    return arr


class Simulator:
    """Variable-inertia rigid-body simulator of SPLITTER with ground contact."""

    def __init__(
        self,
        model: RobotModel,
        config: SimConfig,
        initial: InitialState,
        *,
        gyroscopic_sign: float = -1.0,
        compiled: bool = True,
        hemi_inertia_kg_m2: Sequence[float] = (0.0, 0.0, 0.0),
    ) -> None:
        """Build the simulator; ``gyroscopic_sign = +1`` is a deliberate bug for tests only.

        ``compiled``: run the morphing hot path as compiled C (:mod:`.kernels`) when
        the library is cached or a compiler is available; False: pure Python.
        ``hemi_inertia_kg_m2``: each hemi body's own principal moments about its centre
        (base axes) [kg m^2], which the lumped-mass model (points) leaves out: a robot
        error (``RobotErrors.hemi_inertia_kg_m2``).
        """
        if gyroscopic_sign not in (-1.0, 1.0):
            raise ValueError("gyroscopic_sign must be -1 (physics) or +1 (deliberate error)")
        self.model = model
        self.config = config
        radii = np.asarray(initial.radii_m, dtype=float)
        lo, hi = model.radii_min_m, model.radii_max_m
        if np.any(radii < lo - 1e-12) or np.any(radii > hi + 1e-12):
            raise ValueError(
                f"InitialState.radii_m {radii.tolist()} outside the reachable range "
                f"[{lo.tolist()}, {hi.tolist()}]"
            )
        self._kin = ShapeKinematics(model, hemi_inertia_kg_m2)
        self._limits = actuator_limits(model)
        self._masses = np.array(self._kin.masses)
        self._q = joint_positions_from_radii(model, radii)
        self._q = np.clip(self._q, self._limits.position_min, self._limits.position_max)
        self._qd = np.zeros(N_JOINTS)
        self._qdd = np.zeros(N_JOINTS)
        self._cmd_q = self._q.copy()
        self._cmd_qd = np.zeros(N_JOINTS)
        self._cmd_t_ns = 0
        self._cmd_static = True  # the command has no velocity: the target is the command
        self._blend: actuators.LateCommandBlend | None = None  # a late point, blended in
        self._next_point: tuple[int, NDArray[np.float64]] | None = None  # (stamp, velocity)
        # velocity step of the rounded corner just passed
        self._corner_dv: NDArray[np.float64] | None = None
        self._settled = True  # joints at rest on a resting target: no servo work
        self._zero_joints = np.zeros(N_JOINTS)
        # Faults (splitter_model.faults): joints off their servo, the acceleration they have
        # instead (locked 0, limp from the dynamics), each joint's fault code (0 healthy).
        self._free = np.zeros(N_JOINTS, dtype=bool)
        self._free_qdd = np.zeros(N_JOINTS)
        self._fault_codes = np.zeros(N_JOINTS, dtype=np.int8)
        self._limp: list[int] = []
        self._pending_faults = sorted(config.faults, key=lambda f: (f.time_ns, f.joint_index))
        self._radii_cache: NDArray[np.float64] | None = None
        self._shape: Shape | None = self._kin.evaluate(self._q.tolist())
        self._shape_block: NDArray[np.float64] | None = None  # compiled shape, until needed
        w = np.asarray(initial.angular_velocity_rad_s, dtype=float)
        momentum = self._shape.inertia_matrix() @ w
        self._s = [
            *np.asarray(initial.position_m, dtype=float).tolist(),
            *np.asarray(initial.velocity_m_s, dtype=float).tolist(),
            *np.asarray(initial.orientation_wxyz, dtype=float).tolist(),
            *momentum.tolist(),
            0.0,
        ]
        self._prm = DynamicsParameters(
            total_mass=self._kin.total_mass,
            damping=model.damping_coefficient,
            gravity=config.gravity_m_s2,
            contact_stiffness=config.contact_stiffness_n_m,
            contact_damping=config.contact_damping_n_s_m,
            friction_coefficient=config.friction_coefficient,
            friction_damping=config.friction_damping_n_s_m,
            gyroscopic_sign=gyroscopic_sign,
        )
        self._jump_force = (0.0, 0.0, 0.0)
        self._jump_hemi: str = "auto"
        # Per-hemi thrusts (a, b) of a push by both hemis at once, else None.
        self._jump_per_hemi: tuple[tuple[float, float, float], ...] | None = None
        # With a ride posture, a commanded push waits until the hemi has crouched
        # (legs "Ride height"); once started it goes on until the command is zero.
        self._push_started = [False, False]
        self._crouching = (False, False)
        # A hemi that starts crouched (its legs compressed to the crouch: a robot placed
        # ready to push) holds the crouch until its first push: set at the first look.
        self._hold_crouch: list[bool] | None = None
        self._t_ns = 0
        self._dt_ns = config.dt_ns
        self._dt = self._dt_ns * 1e-9
        # Above this COM height minus body radius nothing touches nor pushes: skip checks.
        self._far_above_m = config.thrust_stroke_m + 1.0
        terrain = config.terrain
        self._terrain = terrain
        # [m] no mass is farther from the COM (the plane choice is skipped above it)
        self._reach_bound_m = math.hypot(model.radius_x_max_m, model.limb_radius_max_m)
        self._ground_normal = terrain.normal
        # world <- ground rotation of the legs' law on a slope (None: level)
        self._ground_frame = None if terrain.slope_deg == 0.0 else terrain.ground_frame()
        if not terrain.flat:  # a slope alone: one plane for every mass
            self._prm.ground_planes = [(*terrain.normal, 0.0)] * 10
        self._legs = config.legs
        # where each hemi's planted feet stuck (ground frame x, y [m]; None: not stuck)
        self._foot_anchor: list[tuple[float, float] | None] = [None, None]
        self.contact_step_count = 0  # steps integrated with contact sub-steps
        library = kernels.load_library() if compiled else None
        self._kernels = (
            None
            if library is None
            else kernels.Kernels(
                library,
                model,
                self._kin.masses,
                self._limits,
                self._prm,
                self._dt,
                self._kin.own_inertia,
            )
        )
        if self._kernels is not None:
            # The joint state, the accelerations the current shape was made with and
            # the rigid-body state live in the kernels' workspace (views, no copies).
            ws = self._kernels.ws
            self._shape = self._kernels.evaluate(self._q)  # (sets ws q, qd, qdd)
            self._q, self._qd = ws[kernels.WS_Q], ws[kernels.WS_QD]
            self._s[10:13] = (self._shape.inertia_matrix() @ w).tolist()
            ws[kernels.WS_STATE] = self._s
            ws[kernels.WS_TARGET] = self._cmd_q

    @property
    def compiled(self) -> bool:
        """True when the morphing hot path runs as compiled C (:mod:`.kernels`)."""
        return self._kernels is not None

    # --- construction ------------------------------------------------------------
    # --- commands ----------------------------------------------------------------
    @property
    def time_ns(self) -> int:
        """Simulated time [ns]."""
        return self._t_ns

    @property
    def joint_limits(self) -> ActuatorLimits:
        """Position, speed and acceleration limits of the 25 actuators."""
        return self._limits

    def command_joints(
        self,
        position: ArrayLike,
        velocity: ArrayLike | None = None,
        stamp_ns: int | None = None,
    ) -> None:
        """Set the joint targets (25, ``names.JOINT_NAMES`` order); ValueError when invalid.

        The command is a point of a trajectory: ``position`` at ``stamp_ns`` (default:
        now), moving at ``velocity``. The servo follows ``position + velocity (t -
        stamp)`` from the stamp on (:func:`.actuators.command_target`; past
        ``SimConfig.command_extrapolation_s`` the position is held). A command that
        arrives after its stamp is followed where its trajectory is now, and the
        offset from the trajectory the servos were on is blended out
        (:class:`.actuators.LateCommandBlend`). A stamp later than the simulated time
        is refused. An invalid command leaves the previous one in force.
        """
        from splitter_msgs_py.names import JOINT_NAMES

        stamp = self._t_ns if stamp_ns is None else int(stamp_ns)
        if stamp > self._t_ns:
            raise ValueError(
                f"joint command stamped {stamp} ns is later than the simulated time {self._t_ns} ns"
            )
        q, qd = actuators.validate_joint_command(self._limits, position, velocity, JOINT_NAMES)
        late_ns = self._t_ns - stamp
        if late_ns > 0:  # the servos are on the old trajectory: blend onto the new one
            old = self._servo_target()
            self._cmd_q, self._cmd_qd, self._cmd_t_ns = q, qd, stamp
            self._blend = None
            self._blend = actuators.LateCommandBlend.between(
                old, self._servo_target(), self._t_ns, late_ns
            )
        else:  # a point on time continues its plan: a blend in progress goes on fading
            nxt = self._next_point
            rounded = nxt is not None and nxt[0] == stamp and late_ns == 0
            self._corner_dv = qd - self._cmd_qd if rounded else None
            self._cmd_q, self._cmd_qd, self._cmd_t_ns = q, qd, stamp
        self._next_point = None
        self._settled = False
        self._cmd_static = not qd.any() and self._blend is None and self._corner_dv is None
        if self._kernels is not None and self._cmd_static:
            self._kernels.ws[kernels.WS_TARGET] = q
            self._kernels.ws[kernels.WS_TARGET_V] = 0.0

    # --- faults ------------------------------------------------------------------
    @property
    def fault_codes(self) -> NDArray[np.int8]:
        """Each joint's fault (``splitter_model.faults.FAULT_CODES``, 0 healthy), read-only."""
        return _readonly(self._fault_codes)

    def inject_fault(self, joint: str, kind: str) -> JointFault:
        """``joint`` fails as ``kind`` (locked, limp) now; ValueError if invalid or failed already.

        Locked: the joint stops at once and holds. Limp: it follows the dynamics with
        zero torque (:mod:`.joint_faults`) within its range.
        """
        fault = JointFault(joint, kind, self._t_ns * 1e-9)
        j = fault.joint_index
        if self._fault_codes[j]:
            raise ValueError(f"joint {joint!r} has failed already")
        self._fault_codes[j] = FAULT_CODES[kind]
        self._free[j] = True
        self._free_qdd[j] = 0.0
        if kind == LOCKED:
            self._qd[j] = 0.0
        elif kind == LIMP:
            self._limp.append(j)
        self._settled = False
        if self._kernels is not None:
            self._kernels.ws[kernels.WS_FREE] = self._free
            self._kernels.ws[kernels.WS_FREE_QDD] = self._free_qdd
        return fault

    def _apply_faults(self) -> None:
        """Inject the scheduled faults that are due, then the limp joints' accelerations."""
        pending = self._pending_faults
        while pending and pending[0].time_ns <= self._t_ns:
            fault = pending.pop(0)
            self.inject_fault(fault.joint, fault.kind)
        if not self._limp:
            return
        if self._kernels is not None:
            others = self._kernels.ws[kernels.WS_QDD]
        else:
            others = self._qdd
        if self._settled:
            others = self._zero_joints
        lim = self._limits
        moving = list(self._limp)
        while moving:  # a joint the dynamics press onto a stop rests there (the stop holds it)
            qdd = limp_joint_accelerations(
                self._kin,
                self._q.tolist(),
                self._qd.tolist(),
                others.tolist(),
                self._s[10:13],
                limp=moving,
                gyroscopic_sign=self._prm.gyroscopic_sign,
            )
            resting = [
                k
                for k, j in enumerate(moving)
                if self._qd[j] == 0.0
                and (
                    (self._q[j] >= lim.position_max[j] and qdd[k] > 0.0)
                    or (self._q[j] <= lim.position_min[j] and qdd[k] < 0.0)
                )
            ]
            if not resting:
                break
            for k in resting:
                self._free_qdd[moving[k]] = 0.0
            moving = [j for k, j in enumerate(moving) if k not in resting]
        if moving:
            self._free_qdd[moving] = qdd
        self._settled = False
        if self._kernels is not None:
            self._kernels.ws[kernels.WS_FREE_QDD] = self._free_qdd

    def command_jump_force(self, force_world_n: ArrayLike, hemi: str = "auto") -> None:
        """Jump thrust [N], world frame, pushed through ``hemi`` ("a", "b" or "auto").

        The force acts on the pushing hemi's body (so it also exerts a moment about
        the COM) while that hemi is within ``SimConfig.thrust_stroke_m`` of the
        ground; "auto": each hemi within reach pushes half (a hemi out of reach takes its
        half away, its legs cannot hand it to the other's). Zero = no thrust.
        """
        f = _finite_force(force_world_n, "jump force")
        if hemi not in ("a", "b", "auto"):
            raise ValueError(f"jump hemi must be 'a', 'b' or 'auto', got {hemi!r}")
        self._jump_force = f
        self._jump_hemi = hemi
        self._jump_per_hemi = None
        if f == (0.0, 0.0, 0.0):
            self._push_started = [False, False]

    def command_jump_forces(self, force_a_world_n: ArrayLike, force_b_world_n: ArrayLike) -> None:
        """Both hemis push at once, each its own thrust [N] (world frame).

        Each hemi's legs push its force on its body while they reach the ground
        (within the stroke and facing it); a hemi that leaves its stroke stops
        pushing, the other goes on with its own force.
        """
        fa = _finite_force(force_a_world_n, "jump force of hemi a")
        fb = _finite_force(force_b_world_n, "jump force of hemi b")
        self._jump_force = (fa[0] + fb[0], fa[1] + fb[1], fa[2] + fb[2])
        self._jump_hemi = "auto"
        self._jump_per_hemi = (fa, fb)
        if fa == (0.0, 0.0, 0.0) and fb == (0.0, 0.0, 0.0):
            self._push_started = [False, False]

    def preview_next_point(self, stamp_ns: int, velocity: ArrayLike) -> None:
        """The next joint command point, known ahead (stamped ``stamp_ns``, ``velocity``).

        With ``SimConfig.knot_blend_s`` > 0 the corner between the command in force and
        that point is rounded (:func:`.actuators.corner_blend`).
        """
        self._next_point = (int(stamp_ns), np.asarray(velocity, dtype=float))
        if self.config.knot_blend_s > 0.0:
            self._settled = False
            self._cmd_static = False

    def _servo_target(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Where the joint command's trajectory is now (position, velocity), any blend in."""
        age_s = (self._t_ns - self._cmd_t_ns) * 1e-9
        target = actuators.command_target(
            self._cmd_q, self._cmd_qd, age_s, self._limits, self.config.command_extrapolation_s
        )
        tau = self.config.knot_blend_s
        if tau > 0.0:
            target = self._rounded_corners(target, age_s, tau)
        blend = self._blend
        if blend is None:
            return target
        if not blend.active(self._t_ns):
            self._blend = None
            return target
        return blend.apply(self._t_ns, *target, self._limits)

    def _rounded_corners(
        self,
        target: tuple[NDArray[np.float64], NDArray[np.float64]],
        age_s: float,
        tau: float,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``target`` with the corners around now rounded by parabolic blends of ``tau``."""
        q, v = target
        half = 0.5 * tau
        if self._corner_dv is not None:  # just past a rounded corner
            if age_s < half:
                q, v = actuators.corner_blend(q, v, self._corner_dv, age_s - half, tau)
            else:
                self._corner_dv = None
        nxt = self._next_point
        if nxt is not None:
            before = (nxt[0] - self._t_ns) * 1e-9  # [s] to the next corner
            if 0.0 < before <= half:
                q, v = actuators.corner_blend(q, v, nxt[1] - self._cmd_qd, half - before, tau)
        lim = self._limits
        return np.clip(q, lim.position_min, lim.position_max), np.clip(
            v, -lim.speed_max, lim.speed_max
        )

    # --- integration -------------------------------------------------------------
    def _mass_heights(self, s: list[float], shape: Shape) -> list[float] | None:
        """World height of every mass [m], or None when all are far above the ground."""
        if self._far_above(s, shape.radius_max):
            return None
        shape.relative()
        return mass_heights_m(
            s[:3],
            rotation_matrix(s[6], s[7], s[8], s[9]),
            shape.rx,
            shape.ry,
            shape.rz,
            self._prm.ground_planes,
        )

    def _far_above(self, s: list[float], radius_m: float) -> bool:
        """Whether the body (``radius_m`` around the COM) is too far above the ground to
        touch it or push within the coming step."""
        terrain = self._terrain
        ground = 0.0 if terrain.flat else terrain.highest_within_m(s[0], s[1], radius_m)
        return s[2] - ground - radius_m > self._far_above_m

    def _update_ground_planes(self, s: list[float], shape: Shape) -> None:
        """The plane each mass touches at the start of the step (ground with steps).

        A mass keeps its plane through the step (the planes are the workspace of the
        compiled kernels): within one 5 ms step a mass moves a few centimetres.
        """
        if not self._terrain.steps or self._far_above(s, shape.radius_max):
            return
        shape.relative()
        r = rotation_matrix(s[6], s[7], s[8], s[9])
        points = [
            (
                s[0] + r[0] * x + r[1] * y + r[2] * z,
                s[1] + r[3] * x + r[4] * y + r[5] * z,
                s[2] + r[6] * x + r[7] * y + r[8] * z,
            )
            for x, y, z in zip(shape.rx, shape.ry, shape.rz, strict=True)
        ]
        planes = self._terrain.contact_planes(points)
        if planes != self._prm.ground_planes:
            self._prm.ground_planes = planes
            if self._kernels is not None:
                self._kernels.set_planes(planes)

    @staticmethod
    def _lowest_per_hemi(heights: list[float] | None) -> tuple[float, float]:
        if heights is None:
            return math.inf, math.inf
        return min(heights[:5]), min(heights[5:])

    def _thrust_terms(
        self, low: tuple[float, float], s: list[float], update: bool = True
    ) -> tuple[tuple[int, float, float, float], ...]:
        """The jump thrust on each pushing hemi body (world [N]).

        A hemi pushes while its lowest mass is within the stroke of the ground and its
        legs face the ground (their workspace cone, :mod:`.legs`), with compliant legs
        at most their force limit ``leg_force_max_n`` (a push asked beyond it is cut).
        Legs with a ride posture first crouch (:attr:`_crouching`, for
        :meth:`_leg_terms`): a hemi starts its push once its legs are compressed to
        the crouch (``update`` False, a snapshot, starts none).
        """
        fx, fy, fz = self._jump_force
        per_hemi = self._jump_per_hemi
        commanded = per_hemi is not None or fx != 0.0 or fy != 0.0 or fz != 0.0
        posture = self.config.compliant_legs and self._legs.posture_stiffness_n_m > 0.0
        if not commanded and (not posture or self._hold_crouch is not None):
            if posture:
                hold = self._hold_crouch
                self._crouching = (hold[0], hold[1])
            return ()
        stroke = self.config.thrust_stroke_m
        r = rotation_matrix(s[6], s[7], s[8], s[9])
        belly = _along(self._ground_normal, r[2], r[5], r[8])
        if posture:
            if self._hold_crouch is None:
                crouch = self._legs.crouch_compression_m - CROUCH_TOLERANCE_M
                self._hold_crouch = [
                    leg_compression_m(stroke, low[h], belly) >= crouch for h in (0, 1)
                ]
            hold = self._hold_crouch
            self._crouching = (hold[0], hold[1])
            if not commanded:
                return ()
        facing = legs_face_ground(belly, self._legs)
        reach = [facing and low[h] <= stroke for h in range(2)]
        if posture:
            reach = self._crouched_first(reach, low, belly, update)
        if per_hemi is not None:
            return tuple(
                (HEMI_BODY_INDEX[h], *self._within_leg_limit(per_hemi[h]))
                for h in range(2)
                if reach[h] and any(per_hemi[h])
            )
        if self._jump_hemi != "auto":
            hemi = HEMI_LABELS.index(self._jump_hemi)
            pushing = [hemi] if reach[hemi] else []
        else:
            pushing = [h for h in range(2) if reach[h]]
        if not pushing:
            return ()
        # "auto": each hemi's legs push half; one that leaves its stroke takes its half
        # away (legs cannot hand their force to the other hemi's legs).
        share = 0.5 if self._jump_hemi == "auto" else 1.0
        force = self._within_leg_limit((fx * share, fy * share, fz * share))
        return tuple((HEMI_BODY_INDEX[h], *force) for h in pushing)

    def _crouched_first(
        self, reach: list[bool], low: tuple[float, float], belly: float, update: bool
    ) -> list[bool]:
        """``reach`` without the hemis still crouching before their push (legs "Ride
        height"); sets :attr:`_crouching` and, with ``update``, starts the crouched (a
        hemi that started crouched then stands up after its push)."""
        crouch = self._legs.crouch_compression_m - CROUCH_TOLERANCE_M
        stroke = self.config.thrust_stroke_m
        started = self._push_started
        hold = self._hold_crouch
        crouching = list(self._crouching)
        for h in range(2):
            if not reach[h] or started[h]:
                continue
            if leg_compression_m(stroke, low[h], belly) >= crouch:
                if update:
                    started[h] = True
                    if hold is not None:
                        hold[h] = False
                crouching[h] = False
                continue
            crouching[h] = True
        self._crouching = (crouching[0], crouching[1])
        return [reach[h] and not crouching[h] for h in range(2)]

    def _within_leg_limit(
        self, force: tuple[float, float, float] | Sequence[float]
    ) -> tuple[float, float, float]:
        """A hemi's push [N], cut to the legs' force limit when the legs are modelled."""
        fx, fy, fz = (float(v) for v in force)
        if not self.config.compliant_legs:
            return fx, fy, fz
        norm = math.sqrt(fx * fx + fy * fy + fz * fz)
        cap = self.config.leg_force_max_n
        if norm <= cap:
            return fx, fy, fz
        return fx * cap / norm, fy * cap / norm, fz * cap / norm

    def _leg_terms(
        self,
        low: tuple[float, float],
        thrust: tuple[tuple[int, float, float, float], ...],
        s: list[float],
        shape: Shape,
        update: bool = True,
    ) -> tuple[tuple[int, float, float, float], ...]:
        """Stance forces of the compliant legs (world, on each hemi's y limbs) for this step.

        A hemi's legs act while its feet, a stroke along the leg axis from its lowest
        mass, reach the ground, its belly faces the ground (:func:`.legs.legs_face_ground`)
        and it is not pushing a jump (the thrust is then the legs' force). The force is
        shared between the hemi's left and right feet, under its y limbs, so that the
        legs level the body about the tether axis (:func:`.legs.roll_load_share`).
        The feet plant where the legs meet the ground and hold the hemi with a spring
        (:func:`.legs.foot_hold_force`); beyond the friction cone they slip, dragged
        behind the hemi (:func:`.legs.slipped_anchor`), until the legs leave the
        ground; ``update`` False (a snapshot) leaves where they stand unchanged. On a
        slope the law acts in the ground's frame.
        """
        if not self.config.compliant_legs:
            return ()
        anchors = self._foot_anchor
        stroke = self.config.thrust_stroke_m
        pushing = {index for index, *_ in thrust}
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation_matrix(s[6], s[7], s[8], s[9])
        normal = self._ground_normal
        belly = _along(normal, r02, r12, r22)  # cosine of the legs' tilt from the normal
        if not legs_face_ground(belly, self._legs):
            if update:
                anchors[0] = anchors[1] = None
            return ()
        frame = self._ground_frame
        legs = self._legs
        terms = []
        for h, body in enumerate(HEMI_BODY_INDEX):
            compression = leg_compression_m(stroke, low[h], belly)
            if compression <= 0.0 or body in pushing:
                if update:
                    anchors[h] = None
                continue
            wx, wy, wz = angular_velocity(shape, s[10], s[11], s[12])
            shape.relative()
            x, y, z = shape.rx[body], shape.ry[body], shape.rz[body]
            ux = wy * z - wz * y + shape.vx[body]
            uy = wz * x - wx * z + shape.vy[body]
            uz = wx * y - wy * x + shape.vz[body]
            velocity = (
                s[3] + r00 * ux + r01 * uy + r02 * uz,
                s[4] + r10 * ux + r11 * uy + r12 * uz,
                s[5] + r20 * ux + r21 * uy + r22 * uz,
            )
            where = (s[0] + r00 * x + r01 * y + r02 * z, s[1] + r10 * x + r11 * y + r12 * z)
            belly_up = (r02, r12, r22)
            if frame is not None:  # the law in the ground's frame (z along the normal)
                where_g = frame.T @ (where[0], where[1], s[2] + r20 * x + r21 * y + r22 * z)
                where = (float(where_g[0]), float(where_g[1]))
                velocity = tuple((frame.T @ velocity).tolist())
                belly_up = tuple((frame.T @ belly_up).tolist())
            anchor = anchors[h]
            if anchor is None and update and legs.hold_stiffness_n_m > 0.0:
                anchor = anchors[h] = where
            hold = (
                (0.0, 0.0)
                if anchor is None
                else foot_hold_force((where[0] - anchor[0], where[1] - anchor[1]), legs)
            )
            fx, fy, fz = leg_stance_force(
                compression, velocity, legs, belly_up, hold, crouch=self._crouching[h]
            )
            if fz <= 0.0:
                if update:
                    anchors[h] = None
                continue
            if update and anchor is not None:  # the feet slip at the cone's edge
                limit = min(
                    legs.friction_coefficient * fz,
                    math.sqrt(max(legs.force_max_n * legs.force_max_n - fz * fz, 0.0)),
                )
                anchors[h] = slipped_anchor(where, anchor, limit, legs)
            if frame is not None:
                fx, fy, fz = (frame @ (fx, fy, fz)).tolist()
            left, right = HEMI_FOOT_INDEX[h]
            share = roll_load_share(
                _along(normal, r01, r11, r21),
                wx,
                fx * r02 + fy * r12 + fz * r22,
                shape.ry[left] - y,
                legs,
            )
            terms.append((left, (0.5 + share) * fx, (0.5 + share) * fy, (0.5 + share) * fz))
            terms.append((right, (0.5 - share) * fx, (0.5 - share) * fy, (0.5 - share) * fz))
        return tuple(terms)

    def _contact_candidates(
        self, heights: list[float] | None, s: list[float], shape: Shape
    ) -> tuple[int, ...]:
        """Masses that can reach the ground within the coming step."""
        if heights is None or not self.config.ground_contact:
            return ()
        w = angular_velocity(shape, s[10], s[11], s[12])
        reach = contact_reach_m(
            s[3:6], w, shape.radius_max, shape.speed_max, self._dt, self.config.gravity_m_s2
        )
        return tuple(i for i, z in enumerate(heights) if z <= reach)

    def _current_shape(self) -> Shape:
        """The shape at the current time (made from the compiled kernels' output on first use)."""
        if self._shape is None:
            assert self._shape_block is not None
            self._shape = kernels.shape_from_block(self._shape_block.tolist())
        return self._shape

    def step(self) -> None:
        """Advance by one step ``dt``: actuators, then RK4 (sub-stepped near the ground)."""
        if self._pending_faults or self._limp:
            self._apply_faults()
        if self._kernels is not None:
            self._step_compiled()
            return
        lim = self._limits
        q, qd = self._q, self._qd
        if self._settled:
            qdd = self._zero_joints
            moving = False
        else:
            target, target_v = self._servo_target()
            qdd = actuators.servo_acceleration(q, qd, target, target_v, lim, self._dt)
            if self._free.any():
                qdd = np.where(self._free, self._free_qdd, qdd)
            moving = bool(qd.any() or qdd.any())
        s = self._s
        shape0 = self._current_shape()
        if moving:  # right-limit accelerations of the new step
            shape0 = self._kin.evaluate(q.tolist(), qd.tolist(), qdd.tolist())
        elif shape0.moving:  # the joints stopped: drop the last step's rates and accelerations
            shape0 = self._kin.evaluate(q.tolist())
            self._shape = shape0
        self._update_ground_planes(s, shape0)
        heights = self._mass_heights(s, shape0)
        prm = self._prm
        low = self._lowest_per_hemi(heights)
        thrust = self._thrust_terms(low, s)
        prm.thrust = thrust + self._leg_terms(low, thrust, s, shape0)
        prm.contact = self._contact_candidates(heights, s, shape0)
        n = self.config.contact_substeps if prm.contact else 1
        if prm.contact:
            self.contact_step_count += 1
        h = self._dt / n
        qdd_list = qdd.tolist() if moving else None
        for _ in range(n):
            if moving:
                q_mid, qd_mid = actuators.advance(q, qd, qdd, 0.5 * h)
                q, qd = actuators.advance(q, qd, qdd, h)
                shape_mid = self._kin.evaluate(q_mid.tolist(), qd_mid.tolist(), qdd_list)
                shape_end = self._kin.evaluate(q.tolist(), qd.tolist(), qdd_list)
            else:
                shape_mid = shape_end = shape0
            s = rk4_step(s, h, prm, shape0, shape_mid, shape_end)
            shape0 = shape_end
        if moving:
            clipped = np.clip(q, lim.position_min, lim.position_max)
            changed = not np.array_equal(clipped, q)
            free = self._free if self._free.any() else None
            if free is not None:  # a free joint stops at its range's end
                qd[free & (clipped != q)] = 0.0
            q = clipped
            changed |= actuators.snap_arrived(q, qd, target, target_v, free)
            if changed:
                shape0 = self._kin.evaluate(q.tolist(), qd.tolist(), qdd_list)
            self._settled = not qd.any() and not target_v.any() and bool(np.array_equal(q, target))
            self._radii_cache = None
        self._q, self._qd, self._qdd = q, qd, qdd
        self._s = s
        self._shape = shape0
        self._t_ns += self._dt_ns

    def _step_compiled(self) -> None:
        """:meth:`step` with the compiled kernels: the same decisions, the numerics in C.

        ``sim_begin`` gives the servo acceleration, the shape at the start and what
        the contact decisions need (mass heights, candidates: ``sim_ground`` for held
        joints); thrust and legs are decided here as in :meth:`step`; then one
        ``sim_flight`` / ``sim_step`` call per RK4 sub-step.
        """
        kern = self._kernels
        assert kern is not None
        ws = kern.ws
        moving = False
        begin = kern.out_begin
        if self._terrain.steps and not self._far_above(self._s, self._reach_bound_m):
            self._update_ground_planes(self._s, self._current_shape())
        if not self._settled:
            if not self._cmd_static:
                target, target_v = self._servo_target()
                ws[kernels.WS_TARGET] = target
                ws[kernels.WS_TARGET_V] = target_v
            kern.begin()
            moving = begin[kernels.BEGIN_MOVING] != 0.0
        s = self._s
        shape0: Shape | None
        if moving:
            ws[kernels.WS_QDD] = begin[kernels.BEGIN_QDD]
            shape0 = None
            ground = begin[kernels.BEGIN_GROUND :]
            radius = ground[kernels.GR_RADIUS]
        else:  # the shape stays that of the last step, at rest
            shape0 = self._current_shape()
            if shape0.moving:  # the joints stopped: drop the last step's rates and accelerations
                shape0 = kern.evaluate(self._q)
                self._shape = shape0
            ground = kern.out_ground
            radius = shape0.radius_max
        prm = self._prm
        if self._far_above(s, radius):  # no thrust, legs nor contact
            prm.thrust = prm.contact = ()
        else:  # the decisions of step(), on the heights and candidates computed in C
            if not moving:
                kern.ground()
            low = (float(ground[kernels.GR_LOW_A]), float(ground[kernels.GR_LOW_B]))
            thrust = self._thrust_terms(low, s)
            if self.config.compliant_legs:
                if shape0 is None:
                    shape0 = kernels.shape_from_block(begin[kernels.BEGIN_SHAPE :].tolist())
                thrust += self._leg_terms(low, thrust, s, shape0)
            prm.thrust = thrust
            prm.contact = (
                kernels.CANDIDATES[int(ground[kernels.GR_CANDIDATES])]
                if self.config.ground_contact
                else ()
            )
        ws[kernels.WS_JOINT_ADVANCE] = 1.0 if moving else 0.0
        if not prm.thrust and not prm.contact:
            ws[kernels.WS_H] = self._dt
            kern.flight()
        else:
            kern.set_forces(prm.thrust, prm.contact)
            n = self.config.contact_substeps if prm.contact else 1
            if prm.contact:
                self.contact_step_count += 1
            ws[kernels.WS_H] = self._dt / n
            kern.step()
            out = kern.out_step
            for _ in range(n - 1):
                ws[kernels.WS_STATE] = out[kernels.STEP_STATE]
                ws[kernels.WS_Q] = out[kernels.STEP_Q]
                ws[kernels.WS_QD] = out[kernels.STEP_QD]
                kern.step()
        out = kern.out_step
        ws[kernels.WS_STATE] = out[kernels.STEP_STATE]
        self._s = out[kernels.STEP_STATE].tolist()
        if moving:
            end = out[kernels.STEP_FINISH :]
            ws[kernels.WS_Q] = end[kernels.FIN_Q]
            ws[kernels.WS_QD] = end[kernels.FIN_QD]
            self._settled = bool(end[kernels.FIN_SETTLED])
            self._shape = None
            self._shape_block = end[kernels.FIN_SHAPE :].copy()
            self._radii_cache = None
        self._t_ns += self._dt_ns

    # --- outputs -----------------------------------------------------------------
    def state(self) -> SimState:
        """Snapshot of the current state and the derived quantities."""
        s = self._s
        shape = self._current_shape().relative()
        prm = self._prm
        low = self._lowest_per_hemi(self._mass_heights(s, shape))
        thrust = self._thrust_terms(low, s, update=False)
        legs = self._leg_terms(low, thrust, s, shape, update=False)
        saved = prm.contact, prm.thrust
        prm.contact = ALL_MASSES if self.config.ground_contact else ()
        prm.thrust = thrust + legs
        out: dict = {}
        try:
            state_derivative(s, shape, prm, out)
        finally:
            prm.contact, prm.thrust = saved
        rot = out["rotation"]
        w = out["angular_velocity"]
        w_dot = out["angular_acceleration"]
        a_com = out["acceleration_world"]
        g = self.config.gravity_m_s2
        masses = self._kin.masses
        # Ground and thrust forces on each mass, world frame.
        contact: dict[int, tuple[float, float, float]] = {
            c[0]: (c[1], c[2], c[3]) for c in out["contacts"] or ()
        }
        thrust_on: dict[int, tuple[float, float, float]] = {t[0]: t[1:] for t in thrust}
        # The legs' stance force and a jump's thrust are the ground's reaction on the legs,
        # applied at the hemi body: contact like that on the masses (thrust also apart).
        for i, *f in legs + thrust:
            contact[i] = _add(contact.get(i, _ZERO3), f)
        # Inertial acceleration (world) of each hemi body, and the tension from the radial
        # dynamics of hemi a: the rest pulls on its five masses with
        # F = sum (m a - m g - f_ext); the tether tension is T = -F . x_tether.
        acc_body = []
        pull = [0.0, 0.0, 0.0]
        tip_forces = np.zeros((N_LIMBS, 3))  # [N] each limb on its lumped mass, world
        for i in range(10):
            r = (shape.rx[i], shape.ry[i], shape.rz[i])
            dr = (shape.vx[i], shape.vy[i], shape.vz[i])
            ddr = (shape.ax[i], shape.ay[i], shape.az[i])
            rel = _add(
                _add(_cross(w_dot, r), _cross(w, _cross(w, r))),
                _add(_scale(2.0, _cross(w, dr)), ddr),
            )
            acc = _add(a_com, _rotate(rot, rel))
            if i in HEMI_BODY_INDEX:
                acc_body.append(acc)
            else:  # mass index i = limb + 1 + limb // 4 (shape.limb_constants)
                f = contact.get(i, _ZERO3)
                m = masses[i]
                tip_forces[i - 1 - i // 5] = (
                    m * acc[0] - f[0],
                    m * acc[1] - f[1],
                    m * (acc[2] + g) - f[2],
                )
            if i < 5:
                f = contact.get(i, _ZERO3)
                m = masses[i]
                pull[0] += m * acc[0] - f[0]
                pull[1] += m * acc[1] - f[1]
                pull[2] += m * (acc[2] + g) - f[2]
        tension = -(pull[0] * rot[0] + pull[1] * rot[3] + pull[2] * rot[6])
        hemi_g = [
            math.sqrt(a[0] * a[0] + a[1] * a[1] + (a[2] + g) ** 2) / STANDARD_GRAVITY
            for a in acc_body
        ]
        R = np.array(rot).reshape(3, 3)
        effort = np.empty(N_JOINTS)
        effort[LIMB_JOINT_SLICE] = limb_joint_torques(self.model, self._q, tip_forces @ R)
        effort[TETHER_INDEX] = tension
        position = np.array(s[0:3])
        world_positions = position + shape.positions() @ R.T
        contact_hemi = np.zeros((2, 3))
        torque_hemi = np.zeros((2, 3))
        for i, f in contact.items():
            hemi = HEMI_OF_MASS[i]
            contact_hemi[hemi] += f
            lever = world_positions[i] - world_positions[HEMI_BODY_INDEX[hemi]]
            torque_hemi[hemi] += _cross(tuple(lever.tolist()), f)
        thrust_hemi = np.zeros((2, 3))
        for i, f in thrust_on.items():
            thrust_hemi[HEMI_OF_MASS[i]] += f
        leg_hemi = np.zeros((2, 3))  # what each hemi's legs push with: stance and thrust
        for i, *f in legs + thrust:
            leg_hemi[HEMI_OF_MASS[i]] += f
        in_contact = np.array([any(HEMI_OF_MASS[i] == h for i in contact) for h in (0, 1)])
        inertia = shape.inertia_matrix()
        w_arr = np.array(w)
        velocity = np.array(s[3:6])
        e_rot = 0.5 * float(w_arr @ inertia @ w_arr)
        t_about = e_rot + float(w_arr @ np.array(shape.h)) + shape.kinetic_energy_relative
        kinetic = 0.5 * self._kin.total_mass * float(velocity @ velocity) + t_about
        specific_com = R.T @ np.array([a_com[0], a_com[1], a_com[2] + g])
        if self._radii_cache is None:
            self._radii_cache = self._radii(shape)
        return SimState(
            t_ns=self._t_ns,
            position_m=_readonly(position),
            velocity_m_s=_readonly(velocity),
            orientation_wxyz=_readonly(s[6:10]),
            angular_velocity_rad_s=_readonly(w_arr),
            linear_acceleration_m_s2=_readonly(specific_com),
            inertia_tensor_kg_m2=_readonly(inertia),
            principal_inertia_kg_m2=_readonly(np.diag(inertia).copy()),
            joint_position=_readonly(self._q),
            joint_velocity=_readonly(self._qd),
            joint_effort=_readonly(effort),
            radii_m=_readonly(self._radii_cache),
            mass_positions_world_m=_readonly(world_positions),
            hemi_acceleration_g=_readonly(hemi_g),
            contact_force_n=_readonly(contact_hemi),
            in_contact=_readonly(in_contact),
            rotational_energy_j=e_rot,
            kinetic_energy_j=kinetic,
            angular_momentum_world=_readonly(R @ np.array(s[10:13])),
            tether_tension_n=tension,
            tether_slack=tension < -TETHER_SLACK_TOLERANCE_N,
            actuator_power_w=float(out["actuator_power"]),
            actuator_work_j=float(s[13]),
            contact_torque_n_m=_readonly(torque_hemi),
            thrust_force_n=_readonly(thrust_hemi),
            leg_force_n=_readonly(leg_hemi),
            in_thrust_range=_readonly([low[h] <= self.config.thrust_stroke_m for h in (0, 1)]),
            kinetic_energy_about_com_j=t_about,
            joint_fault=_readonly(self._fault_codes),
        )

    def _radii(self, shape: Shape) -> NDArray[np.float64]:
        """(r_x, r_y, r_z) as ``kinematics.radii_from_joint_positions`` defines them.

        Half the tether, mean hip-to-tip distance of the y limbs and of the z limbs.
        """
        reach = []
        for i in range(10):
            if i in HEMI_BODY_INDEX:
                continue
            b = HEMI_BODY_INDEX[HEMI_OF_MASS[i]]
            reach.append(
                math.sqrt(
                    (shape.rx[i] - shape.rx[b]) ** 2
                    + (shape.ry[i] - shape.ry[b]) ** 2
                    + (shape.rz[i] - shape.rz[b]) ** 2
                )
            )
        r_y = (reach[0] + reach[1] + reach[4] + reach[5]) / 4.0
        r_z = (reach[2] + reach[3] + reach[6] + reach[7]) / 4.0
        return np.array([0.5 * float(self._q[TETHER_INDEX]), r_y, r_z])


_ZERO3 = (0.0, 0.0, 0.0)


def _cross(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _add(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def _scale(k: float, a: Sequence[float]) -> tuple[float, float, float]:
    return (k * a[0], k * a[1], k * a[2])


def _rotate(rot: Sequence[float], v: Sequence[float]) -> tuple[float, float, float]:
    return (
        rot[0] * v[0] + rot[1] * v[1] + rot[2] * v[2],
        rot[3] * v[0] + rot[4] * v[1] + rot[5] * v[2],
        rot[6] * v[0] + rot[7] * v[1] + rot[8] * v[2],
    )
