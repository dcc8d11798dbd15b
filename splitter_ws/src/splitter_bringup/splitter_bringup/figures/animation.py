"""Draw :class:`~splitter_bringup.analysis.flight_frames.FlightFrames` in 3D and encode mp4 or gif.

Thin plotting layer: one matplotlib figure whose artists are updated frame by
frame (the dumbbell's masses, tether, limbs, the arrows of
:mod:`splitter_sim.core.scene` and a caption), the camera following the
centre of mass. The ground (when the frames have one) is drawn once, before the
first frame: a light grey wireframe grid following
:meth:`~splitter_sim.core.scene.Ground.height_at` (the slope and the steps' tops)
over the whole region the camera visits, and each step's box edges; both are
clipped to the camera's cube vertex by vertex. ``.mp4`` is H.264 through the
ffmpeg of the ``imageio-ffmpeg`` wheel; ``.gif`` goes through Pillow.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from splitter_bringup.analysis.flight_frames import FlightFrames
from splitter_sim.core.scene import FAULT_COLOR, HEMI_MASSES, LIMB_SEGMENTS, Ground, Scene

_log = logging.getLogger(__name__)
DEFAULT_SIZE_PX = (480, 360)  # (width, height) [px]; multiples of 8 for H.264
DPI = 80  # [px/in]
FORMATS = (".mp4", ".gif")
BODY_SIZE = 60  # [pt^2] marker area of a hemi body
TIP_SIZE = 25  # [pt^2] marker area of a limb tip
TETHER_COLOR = "0.4"  # grey (a locked reel: FAULT_COLOR)
LIMB_COLOR = "0.25"  # grey (a limb with a failed joint: FAULT_COLOR)
HEMI_COLORS = ("tab:orange", "tab:blue")  # hemi a, hemi b (the simulator's marker colours)
VIEW_ELEVATION_DEG = 20.0  # [deg]
VIEW_AZIMUTH_DEG = -60.0  # [deg]
TICKS_PER_AXIS = 3  # tick labels are most of a frame's drawing time
GRID_LINES_PER_VIEW = 8  # ground grid lines across the camera's cube (about)
GRID_SUBDIVISIONS = 4  # vertices per grid cell side (the view clips vertex by vertex)
MAX_GROUND_VERTICES = 20_000  # a long flight gets a coarser grid beyond this
GROUND_GRID_COLOR = "0.7"  # light grey
GROUND_GRID_WIDTH = 0.6  # [pt]
STEP_EDGE_COLOR = (0.45, 0.35, 0.25)  # RGB
STEP_EDGE_WIDTH = 1.0  # [pt]
_WALL_EPS_M = 1e-6  # [m] a grid line meets a step's wall just outside and on its edge


@dataclass(frozen=True)
class AnimationInfo:
    """What was written."""

    path: Path
    frames: int
    fps: float  # [1/s]
    duration_s: float  # [s] playing time


def _rgb(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    return np.ascontiguousarray(image[:, :, :3])


def grid_spacing_m(view_half_width_m: float) -> float:
    """A round spacing (1, 2 or 5 times a power of ten) [m] giving about
    :data:`GRID_LINES_PER_VIEW` grid lines across the camera's cube."""
    raw = max(2.0 * view_half_width_m / GRID_LINES_PER_VIEW, 1e-3)
    power = 10.0 ** np.floor(np.log10(raw))
    return float(next(m * power for m in (1.0, 2.0, 5.0, 10.0) if m * power >= raw - 1e-12))


def _profile(ground: Ground, start: NDArray, end: NDArray, step_m: float) -> NDArray[np.float64]:
    """(n, 3) the ground along the horizontal segment start -> end (x, y [m]): samples
    every ``step_m`` and on both sides of each step wall it crosses (vertical walls)."""
    length = float(np.hypot(*(end - start)))
    s = list(np.linspace(0.0, length, max(2, int(np.ceil(length / step_m)) + 1)))
    direction = (end - start) / max(length, 1e-12)
    for step in ground.terrain.steps:
        for axis, edges in ((0, (step.x_min_m, step.x_max_m)), (1, (step.y_min_m, step.y_max_m))):
            if abs(direction[axis]) < 1e-12:
                continue
            for edge in edges:
                at = (edge - start[axis]) / direction[axis]
                s += [at - _WALL_EPS_M, at, at + _WALL_EPS_M]
    s_all = np.unique(np.clip(s, 0.0, length))
    xy = start + s_all[:, None] * direction
    z = [ground.height_at(float(x), float(y)) for x, y in xy]
    return np.column_stack([xy, z])


