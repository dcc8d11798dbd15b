"""The one SPLITTER robot model: masses, geometry, principal inertia, radii and tension.

Used by the simulator, the MPC and the IK/tether allocator alike (paper section
III.B, DESIGN.md section 3). ROS-free and numpy-only.

Ten lumped masses. For hemi ``s`` in {+1 (a), -1 (b)}: body mass ``m_x`` at
``(s r_x, 0, 0)``; two limb masses ``m_y`` at ``(s r_x, +-r_y, 0)``; two limb masses
``m_z`` at ``(s r_x, 0, +-r_z)``. Frame ``base``: origin at the centre of mass, x
along the tether.

Hardware limits not given in the paper are derived here once, with the reasoning
beside each number, so every package uses the same ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

STANDARD_GRAVITY = 9.80665  # [m/s^2]
GRAVITY_PRESETS: dict[str, float] = {
    "zero": 0.0,  # [m/s^2]
    "moon": STANDARD_GRAVITY / 6.0,  # [m/s^2] the paper's "1/6 G"
    "mars": 3.72076,  # [m/s^2]
    "earth": STANDARD_GRAVITY,  # [m/s^2]
}

RPM_TO_RAD_S = 2.0 * math.pi / 60.0  # [rad/s per RPM]

# TBM2G-07613A frameless motor with a 10:1 gearbox (paper section VII.C).
MOTOR_OUTPUT_SPEED_RPM = 800.0  # [RPM] 8000 RPM / 10
MOTOR_OUTPUT_PEAK_TORQUE_NM = 34.3  # [Nm] 3.43 Nm x 10
MOTOR_OUTPUT_CONTINUOUS_TORQUE_NM = 12.3  # [Nm] 1.23 Nm x 10


class InfeasibleInertiaError(ValueError):
    """Principal moments that no real radii produce (a triangle inequality fails)."""


@dataclass(frozen=True)
class RobotModel:
    """Masses, limb and tether geometry and actuator limits of SPLITTER.

    Defaults are the paper's (Table I) where it gives them; the others are derived
    from the hardware as documented on each field.
    """

    body_mass_kg: float = 3.0  # m_x [kg]
    limb_mass_y_kg: float = 1.5  # m_y [kg]
    limb_mass_z_kg: float = 1.5  # m_z [kg]
    thigh_length_m: float = 0.2  # [m] half of the paper's 0.4 m limb
    shank_length_m: float = 0.2  # [m]
    # Knee range: fully stretched is a singularity, fully folded collides.
    knee_min_rad: float = 0.25  # [rad] keeps the stretched limb at 0.397 m
    knee_max_rad: float = 2.6  # [rad] folded limb reaches 0.107 m
    hip_abduction_limit_rad: float = math.pi / 2  # [rad] symmetric range +-
    hip_pitch_limit_rad: float = math.pi  # [rad] symmetric range +-
    # Tether: 6 m of tether on the spool, at least 1 m kept between the hemis so
    # their limbs never touch. Tether length = 2 r_x.
    tether_length_min_m: float = 1.0  # [m]
    tether_length_max_m: float = 6.0  # [m]
    # Joint speed: the actuator output speed, 800 RPM after the 10:1 gearbox.
    joint_speed_max_rad_s: float = MOTOR_OUTPUT_SPEED_RPM * RPM_TO_RAD_S  # [rad/s] 83.8
    # Joint acceleration: peak output torque over the limb-tip mass at full reach,
    # 34.3 Nm / (1.5 kg * 0.4 m^2) = 143 rad/s^2.
    joint_acceleration_max_rad_s2: float = 143.0  # [rad/s^2]
    # Tether reel: the same actuator on a 20 mm-radius spool,
    # 800 RPM * 2 pi / 60 * 0.02 m = 1.68 m/s.
    tether_spool_radius_m: float = 0.02  # [m]
    tether_acceleration_max_m_s2: float = 5.0  # [m/s^2] reel start-up, documented choice
    damping_coefficient: float = 0.001  # b [N s/m], paper Table I

    def __post_init__(self) -> None:
        for name in (
            "body_mass_kg",
            "limb_mass_y_kg",
            "limb_mass_z_kg",
            "thigh_length_m",
            "shank_length_m",
            "tether_length_min_m",
            "tether_length_max_m",
            "joint_speed_max_rad_s",
            "joint_acceleration_max_rad_s2",
            "tether_spool_radius_m",
            "tether_acceleration_max_m_s2",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"RobotModel.{name} must be finite and > 0, got {value}")
        if not 0.0 < self.knee_min_rad < self.knee_max_rad < math.pi:
            raise ValueError("RobotModel knee range must satisfy 0 < knee_min < knee_max < pi")
        if self.tether_length_min_m >= self.tether_length_max_m:
            raise ValueError("RobotModel.tether_length_min_m must be < tether_length_max_m")
        if self.damping_coefficient < 0.0:
            raise ValueError("RobotModel.damping_coefficient must be >= 0")

    # --- masses ------------------------------------------------------------------
    @property
    def total_mass_kg(self) -> float:
        """M = 2 (m_x + 2 m_y + 2 m_z) [kg]."""
        return 2.0 * (self.body_mass_kg + 2.0 * self.limb_mass_y_kg + 2.0 * self.limb_mass_z_kg)

    @property
    def hemi_mass_kg(self) -> float:
        """Mass of one Hemi-SPLITTER [kg]."""
        return self.total_mass_kg / 2.0

    @property
    def lumped_masses_kg(self) -> NDArray[np.float64]:
        """The ten masses in the order of :func:`lumped_mass_positions` [kg]."""
        hemi = [
            self.body_mass_kg,
            self.limb_mass_y_kg,
            self.limb_mass_y_kg,
            self.limb_mass_z_kg,
            self.limb_mass_z_kg,
        ]
        return np.array(hemi + hemi, dtype=float)

    # --- reach -------------------------------------------------------------------
    def limb_reach_m(self, knee_rad: float) -> float:
        """Hip-to-foot distance of a limb with the given knee angle [m]."""
        a, b = self.thigh_length_m, self.shank_length_m
        return math.sqrt(a * a + b * b + 2.0 * a * b * math.cos(knee_rad))

    @property
    def limb_radius_min_m(self) -> float:
        """Smallest reachable r_y, r_z: knee folded to its limit [m]."""
        return self.limb_reach_m(self.knee_max_rad)

    @property
    def limb_radius_max_m(self) -> float:
        """Largest reachable r_y, r_z: knee stretched to its limit [m]."""
        return self.limb_reach_m(self.knee_min_rad)

    @property
    def radius_x_min_m(self) -> float:
        """Smallest r_x (half the shortest tether) [m]."""
        return self.tether_length_min_m / 2.0

    @property
    def radius_x_max_m(self) -> float:
        """Largest r_x (half the longest tether) [m]."""
        return self.tether_length_max_m / 2.0

    @property
    def radii_min_m(self) -> NDArray[np.float64]:
        """Lower bounds of (r_x, r_y, r_z) [m]."""
        return np.array([self.radius_x_min_m, self.limb_radius_min_m, self.limb_radius_min_m])

    @property
    def radii_max_m(self) -> NDArray[np.float64]:
        """Upper bounds of (r_x, r_y, r_z) [m]."""
        return np.array([self.radius_x_max_m, self.limb_radius_max_m, self.limb_radius_max_m])

    @property
    def tether_speed_max_m_s(self) -> float:
        """Reel speed: actuator output speed times spool radius [m/s]."""
        return self.joint_speed_max_rad_s * self.tether_spool_radius_m


def with_masses(model: RobotModel, masses_kg: ArrayLike) -> RobotModel:
    """``model`` with other masses (m_x, m_y, m_z) [kg], the same geometry."""
    mx, my, mz = (float(v) for v in np.asarray(masses_kg, dtype=float).reshape(3))
    return replace(model, body_mass_kg=mx, limb_mass_y_kg=my, limb_mass_z_kg=mz)


def angular_velocity_after_morphing(
    angular_velocity_rad_s: ArrayLike,
    inertia_before_kg_m2: ArrayLike,
    inertia_after_kg_m2: ArrayLike,
) -> NDArray[np.float64]:
    """Body rate [rad/s] after a short change of principal inertia, momentum kept.

    In flight the angular momentum is conserved; over a short morph (tens of ms)
    each principal component ``w_i I_i`` nearly is (the gyroscopic coupling turns it
    by ``|w| dt``): ``w_i' = w_i I_i / I_i'``. Used to predict the rate a command
    stamped ahead of its input will meet.
    """
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    return (
        w
        * np.asarray(inertia_before_kg_m2, dtype=float)
        / np.asarray(inertia_after_kg_m2, dtype=float)
    )


def principal_inertia(model: RobotModel, radii_m: ArrayLike) -> NDArray[np.float64]:
    """(Ixx, Iyy, Izz) [kg m^2] of the symmetric ten-mass model, paper eq. (2).

    ``radii_m`` is (r_x, r_y, r_z) [m], or an array of shape (..., 3).
    """
    r = np.asarray(radii_m, dtype=float)
    rx, ry, rz = r[..., 0], r[..., 1], r[..., 2]
    mx, my, mz = model.body_mass_kg, model.limb_mass_y_kg, model.limb_mass_z_kg
    m_tether = 2.0 * mx + 4.0 * my + 4.0 * mz
    ixx = 4.0 * my * ry**2 + 4.0 * mz * rz**2
    iyy = m_tether * rx**2 + 4.0 * mz * rz**2
    izz = m_tether * rx**2 + 4.0 * my * ry**2
    moments = np.empty((*np.shape(ixx), 3))  # (np.stack's result, without its overhead)
    moments[..., 0] = ixx
    moments[..., 1] = iyy
    moments[..., 2] = izz
    return moments


def radii_from_inertia(model: RobotModel, inertia_kg_m2: ArrayLike) -> NDArray[np.float64]:
    """(r_x, r_y, r_z) [m] from principal inertia, the paper's closed form (eq. 3).

    Raises :class:`InfeasibleInertiaError` when a radicand is negative, i.e. the
    moments violate a triangle inequality of the ten-mass model. Use
    ``splitter_ik.core`` to project an infeasible request onto the reachable set.
    """
    inertia = np.asarray(inertia_kg_m2, dtype=float)
    if not np.all(np.isfinite(inertia)):
        raise InfeasibleInertiaError(f"inertia must be finite, got {inertia}")
    ixx, iyy, izz = inertia[..., 0], inertia[..., 1], inertia[..., 2]
    mx, my, mz = model.body_mass_kg, model.limb_mass_y_kg, model.limb_mass_z_kg
    radicands = np.stack(
        [
            (izz - ixx + iyy) / (4.0 * (mx + 2.0 * my + 2.0 * mz)),
            (ixx - iyy + izz) / (8.0 * my),
            (iyy - izz + ixx) / (8.0 * mz),
        ],
        axis=-1,
    )
    if np.any(radicands < 0.0):
        raise InfeasibleInertiaError(
            f"inertia {inertia} violates a triangle inequality (radicands {radicands})"
        )
    return np.sqrt(radicands)


def lumped_mass_positions(
    radii_m: ArrayLike,
    limb_offsets_m: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Positions (10, 3) [m] of the ten masses in the frame centred on the tether midpoint.

    Order per hemi (a then b): body, limb y_pos, limb y_neg, limb z_pos, limb z_neg.
    With ``limb_offsets_m`` (8, 3) the limb masses sit at hemi body + offset instead
    of on the principal axes (general, asymmetric configurations; order of
    ``splitter_model.joints.LIMB_NAMES``). The centre of mass is at the origin
    only for symmetric configurations: use :func:`inertia_tensor` for the general case.
    """
    rx, ry, rz = (float(v) for v in np.asarray(radii_m, dtype=float))
    if limb_offsets_m is None:
        offsets = np.array([[0.0, ry, 0.0], [0.0, -ry, 0.0], [0.0, 0.0, rz], [0.0, 0.0, -rz]] * 2)
    else:
        offsets = np.asarray(limb_offsets_m, dtype=float).reshape(8, 3)
    positions = np.zeros((10, 3))
    for h, sign in enumerate((1.0, -1.0)):
        body = np.array([sign * rx, 0.0, 0.0])
        positions[5 * h] = body
        positions[5 * h + 1 : 5 * h + 5] = body + offsets[4 * h : 4 * h + 4]
    return positions


