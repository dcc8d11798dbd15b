"""Frames of a flight animation: what to draw at each frame time (ROS-free, no plotting).

A :class:`RunSeries` (from a bag or the library loop) is sampled at ``fps``: frame
``k`` shows the latest sample at or before ``t_0 + k / fps``, so a run of duration
``D`` has ``floor(D fps) + 1`` frames and its video lasts ``(floor(D fps) + 1) / fps``.
Each frame carries the scene (:class:`splitter_sim.core.scene.Scene`, built by
the same :func:`~splitter_sim.core.scene.scene_from_pose` as the simulator's:
the ten masses from the simulator's geometry at the recorded joint positions and
odometry pose, the angular momentum, the contact forces when known, the ground
(the run's terrain) when there is gravity) and a caption with time, gait phase and ``|w|``.
The drawing lives in :mod:`splitter_bringup.figures.animation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_bringup.analysis.series import RunSeries
from splitter_model.model import RobotModel
from splitter_model.terrain import FLAT, Terrain
from splitter_sim.core.scene import Ground, Scene, SceneGeometry, scene_from_pose

DEFAULT_FPS = 10.0  # [1/s] frames per second of `splitter run`'s animations
VIEW_MARGIN_M = 0.5  # [m] around the farthest mass from the centre of mass
_EPS_S = 1e-9  # [s] tolerance on the last frame time


@dataclass(frozen=True)
class FlightFrames:
    """Everything an animation draws, frame by frame (world frame, metres)."""

    times_s: NDArray[np.float64]  # (n,) frame times [s]
    sample_index: NDArray[np.int64]  # (n,) series sample shown by each frame
    scenes: tuple[Scene, ...]  # per frame
    captions: tuple[str, ...]  # per frame
    fps: float  # [1/s]
    view_half_width_m: float  # [m] half the side of the cube the camera shows

    def __len__(self) -> int:
        return len(self.times_s)

    @property
    def duration_s(self) -> float:
        """Playing time of the animation [s]: one frame period per frame."""
        return len(self) / self.fps


def frame_times(t_s: ArrayLike, fps: float) -> NDArray[np.float64]:
    """``t_0 + k / fps`` for every ``k`` up to the last sample time."""
    t = np.asarray(t_s, dtype=float)
    if len(t) == 0:
        raise ValueError("no samples to animate")
    if not (math.isfinite(fps) and fps > 0.0):
        raise ValueError(f"fps must be > 0, got {fps}")
    n = math.floor((t[-1] - t[0]) * fps + _EPS_S) + 1
    return t[0] + np.arange(n) / fps


def sample_indices(t_s: ArrayLike, times_s: ArrayLike) -> NDArray[np.int64]:
    """Index of the latest sample at or before each time (the first one before it)."""
    t = np.asarray(t_s, dtype=float)
    idx = np.searchsorted(t, np.asarray(times_s, dtype=float) + _EPS_S, side="right") - 1
    return np.clip(idx, 0, len(t) - 1).astype(np.int64)


def caption(t_s: float, phase: str, w_norm_rad_s: float) -> str:
    """``t = 1.20 s   IN_FLIGHT   |w| = 1.234 rad/s``."""
    text = f"t = {t_s:5.2f} s"
    if phase:
        text += f"   {phase}"
    return f"{text}   |w| = {w_norm_rad_s:.3f} rad/s"


def flight_frames(
    series: RunSeries,
    fps: float = DEFAULT_FPS,
    contact_forces_n: ArrayLike | None = None,
    model: RobotModel | None = None,
    terrain: Terrain = FLAT,
) -> FlightFrames:
    """Frames of ``series`` at ``fps``; ``contact_forces_n`` (n_samples, 2, 3) is optional.

    ``terrain``: the ground the run flew over (the scenario's), drawn when there is gravity.
    """
    times = frame_times(series.t_s, fps)
    idx = sample_indices(series.t_s, times)
    geometry = SceneGeometry(model)
    forces = None if contact_forces_n is None else np.asarray(contact_forces_n, dtype=float)
    if forces is not None and forces.shape != (len(series), 2, 3):
        raise ValueError(f"contact forces must be ({len(series)}, 2, 3), got {forces.shape}")
    ground = Ground(terrain=terrain) if series.gravity_m_s2 > 0.0 else None
    faults = series.extras.get("joint_fault")  # drawn red (the library's, a bag's)
    scenes = []
    captions = []
    for i in idx:
        p = series.position_m[i]
        q = series.orientation_wxyz[i]
        w = series.angular_velocity_rad_s[i]
        scenes.append(
            scene_from_pose(
                round(float(series.t_s[i]) * 1e9),
                p,
                q,
                mass_positions_world=geometry.world_positions(p, q, series.joint_position[i]),
                principal_inertia_kg_m2=series.principal_inertia_kg_m2[i],
                angular_velocity_rad_s=w,
                contact_forces_n=None if forces is None else forces[i],
                ground=ground,
                joint_fault=None if faults is None else faults[i],
            )
        )
        phase = series.gait_phase[i] if series.gait_phase else ""
        captions.append(caption(float(series.t_s[i]), phase, float(np.linalg.norm(w))))
    reach = max(
        (float(np.max(np.linalg.norm(s.mass_positions_m - s.position_m, axis=1))) for s in scenes),
        default=1.0,
    )
    return FlightFrames(
        times_s=times,
        sample_index=idx,
        scenes=tuple(scenes),
        captions=tuple(captions),
        fps=float(fps),
        view_half_width_m=reach + VIEW_MARGIN_M,
    )
