"""``splitter actuator``: actuator sizing against the paper, and a recorded run against the limits.

* ``splitter actuator [--json] [--plot PNG]``: the lunar-jump requirements and the
  TBM2G-07613A with its 10:1 gearbox, each number beside the paper's with the
  relative error, then every assumption and what could not be matched. Exit 1 if a
  number is more than 3 % off.
* ``splitter actuator --check-npz FILE`` (a ``RunSeries`` ``.npz``) or
  ``--check-bag DIR`` (a rosbag2 MCAP bag of the graph): worst joint speed,
  acceleration and estimated torque against the limits. Exit 1 on a violation.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import numpy as np

from splitter_bringup.analysis.actuator_sizing import JumpAssumptions, SizingReport, size_actuators
from splitter_bringup.analysis.run_check import LimitCheck, check_run, run_check_arrays
from splitter_model.actuators import TETHER_INDEX
from splitter_model.model import RobotModel

LOG = logging.getLogger("splitter.actuator")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``splitter actuator``."""
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--plot", type=Path, metavar="PNG", help="also draw the result here")
    source = parser.add_mutually_exclusive_group()
    source.add_argument(
        "--check-bag", type=Path, metavar="DIR", help="check a recorded bag's joint speeds/torques"
    )
    source.add_argument(
        "--check-npz", type=Path, metavar="FILE", help="check a RunSeries .npz the same way"
    )
    parser.add_argument(
        "--takeoff-knee-deg",
        type=float,
        default=None,
        help="take-off knee angle of the sizing [deg] (default 42, inferred from the paper)",
    )


def main(args: argparse.Namespace) -> int:
    """Run the chosen mode; 0 when everything is within tolerance / limits."""
    if args.check_bag is not None or args.check_npz is not None:
        return _check(args)
    assumptions = JumpAssumptions()
    if args.takeoff_knee_deg is not None:
        assumptions = JumpAssumptions(takeoff_knee_rad=float(np.radians(args.takeoff_knee_deg)))
    report = size_actuators(assumptions)
    if args.json:
        print(json.dumps(report.to_dict(), indent=2))
    else:
        print(format_sizing(report))
    if args.plot is not None:
        from splitter_bringup.figures.actuator_plots import plot_sizing

        LOG.info("figure: %s", plot_sizing(report, args.plot))
    off = [f.key for f in report.figures if f.within_tolerance is False]
    if off:
        LOG.error("more than 3 %% from the paper: %s", ", ".join(off))
    return 1 if off else 0


def format_sizing(report: SizingReport) -> str:
    """The sizing as a plain-text table with assumptions and notes."""
    lines = [
        f"{'quantity':<48} {'ours':>10} {'paper':>9} {'error':>8}  formula",
        "-" * 100,
    ]
    for f in report.figures:
        paper = "" if f.paper is None else f"{f.paper:g}"
        err = "" if f.relative_error is None else f"{100 * f.relative_error:+.2f}%"
        label = f"{f.label} [{f.unit}]"
        lines.append(f"{label:<48} {f.value:>10.4g} {paper:>9} {err:>8}  {f.formula}")
    lines += ["", "assumptions:"]
    for name, a in report.assumptions.items():
        value = a["value"]
        shown = f"{value:.6g}" if isinstance(value, float) else str(value)
        lines.append(f"  {name} = {shown} {a['unit']}: {a['why']}")
    lines += ["", "notes:"] + [f"  - {n}" for n in report.notes]
    return "\n".join(lines)


# --- run check -------------------------------------------------------------------------
def _check(args: argparse.Namespace) -> int:
    if args.check_npz is not None:
        from splitter_bringup.analysis.series import RunSeries

        arrays = run_check_arrays(RunSeries.load_npz(args.check_npz))
        source = str(args.check_npz)
    else:
        from splitter_bringup.run.run_bag import run_check_arrays_from_bag

        try:
            arrays = run_check_arrays_from_bag(args.check_bag)
        except ValueError as exc:
            raise SystemExit(str(exc)) from exc
        source = str(args.check_bag)
    from splitter_msgs_py import names

    model = RobotModel()
    checks = check_run(
        model,
        arrays["t_s"],
        arrays["joint_position"],
        arrays["angular_velocity_rad_s"],
        gait_phase=arrays.get("gait_phase"),
        jump_force_n=arrays.get("jump_force_n"),
        joint_names=names.JOINT_NAMES,
    )
    result = {
        "source": source,
        "samples": len(arrays["t_s"]),
        "duration_s": float(arrays["t_s"][-1] - arrays["t_s"][0]),
        "checks": [_check_dict(c) for c in checks],
        "ok": all(c.ok for c in checks),
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(f"{source}: {result['samples']} samples over {result['duration_s']:.2f} s")
        print(f"{'check':<32} {'worst':>10} {'limit':>10} {'use':>7}  where")
        for c in checks:
            flag = "" if c.ok else "  EXCEEDED"
            print(
                f"{c.key + ' [' + c.unit + ']':<32} {c.value:>10.4g} {c.limit:>10.4g} "
                f"{100 * c.utilisation:>6.1f}%  {c.where}{flag}"
            )
    if args.plot is not None:
        from splitter_bringup.figures.actuator_plots import plot_run_check

        t = np.asarray(arrays["t_s"])
        speed = np.gradient(np.asarray(arrays["joint_position"]), t, axis=0)
        limbs, tether = speed[:, :TETHER_INDEX], speed[:, TETHER_INDEX]
        LOG.info("figure: %s", plot_run_check(t, limbs, tether, checks, args.plot))
    return 0 if result["ok"] else 1


def _check_dict(c: LimitCheck) -> dict[str, object]:
    return {
        "key": c.key,
        "value": c.value,
        "limit": c.limit,
        "unit": c.unit,
        "utilisation": c.utilisation,
        "ok": c.ok,
        "where": c.where,
    }
