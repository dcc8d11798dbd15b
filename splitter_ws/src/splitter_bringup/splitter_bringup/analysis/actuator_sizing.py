"""Actuator sizing for the lunar jump (paper sections IV.C and VII.C), every assumption named.

The paper prints its results (take-off 4.0 m/s, 21.7 m/s^2, 52.5 N per leg,
10.5 Nm per hip, 270.3 RPM; TBM2G-07613A 12.3 / 34.3 Nm and 800 RPM through 10:1;
payload 142 kg static and 20 kg dynamic) but not the intermediate assumptions.
This module rebuilds them from one consistent physical model:

* Each Hemi-SPLITTER is the paper's ten-mass model's hemi, ``m = m_x + 2 m_y + 2 m_z``
  = 9 kg (Table I masses; the text's "<= 10 kg" is the bound).
* Ballistic apex ``h`` on the Moon (1/6 G): ``v = sqrt(2 g h)``.
* Each leg is the model's two-link limb (thigh and shank 0.2 m: the 0.4 m limb).
  Its foot stays under the hip and the leg extends along the hip-foot line from a
  crouch to the take-off posture with constant acceleration; stroke
  ``s = L(k_takeoff) - L(k_crouch)``, ``L(k) = sqrt(l1^2 + l2^2 + 2 l1 l2 cos k)``,
  ``a = v^2 / (2 s)``.
* The four legs share the push: ``F = m (a + g) / 4``.
* Torque: the foot force acts along the hip-foot line, so its moment arm about the
  knee is the knee's distance from that line, ``l1 sin(beta)``, largest (``l1``)
  in the crouch. The paper's simplification ("mainly outputted by the larger hip
  actuator ... a four joint system") books it on the hip: ``tau = F l1 sin(beta_crouch)``.
* Speed: with the foot on the hip-foot line, ``dk/dt = v / |dL/dk|`` and the hip
  pitch turns ``dq2/dk`` as fast (-1/2 for equal links); the requirement is the
  take-off value, the fastest of the stroke.
* Gearbox: ideal (efficiency 1.0), ratio 10.
* Payload: the four legs hold (static, continuous torque) or jump with (dynamic,
  peak torque) ``4 tau / l1`` of foot force; payload = supported mass - robot mass.

The take-off knee angle is not in the paper. It is the one parameter read back
from the paper's numbers: 42 deg is where the hip speed comes out at 270.3 RPM, so
that row is a consistency check rather than an independent reproduction; a, F,
tau and the payloads then follow independently. See :func:`size_actuators` notes.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from splitter_ik.core.radial_kinematics import (
    hip_pitch_rate_per_knee_rate,
    radius_rate_per_knee_rate,
)
from splitter_model.model import RPM_TO_RAD_S, STANDARD_GRAVITY, RobotModel

RELATIVE_TOLERANCE = 0.03  # the acceptance: each number within 3 %

# Paper section IV.C / VII.C values, as printed.
PAPER_VALUES: dict[str, float] = {
    "takeoff_speed_m_s": 4.0,
    "takeoff_acceleration_m_s2": 21.7,
    "leg_force_n": 52.5,
    "hip_torque_nm": 10.5,
    "hip_speed_rpm": 270.3,
    "continuous_torque_nm": 12.3,
    "peak_torque_nm": 34.3,
    "output_speed_rpm": 800.0,
    "motor_mass_kg": 0.321,
    "static_payload_kg": 142.0,
    "dynamic_payload_kg": 20.0,
}


def limb_dynamic_force_limit_n(
    dynamic_payload_kg: float = PAPER_VALUES["dynamic_payload_kg"],
) -> float:
    """Largest dynamic ground force on one quadruped's limbs [N]: its dynamic payload's weight.

    The paper's limbs carry a 20 kg dynamic payload per quadruped (peak torque through
    the limb length, section VII.C): 20 kg x 9.81 m/s^2 = 196 N, the bound touchdowns
    are held to.
    """
    return dynamic_payload_kg * STANDARD_GRAVITY


@dataclass(frozen=True)
class MotorSpec:
    """A frameless BLDC motor with a gearbox (datasheet values, motor side)."""

    name: str = "TBM2G-07613A"
    continuous_torque_nm: float = 1.23  # [Nm] continuous stall torque
    peak_torque_nm: float = 3.43  # [Nm] peak stall torque
    max_speed_rpm: float = 8000.0  # [RPM]
    mass_kg: float = 0.321  # [kg]
    gear_ratio: float = 10.0  # [-]
    gear_efficiency: float = 1.0  # [-] ideal gearbox, as the paper's 1.23 -> 12.3 Nm implies


@dataclass(frozen=True)
class JumpAssumptions:
    """Every input of the sizing, with its unit. Defaults: the paper's set-up."""

    gravity_m_s2: float = STANDARD_GRAVITY / 6.0  # [m/s^2] the paper's 1/6 G
    apex_height_m: float = 5.0  # [m] lift-off to 5 m
    robot_mass_kg: float = field(default_factory=lambda: RobotModel().hemi_mass_kg)  # [kg] 9
    legs: int = 4  # [-] legs pushing together
    thigh_length_m: float = 0.2  # [m] half of the 0.4 m limb (RobotModel)
    shank_length_m: float = 0.2  # [m]
    crouch_knee_rad: float = math.pi  # [rad] leg folded flat: the whole 0.4 m is stroke
    takeoff_knee_rad: float = math.radians(42.0)  # [rad] inferred from the 270.3 RPM

    def __post_init__(self) -> None:
        for name in ("gravity_m_s2", "apex_height_m", "robot_mass_kg", "thigh_length_m",
                     "shank_length_m"):  # fmt: skip
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"JumpAssumptions.{name} must be finite and > 0, got {value}")
        if self.legs < 1:
            raise ValueError("JumpAssumptions.legs must be >= 1")
        if not 0.0 < self.takeoff_knee_rad < self.crouch_knee_rad <= math.pi:
            raise ValueError("JumpAssumptions: need 0 < takeoff_knee_rad < crouch_knee_rad <= pi")