def ground_grid_lines(
    ground: Ground,
    x_range_m: tuple[float, float],
    y_range_m: tuple[float, float],
    spacing_m: float,
) -> list[NDArray[np.float64]]:
    """A wireframe of the ground over the rectangle: polylines (n, 3) of constant y, then
    of constant x, every ``spacing_m`` (on its multiples), following
    :meth:`Ground.height_at` with a vertex at least every ``spacing_m / GRID_SUBDIVISIONS``
    (the view hides a line's vertices outside it). The spacing is doubled until there are
    at most about :data:`MAX_GROUND_VERTICES` vertices."""
    while True:
        x0 = np.floor(x_range_m[0] / spacing_m) * spacing_m
        x1 = np.ceil(x_range_m[1] / spacing_m) * spacing_m
        y0 = np.floor(y_range_m[0] / spacing_m) * spacing_m
        y1 = np.ceil(y_range_m[1] / spacing_m) * spacing_m
        nx = round((x1 - x0) / spacing_m) + 1
        ny = round((y1 - y0) / spacing_m) + 1
        if 2 * nx * ny * GRID_SUBDIVISIONS <= MAX_GROUND_VERTICES:
            break
        spacing_m *= 2.0
    res = spacing_m / GRID_SUBDIVISIONS
    lines = [
        _profile(ground, np.array([x0, y]), np.array([x1, y]), res) for y in np.linspace(y0, y1, ny)
    ]
    lines += [
        _profile(ground, np.array([x, y0]), np.array([x, y1]), res) for x in np.linspace(x0, x1, nx)
    ]
    return lines


def step_edge_lines(ground: Ground, max_length_m: float) -> list[NDArray[np.float64]]:
    """The twelve edges of each step's box (bottom on the base plane, top ``height_m``
    above it, vertical walls) as polylines (n, 3), a vertex at least every ``max_length_m``."""
    terrain = ground.terrain
    lines = []
    for step in terrain.steps:
        corners = [
            (step.x_min_m, step.y_min_m),
            (step.x_max_m, step.y_min_m),
            (step.x_max_m, step.y_max_m),
            (step.x_min_m, step.y_max_m),
        ]
        bottom = np.array(
            [[x, y, ground.height_m + terrain.base_height_m(x, y)] for x, y in corners]
        )
        top = bottom + np.array([0.0, 0.0, step.height_m])
        edges = [(face[i], face[(i + 1) % 4]) for face in (bottom, top) for i in range(4)]
        edges += [(bottom[i], top[i]) for i in range(4)]
        for a, b in edges:
            n = max(1, int(np.ceil(np.linalg.norm(b - a) / max_length_m)))
            lines.append(a + np.linspace(0.0, 1.0, n + 1)[:, None] * (b - a))
    return lines


