"""Draw :class:`~splitter_bringup.analysis.flight_frames.FlightFrames` in 3D and encode mp4 or gif.

Thin plotting layer: one matplotlib figure whose artists are updated frame by
frame (the dumbbell's masses, tether, limbs, the arrows of
:mod:`splitter_sim.core.scene` and a caption), the camera following the
centre of mass. ``.mp4`` is H.264 through the ffmpeg of the ``imageio-ffmpeg``
wheel; ``.gif`` goes through Pillow.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from splitter_bringup.analysis.flight_frames import FlightFrames
from splitter_sim.core.scene import HEMI_MASSES, LIMB_SEGMENTS, Scene

_log = logging.getLogger(__name__)
DEFAULT_SIZE_PX = (480, 360)  # (width, height) [px]; multiples of 8 for H.264
DPI = 80  # [px/in]
FORMATS = (".mp4", ".gif")
BODY_SIZE = 60  # [pt^2] marker area of a hemi body
TIP_SIZE = 25  # [pt^2] marker area of a limb tip
HEMI_COLORS = ("tab:orange", "tab:blue")  # hemi a, hemi b (the simulator's marker colours)
VIEW_ELEVATION_DEG = 20.0  # [deg]
VIEW_AZIMUTH_DEG = -60.0  # [deg]
TICKS_PER_AXIS = 3  # tick labels are most of a frame's drawing time


@dataclass(frozen=True)
class AnimationInfo:
    """What was written."""

    path: Path
    frames: int
    fps: float  # [1/s]
    duration_s: float  # [s] playing time


def _rgb(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    return np.ascontiguousarray(image[:, :, :3])


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
        self.tether = self.ax.plot([], [], [], color="0.4", lw=1.5)[0]
        self.limbs = [self.ax.plot([], [], [], color="0.25", lw=1.2)[0] for _ in LIMB_SEGMENTS]
        self.bodies = []
        self.tips = []
        for color in HEMI_COLORS:
            self.bodies.append(self.ax.plot([], [], [], "o", color=color, ms=BODY_SIZE**0.5)[0])
            self.tips.append(self.ax.plot([], [], [], "o", color=color, ms=TIP_SIZE**0.5)[0])
        names = [a.name for a in frames.scenes[0].arrows] if len(frames) else []
        names += [n for n in ("contact_a", "contact_b") if n not in names]
        self.arrows = {n: self.ax.plot([], [], [], lw=2.0)[0] for n in names}
        self.heads = {n: self.ax.plot([], [], [], "o", ms=3)[0] for n in names}
        self.ground = self.ax.plot([], [], [], color="0.6", lw=0.8)[0]

    def draw(self, k: int) -> NDArray[np.uint8]:
        self._draw_scene(self.frames.scenes[k], self.frames.view_half_width_m)
        self.caption.set_text(self.frames.captions[k])
        self.fig.canvas.draw()
        return _rgb(np.asarray(self.fig.canvas.buffer_rgba()))

    def _draw_scene(self, scene: Scene, h: float) -> None:
        """The artists at ``scene``, in a cube of half side ``h`` about its centre of mass."""
        masses = scene.mass_positions_m
        self.tether.set_data_3d(*scene.tether_m.T)
        for line, segment in zip(self.limbs, scene.limb_segments_m, strict=True):
            line.set_data_3d(*segment.T)
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
        if scene.ground is None:
            self.ground.set_data_3d([], [], [])
            return
        xs = [c[0] - h, c[0] + h, c[0] + h, c[0] - h, c[0] - h]
        ys = [c[1] - h, c[1] - h, c[1] + h, c[1] + h, c[1] - h]
        zs = [scene.ground.height_at(x, y) for x, y in zip(xs, ys, strict=True)]
        self.ground.set_data_3d(xs, ys, zs)

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
