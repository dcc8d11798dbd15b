"""What the ``simulator`` node sets besides the physics: mode, periods, start-up, initial state.

ROS-free. Each field is a node parameter (:func:`parameter_field`: name, default,
description with unit, range); the physics parameters are the fields of
:class:`splitter_sim.core.simulator.SimConfig`, the simulated robot's errors those of
:class:`splitter_sim.core.robot_errors.RobotErrors` (``robot_errors``). The node
declares them all from here.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from splitter_model.model import RobotModel
from splitter_msgs_py.core.parameter_fields import parameter_field
from splitter_sim.core.robot_errors import RobotErrors
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator

MODES = ("lockstep", "real_time")
OUTPUT_PERIOD_S = (1e-4, 100.0)  # [s] range of the markers' and diagnostics' periods


@dataclass(frozen=True)
class SimulatorSettings:
    """The simulator node's own settings (docs/ARCHITECTURE.md, "Lockstep protocol")."""

    mode: str = parameter_field("lockstep", "stepping mode", choices=MODES)
    rate_factor: float = parameter_field(
        1.0, "real_time mode: simulated seconds per wall second [-]", bounds=(1e-3, 1e4)
    )
    lockstep_timeout_s: float = parameter_field(
        5.0,
        "lockstep: longest wall wait for a tick's commands before stepping on [s]",
        bounds=(1e-3, 3600.0),
    )
    startup_wait_s: float = parameter_field(
        3.0,
        "longest wall wait at start for state subscribers (and, lockstep, command publishers) [s]",
        bounds=(0.0, 600.0),
    )
    startup_wait_for_nodes: tuple[str, ...] = parameter_field(
        (),
        "nodes that must be in the graph before stepping starts (e.g. the controllers)",
        item_type=str,
    )
    startup_wait_for_publishers: tuple[str, ...] = parameter_field(
        (),
        "topics that must have a publisher before stepping starts (e.g. the MPC's setpoints)",
        item_type=str,
    )
    startup_settle_s: float = parameter_field(
        0.0,
        "the start condition must hold this long before stepping: time for the other nodes' "
        "endpoints to match each other, which this node cannot see [s]",
        bounds=(0.0, 60.0),
    )
    startup_wait_for_subscribers: tuple[str, ...] = parameter_field(
        (),
        "nodes that must subscribe to every state topic before stepping starts (a recorder)",
        item_type=str,
    )
    duration_s: float = parameter_field(
        0.0, "simulated time after which the node stops stepping (0: never) [s]", bounds=(0.0, 1e7)
    )
    control_period_s: float = parameter_field(
        0.01, "lockstep tick period, a multiple of dt_s [s]", bounds=(1e-4, 10.0)
    )
    markers_period_s: float = parameter_field(
        0.04,
        "markers and scene period, simulated time, a multiple of dt_s [s]",
        bounds=OUTPUT_PERIOD_S,
    )
    diagnostics_period_s: float = parameter_field(
        0.1, "diagnostics period, simulated time, a multiple of dt_s [s]", bounds=OUTPUT_PERIOD_S
    )
    progress_period_s: float = parameter_field(
        1.0, "period of the 't = ... s' progress log line, simulated time [s]", bounds=(1e-3, 1e6)
    )
    initial_position_m: tuple[float, ...] = parameter_field(
        (0.0, 0.0, 10.0), "centre of mass, world [m]", length=3
    )
    initial_velocity_m_s: tuple[float, ...] = parameter_field(
        (0.0, 0.0, 0.0), "world frame [m/s]", length=3
    )
    initial_orientation_euler_deg: tuple[float, ...] = parameter_field(
        (0.0, 0.0, 0.0), "attitude, extrinsic xyz Euler angles (scipy 'xyz') [deg]", length=3
    )
    initial_angular_velocity_rad_s: tuple[float, ...] = parameter_field(
        (-0.3, -0.9, 0.9), "body frame [rad/s] (paper Table I)", length=3
    )
    initial_radii_m: tuple[float, ...] = parameter_field(
        (2.8, 0.2, 0.2), "r_x, r_y, r_z [m]", length=3
    )
    # the simulated robot's errors (parameters of their own: RobotErrors' fields)
    robot_errors: RobotErrors = field(default_factory=RobotErrors)

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {self.mode!r}")

    def period_ns(self, name: str, dt_ns: int) -> int:
        """The period field ``name`` in ns; ValueError unless a multiple of the step ``dt_ns``."""
        seconds = float(getattr(self, name))
        period = round(seconds * 1e9)
        if period <= 0 or period % dt_ns != 0:
            raise ValueError(f"{name} ({seconds} s) must be a multiple of dt_s ({dt_ns * 1e-9} s)")
        return period

    def simulator(self, config: SimConfig, model: RobotModel | None = None) -> Simulator:
        """The simulator starting from this initial state; a ValueError names its parameter.

        It flies ``model`` (default: the nominal robot) with ``robot_errors``' masses
        (:meth:`RobotErrors.plant_model`) and hemi bodies' own inertia.
        """
        plant = self.robot_errors.plant_model(model or RobotModel())
        try:
            return Simulator(
                plant,
                config,
                self.initial_state(),
                hemi_inertia_kg_m2=self.robot_errors.hemi_inertia_kg_m2,
            )
        except ValueError as exc:
            raise _naming_parameter(exc) from exc

    def initial_state(self) -> InitialState:
        """The initial state; a ValueError names the ``initial_*`` parameter refused."""
        try:
            return initial_state_from_euler(
                self.initial_position_m,
                self.initial_velocity_m_s,
                self.initial_orientation_euler_deg,
                self.initial_angular_velocity_rad_s,
                self.initial_radii_m,
            )
        except ValueError as exc:
            raise _naming_parameter(exc) from exc


def _naming_parameter(exc: ValueError) -> ValueError:
    """``InitialState.<field> ...`` as an error naming the node parameter ``initial_<field>``."""
    text = str(exc)
    if not text.startswith("InitialState."):
        return exc
    field_name = text.removeprefix("InitialState.").split(":")[0].split(" ")[0]
    field_name = {"orientation_wxyz": "orientation_euler_deg"}.get(field_name, field_name)
    return ValueError(f"initial_{field_name}: {text}")


def initial_state_from_euler(
    position_m: ArrayLike,
    velocity_m_s: ArrayLike,
    orientation_euler_deg: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    radii_m: ArrayLike,
) -> InitialState:
    """An :class:`InitialState` with its attitude as extrinsic xyz Euler angles [deg]."""
    xyzw = Rotation.from_euler(
        "xyz", np.asarray(orientation_euler_deg, dtype=float), degrees=True
    ).as_quat()
    return InitialState(
        position_m=position_m,
        velocity_m_s=velocity_m_s,
        orientation_wxyz=np.roll(xyzw, 1),
        angular_velocity_rad_s=angular_velocity_rad_s,
        radii_m=radii_m,
    )
