"""The paper's flight figures from a :class:`RunSeries` (PNG, matplotlib Agg).

Plotting only: every number shown is computed by :mod:`.metrics` or read from
the series. Figures (paper Fig. 7 and 10-12): angular velocity, radii and
control effort (inertia and its setpoint), Euler angles, and the quaternion map
(the components of the attitude quaternion over time); beside them the paper's
findings as checked (:func:`plot_findings`) and the solve times of the MPC
benchmark (:func:`plot_solve_times`).
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from numpy.typing import NDArray

from splitter_bringup.analysis.metrics import FindingResult
from splitter_bringup.analysis.series import RunSeries
from splitter_bringup.analysis.touchdowns import Touchdown
from splitter_model.joints import JOINT_NAMES
from splitter_model.model import RobotModel
from splitter_model.rotations import quaternion_to_matrix
from splitter_model.terrain import FLAT, Terrain
from splitter_sim.core.robot_errors import RobotErrors

AXES = ("x", "y", "z")


def save_figure(fig: Figure, path: Path, title: str | None = "", *, dpi: int = 110) -> Path:
    """Title, lay out and write ``fig`` as a PNG at ``path`` (folders made), then close it.

    ``title`` None: no title line at all (an empty title still takes its room).
    """
    if title is not None:
        fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def euler_xyz_deg(q_wxyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """Roll, pitch, yaw [deg] (extrinsic x-y-z, the scenario files' convention), unwrapped."""
    from scipy.spatial.transform import Rotation

    xyzw = np.roll(np.asarray(q_wxyz, dtype=float), -1, axis=1)
    angles = Rotation.from_quat(xyzw).as_euler("xyz")
    return np.degrees(np.unwrap(angles, axis=0))


def _canonical_sign(q: NDArray[np.float64]) -> NDArray[np.float64]:
    """Quaternions with sign flips removed (q and -q are one attitude): a continuous path."""
    out = np.array(q, dtype=float)
    for i in range(1, len(out)):
        if np.dot(out[i], out[i - 1]) < 0.0:
            out[i] = -out[i]
    return out


def _plot_columns(
    ax: Axes,
    t: NDArray[np.float64],
    values: NDArray[np.float64],
    labels: Sequence[str],
    ylabel: str,
) -> None:
    """One line per column of ``values`` over ``t``, labelled, with legend and grid."""
    for i, label in enumerate(labels):
        ax.plot(t, values[:, i], label=label)
    ax.set_ylabel(ylabel)
    ax.legend(loc="best")
    ax.grid(True, alpha=0.3)


def plot_flight(series: RunSeries, path: Path, title: str = "") -> Path:
    """Angular velocity, radii, inertia vs setpoint and Euler angles, one PNG."""
    t = series.t_s
    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True)
    omega_labels = [f"$\\omega_{name}$" for name in AXES]
    _plot_columns(
        axes[0, 0], t, series.angular_velocity_rad_s, omega_labels, "angular velocity [rad/s]"
    )
    radius_labels = [f"$r_{name}$" for name in AXES]
    _plot_columns(axes[0, 1], t, series.radii_m, radius_labels, "radius [m]")
    euler = euler_xyz_deg(series.orientation_wxyz)
    _plot_columns(axes[1, 0], t, euler, ("roll", "pitch", "yaw"), "Euler angles xyz [deg]")
    axes[1, 0].set_xlabel("t [s]")
    ax = axes[1, 1]
    nominal = series.principal_inertia_kg_m2[0]
    for i, name in enumerate(("xx", "yy", "zz")):
        (line,) = ax.plot(
            t, series.principal_inertia_kg_m2[:, i] / nominal[i], label=f"$I_{{{name}}}$"
        )
        ax.plot(
            t,
            series.inertia_setpoint_kg_m2[:, i] / nominal[i],
            "--",
            color=line.get_color(),
            alpha=0.7,
            label=f"setpoint $I_{{{name}}}$",
        )
    ax.set_ylabel("inertia / initial [-]")
    ax.set_xlabel("t [s]")
    ax.legend(loc="best", fontsize="small")
    ax.grid(True, alpha=0.3)
    mark_faults(axes.ravel(), series)
    return save_figure(fig, path, title)


def fault_events(series: RunSeries) -> list[tuple[float, str, str]]:
    """(time [s], label, kind) of each joint's failure ("fault") and detection ("found")."""
    events = []
    for key, kind in (("joint_fault", "fault"), ("joint_detected", "found")):
        values = series.extras.get(key)
        if values is None or not len(values):
            continue
        for j in np.flatnonzero(np.asarray(values)[-1] != 0).tolist():
            first = int(np.argmax(np.asarray(values)[:, j] != 0))
            events.append((float(series.t_s[first]), f"{kind}: {JOINT_NAMES[j]}", kind))
    return sorted(events)


