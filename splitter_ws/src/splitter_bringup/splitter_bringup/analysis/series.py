"""Time series of one run: what the library loop produces and what a bag is read back into.

ROS-free. Metrics (``metrics.py``) and figures (``plots.py``) take a
:class:`RunSeries`, whichever way the run was made, so the library loop and the
node graph are summarised by the very same code.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
from numpy.typing import NDArray


@dataclass
class RunSeries:
    """Samples of one run at the simulator's state rate (n samples).

    Angular velocity is body frame; orientation is world <- base, scalar first.
    ``inertia_setpoint_kg_m2`` holds the latest setpoint at each sample
    (forward-filled; the first setpoint back-fills the start).
    """

    t_s: NDArray[np.float64]  # (n,) [s]
    angular_velocity_rad_s: NDArray[np.float64]  # (n, 3) [rad/s] body
    orientation_wxyz: NDArray[np.float64]  # (n, 4)
    principal_inertia_kg_m2: NDArray[np.float64]  # (n, 3) [kg m^2] measured
    inertia_setpoint_kg_m2: NDArray[np.float64]  # (n, 3) [kg m^2]
    radii_m: NDArray[np.float64]  # (n, 3) [m] r_x, r_y, r_z
    position_m: NDArray[np.float64]  # (n, 3) [m] world, centre of mass
    velocity_m_s: NDArray[np.float64]  # (n, 3) [m/s] world
    joint_position: NDArray[np.float64]  # (n, 25) [rad, m] order of names.JOINT_NAMES
    gravity_m_s2: float = 0.0  # [m/s^2]
    gait_phase: list[str] = field(default_factory=list)  # (n,) or empty
    jump_force_n: NDArray[np.float64] | None = None  # (n, 3) [N] world, or None
    extras: dict[str, NDArray[np.float64]] = field(default_factory=dict)  # named (n, ...) arrays

    def __post_init__(self) -> None:
        n = len(self.t_s)
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, np.ndarray) and value.shape[0] != n:
                raise ValueError(f"RunSeries.{f.name} has {value.shape[0]} samples, t_s has {n}")
        if self.gait_phase and len(self.gait_phase) != n:
            raise ValueError(f"RunSeries.gait_phase has {len(self.gait_phase)} samples, not {n}")

    def __len__(self) -> int:
        return len(self.t_s)

    def save_npz(self, path: Path) -> None:
        """Write every array to one ``.npz`` file (for golden tests and notebooks)."""
        arrays = {
            f.name: getattr(self, f.name)
            for f in fields(self)
            if isinstance(getattr(self, f.name), np.ndarray)
        }
        arrays.update({f"extras.{k}": v for k, v in self.extras.items()})
        arrays["gravity_m_s2"] = np.array(self.gravity_m_s2)
        arrays["gait_phase"] = np.array(self.gait_phase, dtype=str)
        np.savez_compressed(path, **arrays)

    @classmethod
    def load_npz(cls, path: Path) -> RunSeries:
        """Read a file written by :meth:`save_npz`."""
        with np.load(path) as data:
            names = {f.name for f in fields(cls)} - {"extras", "gravity_m_s2", "gait_phase"}
            kwargs = {k: data[k] for k in names if k in data}
            extras = {k.split(".", 1)[1]: data[k] for k in data.files if k.startswith("extras.")}
            return cls(
                **kwargs,
                gravity_m_s2=float(data["gravity_m_s2"]),
                gait_phase=[str(p) for p in data["gait_phase"]],
                extras=extras,
            )