def center_of_mass(masses_kg: ArrayLike, positions_m: ArrayLike) -> NDArray[np.float64]:
    """Mass-weighted mean position [m]."""
    m = np.asarray(masses_kg, dtype=float)
    p = np.asarray(positions_m, dtype=float)
    return (m[:, None] * p).sum(axis=0) / m.sum()


def inertia_tensor(masses_kg: ArrayLike, positions_m: ArrayLike) -> NDArray[np.float64]:
    """Full 3x3 inertia tensor [kg m^2] of point masses about their centre of mass.

    Products of inertia included: I = sum m (|r|^2 E - r r^T), r relative to the COM.
    """
    m = np.asarray(masses_kg, dtype=float)
    p = np.asarray(positions_m, dtype=float)
    r = p - center_of_mass(m, p)
    sq = np.einsum("i,ij,ij->", m, r, r)
    return sq * np.eye(3) - np.einsum("i,ij,ik->jk", m, r, r)


def rotational_energy(inertia: ArrayLike, angular_velocity_rad_s: ArrayLike) -> float:
    """E = 1/2 w' I w [J]; ``inertia`` is (3,) principal moments or a (3, 3) tensor."""
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    i = np.asarray(inertia, dtype=float)
    iw = i * w if i.ndim == 1 else i @ w
    return 0.5 * float(w @ iw)