def mark_faults(axes, series: RunSeries) -> None:
    """Vertical lines where a joint failed (red) and where it was found (dark red, dashed)."""
    for t, label, kind in fault_events(series):
        for k, ax in enumerate(axes):
            ax.axvline(
                t,
                color="red" if kind == "fault" else "darkred",
                linestyle="-" if kind == "fault" else "--",
                linewidth=1.0,
                label=label if k == 0 else None,
            )
    if fault_events(series):
        axes[0].legend(loc="best", fontsize="small")


def plot_quaternion_map(series: RunSeries, path: Path, title: str = "") -> Path:
    """The quaternion components over time, and the path of the body y axis in the world."""
    q = _canonical_sign(series.orientation_wxyz)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    quaternion_labels = [f"$q_{name}$" for name in "wxyz"]
    _plot_columns(axes[0], series.t_s, q, quaternion_labels, "quaternion (world <- base)")
    axes[0].set_xlabel("t [s]")
    ax = axes[1]
    # body y axis in the world frame: second column of the rotation matrix
    y_axis = np.array([quaternion_to_matrix(q_k)[:, 1] for q_k in q])
    sc = ax.scatter(y_axis[:, 0], y_axis[:, 2], c=series.t_s, s=3, cmap="viridis")
    ax.set_xlabel("body y axis, world x")
    ax.set_ylabel("body y axis, world z")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    fig.colorbar(sc, ax=ax, label="t [s]")
    return save_figure(fig, path, title)


def plot_comparison(runs: Mapping[str, RunSeries], path: Path, title: str = "") -> Path:
    """|w_x|, w_y, |w_z| of several variants on one figure (e.g. MPC vs open loop)."""
    fig, axes = plt.subplots(1, 3, figsize=(14, 4), sharex=True)
    for label, series in runs.items():
        w = series.angular_velocity_rad_s
        for i, ax in enumerate(axes):
            ax.plot(series.t_s, w[:, i], label=label)
    for i, ax in enumerate(axes):
        ax.set_title(f"$\\omega_{AXES[i]}$ [rad/s]")
        ax.set_xlabel("t [s]")
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="best")
    return save_figure(fig, path, title)


def plot_solve_times(
    runs: Mapping[str, RunSeries], path: Path, budget_ms: float | None = None, title: str = ""
) -> Path:
    """Solve time and iterations of each re-plan, and |w| differences, of several controllers.

    ``runs`` maps a controller's name to its closed loop (``extras`` ``mpc_solve_time_ms``
    and ``mpc_iterations``, NaN between re-plans); ``budget_ms`` draws the time goal.
    The third panel is each run's largest |w_i| difference to the first run. A run has
    one colour in every panel.
    """
    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    reference = next(iter(runs.values()))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for k, (label, series) in enumerate(runs.items()):
        colour = colours[k % len(colours)]
        times = np.asarray(series.extras["mpc_solve_time_ms"], dtype=float)
        iterations = np.asarray(series.extras["mpc_iterations"], dtype=float)
        replans = np.isfinite(times)
        axes[0].semilogy(series.t_s[replans], times[replans], ".-", color=colour, label=label)
        axes[1].plot(series.t_s[replans], iterations[replans], ".-", color=colour, label=label)
        if series is not reference:
            diff = np.max(
                np.abs(series.angular_velocity_rad_s - reference.angular_velocity_rad_s), 1
            )
            axes[2].semilogy(series.t_s, np.maximum(diff, 1e-12), color=colour, label=label)
    if budget_ms is not None:
        axes[0].axhline(budget_ms, color="k", linestyle="--", linewidth=1, label="goal (p99)")
    axes[0].set_ylabel("solve time [ms]")
    axes[1].set_ylabel("iterations")
    first = next(iter(runs))
    axes[2].set_ylabel(f"max$_i$ |$\\omega_i$ - $\\omega_i$({first})| [rad/s]")
    axes[2].set_xlabel("t [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(loc="best")
    return save_figure(fig, path, title)


def plot_graph_time(
    runs: Sequence[Mapping[str, float | str]],
    path: Path,
    goal_real_time_factor: float | None = None,
    title: str = "",
) -> Path:
    """Where each lockstep-graph flight's wall time goes, per simulated second.

    Each run (``splitter bench graph``'s JSON: ``scenario``, ``mode``, ``duration_s``,
    ``flight_wall_time_s``, ``transport_floor_s``, ``library_flight_wall_time_s``) is
    one bar split into the transport floor (the messages alone), the library loop
    (physics and control alone) and the rest: the nodes' own work (building,
    checking and recording messages). ``goal_real_time_factor`` draws its budget.
    """
    labels = [f"{r['scenario']}\n({r['mode']})" for r in runs]
    per_s = [1.0 / float(r["duration_s"]) for r in runs]
    floor = np.array([float(r["transport_floor_s"]) * k for r, k in zip(runs, per_s, strict=True)])
    library = np.array(
        [float(r["library_flight_wall_time_s"]) * k for r, k in zip(runs, per_s, strict=True)]
    )
    flight = np.array(
        [float(r["flight_wall_time_s"]) * k for r, k in zip(runs, per_s, strict=True)]
    )
    rest = np.maximum(flight - floor - library, 0.0)
    fig, ax = plt.subplots(figsize=(10, 2.2 + 0.9 * len(runs)))
    y = np.arange(len(runs))
    ax.barh(y, floor, color="tab:blue", label="transport floor (messages alone)")
    ax.barh(y, library, left=floor, color="tab:orange", label="library loop (physics, control)")
    ax.barh(y, rest, left=floor + library, color="tab:gray", label="nodes' own work (the rest)")
    for yi, total in zip(y, flight, strict=True):
        ax.text(total, yi, f" {1.0 / total:.2f}x", va="center")
    if goal_real_time_factor is not None:
        budget = 1.0 / goal_real_time_factor
        ax.axvline(budget, color="k", linestyle="--", label=f"{goal_real_time_factor:g}x budget")
    ax.set_yticks(y, labels)
    ax.invert_yaxis()
    ax.set_xlabel("wall time per simulated second [s/s]")
    ax.set_xlim(0.0, 1.15 * float(np.max(flight, initial=0.2)))
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12 - 0.3 / len(runs)), ncol=2)
    return save_figure(fig, path, title)