class _Scene:
    """The figure and the artists updated at each frame."""

    def __init__(self, frames: FlightFrames, title: str, size_px: tuple[int, int]) -> None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.ticker import MaxNLocator

        self.frames = frames
        width, height = size_px
        self.fig = plt.figure(figsize=(width / DPI, height / DPI), dpi=DPI)
        self.ax = self.fig.add_axes((0.0, 0.06, 1.0, 0.86), projection="3d")
        self.ax.view_init(elev=VIEW_ELEVATION_DEG, azim=VIEW_AZIMUTH_DEG)
        self.ax.set_box_aspect((1.0, 1.0, 1.0))
        self.ax.set_xlabel("x [m]", fontsize=7, labelpad=-8)
        self.ax.set_ylabel("y [m]", fontsize=7, labelpad=-8)
        self.ax.set_zlabel("z [m]", fontsize=7, labelpad=-8)
        self.ax.tick_params(labelsize=6, pad=-3)
        for axis in (self.ax.xaxis, self.ax.yaxis, self.ax.zaxis):  # few labels: cheap frames
            axis.set_major_locator(MaxNLocator(TICKS_PER_AXIS))
        self.fig.suptitle(title, fontsize=9, y=0.985)
        self.caption = self.fig.text(0.5, 0.015, "", ha="center", fontsize=8, family="monospace")
        self.tether = self.ax.plot([], [], [], color=TETHER_COLOR, lw=1.5)[0]
        self.limbs = [self.ax.plot([], [], [], color=LIMB_COLOR, lw=1.2)[0] for _ in LIMB_SEGMENTS]
        self.bodies = []
        self.tips = []
        for color in HEMI_COLORS:
            self.bodies.append(self.ax.plot([], [], [], "o", color=color, ms=BODY_SIZE**0.5)[0])
            self.tips.append(self.ax.plot([], [], [], "o", color=color, ms=TIP_SIZE**0.5)[0])
        names = [a.name for a in frames.scenes[0].arrows] if len(frames) else []
        names += [n for n in ("contact_a", "contact_b") if n not in names]
        self.arrows = {n: self.ax.plot([], [], [], lw=2.0)[0] for n in names}
        self.heads = {n: self.ax.plot([], [], [], "o", ms=3)[0] for n in names}
        self._add_ground()

    def _add_ground(self) -> None:
        """The ground's grid and step edges over the region the camera visits (once)."""
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        frames = self.frames
        ground = next((s.ground for s in frames.scenes if s.ground is not None), None)
        if ground is None:
            return
        h = frames.view_half_width_m
        centres = np.array([s.position_m for s in frames.scenes])
        spacing = grid_spacing_m(h)
        grid = ground_grid_lines(
            ground,
            (float(centres[:, 0].min() - h), float(centres[:, 0].max() + h)),
            (float(centres[:, 1].min() - h), float(centres[:, 1].max() + h)),
            spacing,
        )
        self.ax.add_collection3d(
            Line3DCollection(
                grid, colors=GROUND_GRID_COLOR, linewidths=GROUND_GRID_WIDTH, axlim_clip=True
            ),
            autolim=False,
        )
        edges = step_edge_lines(ground, spacing / GRID_SUBDIVISIONS)
        if edges:
            self.ax.add_collection3d(
                Line3DCollection(
                    edges, colors=[STEP_EDGE_COLOR], linewidths=STEP_EDGE_WIDTH, axlim_clip=True
                ),
                autolim=False,
            )

    def draw(self, k: int) -> NDArray[np.uint8]:
        self._draw_scene(self.frames.scenes[k], self.frames.view_half_width_m)
        self.caption.set_text(self.frames.captions[k])
        self.fig.canvas.draw()
        return _rgb(np.asarray(self.fig.canvas.buffer_rgba()))

    def _draw_scene(self, scene: Scene, h: float) -> None:
        """The artists at ``scene``, in a cube of half side ``h`` about its centre of mass."""
        masses = scene.mass_positions_m
        self.tether.set_data_3d(*scene.tether_m.T)
        for i, (line, segment) in enumerate(zip(self.limbs, scene.limb_segments_m, strict=True)):
            line.set_data_3d(*segment.T)
            faulty = i in scene.faulty_limbs
            line.set_color(FAULT_COLOR[:3] if faulty else LIMB_COLOR)
            line.set_linewidth(2.4 if faulty else 1.2)
        self.tether.set_color(FAULT_COLOR[:3] if scene.reel_locked else TETHER_COLOR)
        for hemi, indices in enumerate(HEMI_MASSES):
            self.bodies[hemi].set_data_3d(*masses[[indices[0]]].T)
            self.tips[hemi].set_data_3d(*masses[list(indices[1:])].T)
        shown = {a.name: a for a in scene.arrows}
        for name, line in self.arrows.items():
            arrow = shown.get(name)
            if arrow is None:
                line.set_data_3d([], [], [])
                self.heads[name].set_data_3d([], [], [])
                continue
            pts = np.stack([arrow.start, arrow.end])
            line.set_data_3d(*pts.T)
            line.set_color(arrow.color)
            self.heads[name].set_data_3d(*pts[1:].T)
            self.heads[name].set_color(arrow.color)
        c = scene.position_m
        self.ax.set_xlim(c[0] - h, c[0] + h)
        self.ax.set_ylim(c[1] - h, c[1] + h)
        self.ax.set_zlim(c[2] - h, c[2] + h)

    def close(self) -> None:
        import matplotlib.pyplot as plt

        plt.close(self.fig)


def render_animation(
    frames: FlightFrames,
    path: Path,
    title: str = "",
    size_px: tuple[int, int] = DEFAULT_SIZE_PX,
) -> AnimationInfo:
    """Draw every frame and write ``path`` (``.mp4`` or ``.gif``); folders are made."""
    import imageio.v2 as imageio

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ValueError(f"animation file must end in {' or '.join(FORMATS)}, got {path.name}")
    if len(frames) == 0:
        raise ValueError("no frames to write")
    path.parent.mkdir(parents=True, exist_ok=True)
    scene = _Scene(frames, title, size_px)
    try:
        if suffix == ".mp4":
            writer = imageio.get_writer(
                path,
                format="FFMPEG",
                mode="I",
                fps=frames.fps,
                codec="libx264",
                pixelformat="yuv420p",
                macro_block_size=8,
                ffmpeg_log_level="error",
            )
            try:
                for k in range(len(frames)):
                    writer.append_data(scene.draw(k))
            finally:
                writer.close()
        else:
            images = [scene.draw(k) for k in range(len(frames))]
            imageio.mimsave(path, images, format="GIF", duration=1000.0 / frames.fps, loop=0)
    finally:
        scene.close()
    _log.info("wrote %s: %d frames at %g fps", path, len(frames), frames.fps)
    return AnimationInfo(path, len(frames), frames.fps, frames.duration_s)