def tether_tension(
    model: RobotModel,
    angular_velocity_y_rad_s: float,
    radius_x_m: float,
    gravity_m_s2: float = 0.0,
    dumbbell_angle_rad: float = 0.0,
) -> float:
    """Tether tension T = m_x w_y^2 r_x + m_x g sin(theta) [N], paper section III.

    The tether must stay taut (T > 0). ``dumbbell_angle_rad`` is the paper's
    theta, the dumbbell's angle in its 2D plane.
    """
    mx = model.body_mass_kg
    return mx * angular_velocity_y_rad_s**2 * radius_x_m + mx * gravity_m_s2 * math.sin(
        dumbbell_angle_rad
    )


def tether_tension_3d(
    model: RobotModel, angular_velocity_rad_s: ArrayLike, radius_x_m: float
) -> float:
    """Centripetal tether tension of a spinning SPLITTER in free fall, fixed radii [N].

    The tether holds a whole Hemi-SPLITTER (body and the four limbs mounted on
    it) on its circle about the x axis: M_hemi r_x (w_y^2 + w_z^2). The paper's
    ``tether_tension`` counts the body mass m_x only, a third of the load with the
    paper's masses; both are positive exactly when the robot spins about an axis
    across the tether, so the taut condition is the same. Gravity does not load
    the tether in free fall (both hemis fall together).
    """
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    return model.hemi_mass_kg * radius_x_m * float(w[1] ** 2 + w[2] ** 2)


def gravity_from_name(name_or_value: str | float) -> float:
    """Gravity magnitude [m/s^2] from a preset name (zero, moon, mars, earth) or a value."""
    if isinstance(name_or_value, str):
        key = name_or_value.strip().lower()
        if key in GRAVITY_PRESETS:
            return GRAVITY_PRESETS[key]
        try:
            value = float(key)
        except ValueError:
            raise ValueError(
                f"unknown gravity preset {name_or_value!r}; use one of "
                f"{sorted(GRAVITY_PRESETS)} or a number in m/s^2"
            ) from None
    else:
        value = float(name_or_value)
    if not (math.isfinite(value) and value >= 0.0):
        raise ValueError(f"gravity must be finite and >= 0 m/s^2, got {value}")
    return value


PAPER_INITIAL_RADII_M = np.array([2.8, 0.2, 0.2])  # [m] paper Table I