def plot_findings(findings: Sequence[FindingResult], path: Path, title: str = "") -> Path:
    """One panel per checked finding: its metric on the two variants compared."""
    checked = [f for f in findings if f.reproduced is not None]
    fig, axes = plt.subplots(1, max(len(checked), 1), figsize=(4.5 * max(len(checked), 1), 4.2))
    axes = np.atleast_1d(axes)
    for ax, finding in zip(axes, checked, strict=False):
        names = list(finding.values)
        ax.bar(range(len(names)), [finding.values[n] for n in names], color=["C0", "C1"])
        ax.set_xticks(range(len(names)), [n.replace("_", "\n") for n in names], fontsize=8)
        ax.set_ylabel(finding.metric)
        verdict = "reproduced" if finding.reproduced else "NOT reproduced"
        ax.set_title(f"{textwrap.fill(finding.statement, 42)}\n({verdict})", fontsize=8)
        ax.grid(True, axis="y", alpha=0.3)
    return save_figure(fig, path, title)


PHASE_COLOURS = {
    "LAUNCH": "tab:orange",
    "IN_FLIGHT": "tab:blue",
    "JUMP": "tab:red",
    "LANDING": "tab:purple",
    "LANDED": "tab:green",
}


def plot_gait(
    series: RunSeries,
    path: Path,
    title: str = "",
    force_limit_n: float | None = None,
    touchdown_events: Sequence[Touchdown] = (),
    *,
    terrain: Terrain = FLAT,
) -> Path:
    """The paper's Fig. "full" for a jumping run: height, v_x, |w| and ground force per hemi
    over time, the gait phases as coloured bands (and the limbs' force limit); each
    touchdown of ``touchdown_events`` a vertical line on the force panel, green on the
    legs, red on the body, with the tether's tilt. ``terrain`` (not level): the ground's
    height under the centre of mass on the height panel."""
    from splitter_bringup.analysis.jump_metrics import phase_spans

    t = series.t_s
    fig, axes = plt.subplots(4, 1, figsize=(9, 9), sharex=True)
    axes[0].plot(t, series.position_m[:, 2], color="k")
    if not terrain.flat:
        from splitter_bringup.figures.trajectory import GROUND_COLOR, ground_under_path_m

        ground = ground_under_path_m(terrain, series.position_m)
        axes[0].plot(t, ground, color=GROUND_COLOR, lw=1.0, label="ground under the COM")
    axes[0].set_ylabel("COM height z [m]")
    axes[1].plot(t, series.velocity_m_s[:, 0], color="k")
    axes[1].set_ylabel("v_x [m/s]")
    axes[2].plot(t, np.linalg.norm(series.angular_velocity_rad_s, axis=1), color="k")
    axes[2].set_ylabel("|w| [rad/s]")
    contact = series.extras.get("contact_force_n")
    if contact is not None:
        force = np.linalg.norm(np.asarray(contact, dtype=float), axis=2)
        axes[3].plot(t, force[:, 0], label="hemi a")
        axes[3].plot(t, force[:, 1], label="hemi b", linestyle="--")
    if force_limit_n is not None:
        axes[3].axhline(force_limit_n, color="r", linewidth=0.8, label="limbs' dynamic limit")
    for k, event in enumerate(touchdown_events, start=1):
        colour = "g" if event.on_legs else "r"
        axes[3].axvline(event.t_s, color=colour, linestyle=":", linewidth=1.0)
        axes[3].annotate(
            f"TD{k} {'legs' if event.on_legs else 'BODY'}, tilt {event.tether_tilt_deg:.0f} deg",
            (event.t_s, 0.9),
            xycoords=("data", "axes fraction"),
            fontsize=7,
            color=colour,
            rotation=90,
            va="top",
            ha="right",
        )
    axes[3].set_ylabel("ground force [N]")
    axes[3].set_xlabel("t [s]")
    axes[3].legend(loc="upper right", fontsize=8)
    seen: set[str] = set()
    for label, start, end in phase_spans(t, series.gait_phase):
        for ax in axes:
            ax.axvspan(start, end, color=PHASE_COLOURS.get(label, "grey"), alpha=0.12, lw=0)
        if label not in seen:
            axes[0].axvspan(0, 0, color=PHASE_COLOURS.get(label, "grey"), alpha=0.3, label=label)
            seen.add(label)
    axes[0].legend(loc="upper right", fontsize=8, ncols=max(1, len(seen)))
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return save_figure(fig, path, title)