@dataclass(frozen=True)
class Figure:
    """One computed number, beside the paper's when it prints one."""

    key: str
    label: str
    value: float
    unit: str
    formula: str
    paper: float | None = None

    @property
    def relative_error(self) -> float | None:
        """(value - paper) / paper, or None without a paper value."""
        return None if self.paper is None else (self.value - self.paper) / self.paper

    @property
    def within_tolerance(self) -> bool | None:
        """|relative error| <= 3 %, or None without a paper value."""
        err = self.relative_error
        return None if err is None else abs(err) <= RELATIVE_TOLERANCE


@dataclass(frozen=True)
class SizingReport:
    """All figures, the assumptions behind them and what could not be matched."""

    figures: tuple[Figure, ...]
    assumptions: dict[str, dict[str, object]]
    notes: tuple[str, ...]

    def figure(self, key: str) -> Figure:
        """The figure named ``key``."""
        for f in self.figures:
            if f.key == key:
                return f
        raise KeyError(key)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: figures with paper value and relative error, assumptions, notes."""
        return {
            "tolerance": RELATIVE_TOLERANCE,
            "figures": [
                {
                    "key": f.key,
                    "label": f.label,
                    "value": f.value,
                    "unit": f.unit,
                    "paper": f.paper,
                    "relative_error": f.relative_error,
                    "within_tolerance": f.within_tolerance,
                    "formula": f.formula,
                }
                for f in self.figures
            ],
            "assumptions": self.assumptions,
            "notes": list(self.notes),
        }


def leg_length_m(thigh_m: float, shank_m: float, knee_rad: float) -> float:
    """Hip-to-foot distance of a two-link leg [m] (0 = knee stretched convention)."""
    return math.sqrt(
        max(0.0, thigh_m**2 + shank_m**2 + 2.0 * thigh_m * shank_m * math.cos(knee_rad))
    )


def knee_moment_arm_m(thigh_m: float, shank_m: float, knee_rad: float) -> float:
    """Distance [m] of the knee from the hip-foot line: the moment arm of a foot force along it."""
    length = leg_length_m(thigh_m, shank_m, knee_rad)
    if length < 1e-12:  # folded flat (equal links): the thigh is perpendicular to the force
        return thigh_m
    # triangle hip-knee-foot: area = 1/2 l1 l2 sin(k) = 1/2 L * arm
    return thigh_m * shank_m * math.sin(knee_rad) / length


def takeoff_joint_speeds_rad_s(
    assumptions: JumpAssumptions, takeoff_speed_m_s: float
) -> tuple[float, float]:
    """(hip pitch, knee) speeds [rad/s] at take-off, foot on the hip-foot line."""
    model = RobotModel(
        thigh_length_m=assumptions.thigh_length_m, shank_length_m=assumptions.shank_length_m
    )
    knee = assumptions.takeoff_knee_rad
    knee_speed = takeoff_speed_m_s / abs(radius_rate_per_knee_rate(model, knee))
    hip_speed = abs(hip_pitch_rate_per_knee_rate(model, knee)) * knee_speed
    return hip_speed, knee_speed


def size_actuators(
    assumptions: JumpAssumptions | None = None, motor: MotorSpec | None = None
) -> SizingReport:
    """Requirements of the lunar jump and what the geared motor offers, against the paper."""
    a_ = assumptions or JumpAssumptions()
    motor = motor or MotorSpec()
    g, h, m, n = a_.gravity_m_s2, a_.apex_height_m, a_.robot_mass_kg, a_.legs
    l1, l2 = a_.thigh_length_m, a_.shank_length_m
    v = math.sqrt(2.0 * g * h)
    length_crouch = leg_length_m(l1, l2, a_.crouch_knee_rad)
    length_takeoff = leg_length_m(l1, l2, a_.takeoff_knee_rad)
    stroke = length_takeoff - length_crouch
    accel = v * v / (2.0 * stroke)
    force = m * (accel + g) / n
    arm = knee_moment_arm_m(l1, l2, a_.crouch_knee_rad)
    torque = force * arm
    hip_speed, knee_speed = takeoff_joint_speeds_rad_s(a_, v)
    rpm = 1.0 / RPM_TO_RAD_S
    eff, ratio = motor.gear_efficiency, motor.gear_ratio
    tau_cont = motor.continuous_torque_nm * ratio * eff
    tau_peak = motor.peak_torque_nm * ratio * eff
    out_speed = motor.max_speed_rpm / ratio
    static_payload = n * tau_cont / (arm * g) - m
    dynamic_payload = n * tau_peak / (arm * (accel + g)) - m
    figs = (
        Figure("takeoff_speed_m_s", "take-off speed", v, "m/s", "v = sqrt(2 g h)",
               PAPER_VALUES["takeoff_speed_m_s"]),
        Figure("stroke_m", "push-off stroke", stroke, "m",
               "s = L(k_takeoff) - L(k_crouch)"),
        Figure("takeoff_acceleration_m_s2", "take-off acceleration", accel, "m/s^2",
               "a = v^2 / (2 s)", PAPER_VALUES["takeoff_acceleration_m_s2"]),
        Figure("leg_force_n", "force per leg", force, "N", "F = m (a + g) / legs",
               PAPER_VALUES["leg_force_n"]),
        Figure("hip_torque_nm", "torque per hip", torque, "Nm",
               "tau = F * l1 sin(beta_crouch)", PAPER_VALUES["hip_torque_nm"]),
        Figure("hip_speed_rpm", "hip speed at take-off", hip_speed * rpm, "RPM",
               "w_hip = |dq2/dk| v / |dL/dk| at k_takeoff", PAPER_VALUES["hip_speed_rpm"]),
        Figure("knee_speed_rpm", "knee speed at take-off (not in the paper)", knee_speed * rpm,
               "RPM", "w_knee = v / |dL/dk| at k_takeoff"),
        Figure("continuous_torque_nm", "continuous output torque", tau_cont, "Nm",
               "tau_cont * ratio * efficiency", PAPER_VALUES["continuous_torque_nm"]),
        Figure("peak_torque_nm", "peak output torque", tau_peak, "Nm",
               "tau_peak * ratio * efficiency", PAPER_VALUES["peak_torque_nm"]),
        Figure("output_speed_rpm", "output speed", out_speed, "RPM", "motor speed / ratio",
               PAPER_VALUES["output_speed_rpm"]),
        Figure("motor_mass_kg", "motor mass", motor.mass_kg, "kg", "datasheet",
               PAPER_VALUES["motor_mass_kg"]),
        Figure("peak_torque_margin", "peak output torque / hip torque", tau_peak / torque, "-",
               "tau_peak_out / tau"),
        Figure("speed_margin", "output speed / hip speed", out_speed / (hip_speed * rpm), "-",
               "w_out / w_hip"),
        Figure("static_payload_kg", "static payload", static_payload, "kg",
               "legs * tau_cont_out / (l1 g) - m", PAPER_VALUES["static_payload_kg"]),
        Figure("dynamic_payload_kg", "dynamic payload (same jump)", dynamic_payload, "kg",
               "legs * tau_peak_out / (l1 (a + g)) - m", PAPER_VALUES["dynamic_payload_kg"]),
        Figure("limb_force_limit_n", "limbs' dynamic force limit (touchdowns)",
               limb_dynamic_force_limit_n(), "N", "paper's 20 kg dynamic payload x 9.81 m/s^2"),
    )  # fmt: skip
    assumptions_out: dict[str, dict[str, object]] = {
        "gravity_m_s2": {"value": g, "unit": "m/s^2", "why": "paper: 1/6 G (9.80665 / 6)"},
        "apex_height_m": {"value": h, "unit": "m", "why": "paper: lift-off to 5 m"},
        "robot_mass_kg": {
            "value": m,
            "unit": "kg",
            "why": "hemi of the paper's ten-mass model, m_x + 2 m_y + 2 m_z (Table I); "
            "within the text's <= 10 kg",
        },
        "legs": {"value": n, "unit": "-", "why": "paper: force distributed across four legs"},
        "thigh_length_m": {"value": l1, "unit": "m", "why": "half of the paper's 0.4 m limb"},
        "shank_length_m": {"value": l2, "unit": "m", "why": "half of the paper's 0.4 m limb"},
        "crouch_knee_deg": {
            "value": math.degrees(a_.crouch_knee_rad),
            "unit": "deg",
            "why": "leg folded flat: the stroke uses the whole 0.4 m limb",
        },
        "takeoff_knee_deg": {
            "value": math.degrees(a_.takeoff_knee_rad),
            "unit": "deg",
            "why": "not in the paper; the take-off posture at which the hip speed is the "
            "paper's 270.3 RPM (41.8 deg), rounded",
        },
        "push_profile": {
            "value": "constant acceleration",
            "unit": "-",
            "why": "a = v^2 / (2 s) over the stroke",
        },
        "foot_force_line": {
            "value": "hip-foot line, vertical",
            "unit": "-",
            "why": "foot under the hip; largest moment arm l1 in the crouch, booked on the "
            "hip as the paper's four-joint simplification does",
        },
        "gear": {
            "value": f"{ratio:g}:1, efficiency {eff:g}",
            "unit": "-",
            "why": "paper: 1.23 Nm -> 12.3 Nm implies an ideal gearbox",
        },
        "payload": {
            "value": "legs * tau_out / l1 of foot force",
            "unit": "-",
            "why": "static: holds payload + robot against lunar g on continuous torque; "
            "dynamic: the same jump (a + g) on peak torque",
        },
    }
    full_stroke = leg_length_m(l1, l2, 0.0) - length_crouch
    a_full = v * v / (2.0 * full_stroke)
    model = RobotModel()
    fold = leg_length_m(l1, l2, model.knee_max_rad)
    a_model = v * v / (2.0 * (length_takeoff - fold))
    notes = (
        f"take-off speed: sqrt(2 g h) = {v:.3f} m/s; the paper prints 4.0 (rounded).",
        f"hip speed is matched by the one inferred assumption (take-off knee angle): a "
        f"consistency check, not an independent reproduction. It is steep: 40 deg gives "
        f"{_hip_rpm(a_, v, 40.0):.1f} RPM, 45 deg {_hip_rpm(a_, v, 45.0):.1f} RPM.",
        f"a stroke of the full stretched limb (0.4 m, take-off at the singular straight knee) "
        f"would give a = {a_full:.2f} m/s^2 ({(a_full / 21.7 - 1) * 100:+.1f} %), outside 3 %, "
        f"and an unbounded joint speed; the paper's 21.7 m/s^2 implies a stroke of "
        f"{v * v / (2 * 21.7):.4f} m.",
        f"the simulator's knee range ({math.degrees(model.knee_min_rad):.0f}-"
        f"{math.degrees(model.knee_max_rad):.0f} deg) does not fold flat: from its deepest crouch "
        f"the stroke is {length_takeoff - fold:.3f} m and a = {a_model:.1f} m/s^2, "
        f"F = {m * (a_model + g) / n:.1f} N per leg, still under the peak torque.",
        "the torque the paper books on the hip is, for a foot force along the hip-foot line, "
        "carried by the knee (the hip's moment arm is zero); both actuators are the same motor.",
        f"knee speed at take-off {knee_speed * rpm:.1f} RPM is twice the hip's and still under "
        f"{out_speed:.0f} RPM.",
    )
    return SizingReport(figures=figs, assumptions=assumptions_out, notes=notes)


def _hip_rpm(assumptions: JumpAssumptions, v: float, knee_deg: float) -> float:
    changed = JumpAssumptions(**{**asdict(assumptions), "takeoff_knee_rad": math.radians(knee_deg)})
    return takeoff_joint_speeds_rad_s(changed, v)[0] / RPM_TO_RAD_S