def plot_estimator(series: RunSeries, errors: RobotErrors, path: Path, title: str = "") -> Path:
    """The flight estimator against the simulated robot: gyro bias, masses, rate error,
    and the hemi bodies' own moments when the robot or the estimator has them.

    Estimates solid, the simulated robot's values dashed in the same colour.
    """
    extras = series.extras
    t = extras["estimate_t_s"]
    plant = errors.plant_model(RobotModel())
    hemi = extras.get("estimate_hemi_inertia_kg_m2")
    bodies = hemi is not None and (any(errors.hemi_inertia_kg_m2) or bool(np.any(hemi)))
    rows = 4 if bodies else 3
    fig, axes = plt.subplots(rows, 1, figsize=(10, 3 * rows), sharex=True)
    ax = axes[0]
    for i, name in enumerate(AXES):
        (line,) = ax.plot(t, 1e3 * extras["estimate_gyro_bias_rad_s"][:, i], label=f"$b_{name}$")
        ax.axhline(1e3 * errors.gyro_bias_rad_s[i], ls="--", color=line.get_color(), alpha=0.7)
    ax.set_ylabel("gyro bias [mrad/s]")
    ax = axes[1]
    true = (plant.body_mass_kg, plant.limb_mass_y_kg, plant.limb_mass_z_kg)
    for i, label in enumerate(("$m_x$", "$m_y$", "$m_z$")):
        (line,) = ax.plot(t, extras["estimate_masses_kg"][:, i], label=label)
        ax.axhline(true[i], ls="--", color=line.get_color(), alpha=0.7)
    ax.set_ylabel("lumped masses [kg]")
    ax = axes[2]
    w_true = np.stack(
        [np.interp(t, series.t_s, series.angular_velocity_rad_s[:, i]) for i in range(3)], axis=1
    )
    rate_error = extras["estimate_rate_rad_s"] - w_true
    for i, name in enumerate(AXES):
        ax.plot(t, 1e3 * rate_error[:, i], label=f"$\\hat\\omega_{name} - \\omega_{name}$")
    ax.set_ylabel("rate error [mrad/s]")
    if bodies:
        ax = axes[3]
        for i, name in enumerate(AXES):
            (line,) = ax.plot(t, np.asarray(hemi)[:, i], label=f"$J_{name}$")
            ax.axhline(errors.hemi_inertia_kg_m2[i], ls="--", color=line.get_color(), alpha=0.7)
        ax.set_ylabel("hemi body's own\nmoments [kg m$^2$]")
    axes[-1].set_xlabel("t [s]")
    for ax in axes:
        ax.legend(loc="best", fontsize="small")
        ax.grid(True, alpha=0.3)
    return save_figure(fig, path, title)
