"""``splitter campaign SCENARIO`` for a scenario with jumps (``lunar_jumping``), on Dask.

Every draw is a random world (:mod:`splitter_bringup.analysis.jump_campaign`: each
hemi's pushes, the launch spin, the simulated robot's masses, gyro and command
latency) flown by every variant of the scenario (the MPC and the open loop), each
judged on its landings: LANDED, every contact within 196 N per hemi, every
touchdown on the legs, no lumped mass on the ground.

Writes to ``--out`` (default ``runs/campaign/SCENARIO_seedS``):

* ``draws.csv``: per draw its seed, its randomized factors and each variant's outcome;
* ``campaign.json``: the command, the ranges, per variant the success rate with its
  95 % Wilson interval and the failure modes, the definitions, and per draw the
  command that replays it;
* ``success_by_factor.png`` and ``failure_modes.png``;
* ``draws/draw_NNNN.yaml`` for every draw some variant failed (``--yaml all``: all):
  ``splitter run draws/draw_NNNN.yaml --no-ros --out DIR`` flies it again with every
  figure of ``splitter run``.

``--replay SEED`` flies that draw alone, here, and writes its scenario file and a
``campaign.json`` of one draw.
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import time
from dataclasses import asdict
from pathlib import Path
from typing import Any

from splitter_bringup.analysis.campaign import draw_seeds, write_draw_scenario
from splitter_bringup.analysis.jump_campaign import (
    JumpRanges,
    definitions,
    jump_scenario_document,
    make_jump_draw,
    variant_summary,
    write_jump_csv,
)
from splitter_bringup.run.campaign import map_on_dask
from splitter_bringup.run.jump_campaign import jump_error_result, run_jump_draw
from splitter_bringup.scenario.definition import Scenario, ScenarioError, load_scenario


def ranges_from_args(args: argparse.Namespace) -> JumpRanges:
    """The draw ranges: the defaults, with the flags given (``ValueError`` if bad)."""
    defaults = JumpRanges()

    def chosen(value: float | None, default: float) -> float:
        return default if value is None else float(value)

    return JumpRanges(
        push_fraction=float(args.push_fraction),
        push_tilt_deg=float(args.push_tilt),
        spin_fraction=float(args.spin_fraction),
        mass_fraction=chosen(args.perturb_mass, defaults.mass_fraction),
        gyro_noise_rad_s=chosen(args.imu_noise, defaults.gyro_noise_rad_s),
        gyro_bias_rad_s=chosen(args.imu_bias, defaults.gyro_bias_rad_s),
        command_latency_s=chosen(args.command_latency, defaults.command_latency_s),
        slope_deg=float(args.slope),
        step_height_m=float(args.step_height),
    )


def _variants(name: str, wanted: str | None) -> dict[str, Scenario]:
    """Every variant of the scenario (MPC first), or only ``--variant``."""
    base = load_scenario(name)
    names = sorted(base.variants, key=lambda v: (v != "mpc", base.variants.index(v)))
    if wanted is not None:
        if wanted not in base.variants:
            raise ScenarioError(f"variant {wanted!r} not in {list(base.variants)}")
        names = [wanted]
    return {v: load_scenario(name, v) for v in names}


def replay_command(args: argparse.Namespace, out: Path, seed: int) -> str:
    """The command that flies the draw of ``seed`` alone, with the campaign's ranges."""
    words = ["splitter", "campaign", str(args.scenario), "--replay", str(seed)]
    if args.variant is not None:
        words += ["--variant", args.variant]
    if getattr(args, "solver", None) is not None:
        words += ["--solver", args.solver]
    ranges = ranges_from_args(args)
    words += ["--push-fraction", repr(ranges.push_fraction)]
    words += ["--push-tilt", repr(ranges.push_tilt_deg)]
    words += ["--spin-fraction", repr(ranges.spin_fraction)]
    words += ["--perturb-mass", repr(ranges.mass_fraction)]
    words += ["--imu-noise", repr(ranges.gyro_noise_rad_s)]
    words += ["--imu-bias", repr(ranges.gyro_bias_rad_s)]
    words += ["--command-latency", repr(ranges.command_latency_s)]
    words += ["--slope", repr(ranges.slope_deg), "--step-height", repr(ranges.step_height_m)]
    words += ["--out", str(out)]
    return shlex.join(words)


def _print_summary(summaries: dict[str, dict[str, Any]], title: str) -> None:
    print(f"\n{title}")
    for variant, summary in summaries.items():
        lo, hi = summary["success_rate_wilson_95"]
        rate = summary["success_rate"]
        if rate is None:
            continue
        print(
            f"  {variant:<10} success rate  {summary['successes']}/{summary['draws']} = "
            f"{rate:.3f} (95 % Wilson {lo:.3f} - {hi:.3f})"
        )
        for mode, count in summary["failure_mode_counts"].items():
            if count:
                print(f"  {'':<10}   {mode:<16}{count}")


def main(args: argparse.Namespace) -> int:
    """Draw, fly every variant on Dask, judge, summarise, plot; 0 when it ran, 2 on bad
    input."""
    try:
        variants = _variants(args.scenario, args.variant)
        base = next(iter(variants.values()))
        ranges = ranges_from_args(args)
        if args.draws < 1:
            raise ValueError(f"--draws must be >= 1, got {args.draws}")
        if args.duration is not None:
            raise ValueError("--duration: a jumping campaign flies the scenario's duration")
        seeds = draw_seeds(args.seed, args.draws) if args.replay is None else [args.replay]
        draws = [make_jump_draw(k, s, len(base.jumps), ranges) for k, s in enumerate(seeds)]
    except (ScenarioError, ValueError) as exc:
        print(f"splitter campaign: {exc}", file=sys.stderr)
        return 2
    name = Path(args.scenario).stem
    out: Path = args.out or Path("runs") / "campaign" / f"{name}_seed{args.seed}"
    out.mkdir(parents=True, exist_ok=True)
    solver = getattr(args, "solver", None)
    started = time.monotonic()
    if args.replay is None:
        tasks = [(f"draw-{d.index}-{d.seed}", (variants, d, solver)) for d in draws]
        results, cluster = map_on_dask(
            run_jump_draw,
            tasks,
            lambda k, exc: jump_error_result(draws[k], variants, f"Dask task failed: {exc!r}"),
            args.workers,
            args.scheduler,
        )
    else:
        results, cluster = (
            [run_jump_draw(variants, draws[0], solver)],
            {"replay": True},
        )
    wall = time.monotonic() - started
    names = list(variants)
    write_jump_csv(results, names, out / "draws.csv")
    summaries = {v: variant_summary(results, v) for v in names}
    per_draw = []
    for result in results:
        draw = result.draw
        entry: dict[str, Any] = {
            "index": draw.index,
            "seed": draw.seed,
            "outcomes": {v: o.outcome for v, o in result.outcomes.items()},
            "replay": replay_command(args, out / f"replay_{draw.seed}", draw.seed),
        }
        failed = not all(o.success for o in result.outcomes.values())
        if args.yaml == "all" or (args.yaml == "failed" and failed) or args.replay is not None:
            entry.update(
                write_draw_scenario(out, draw.index, jump_scenario_document(variants, draw))
            )
        per_draw.append(entry)
    document = {
        "scenario": base.name,
        "variants": names,
        "solver": solver or base.controller.solver,
        "command": shlex.join(["splitter", *sys.argv[1:]]),
        "seed": args.seed,
        "duration_s": base.duration_s,
        "cluster": cluster,
        "wall_time_s": wall,
        "summary": summaries,
        "definitions": definitions(ranges),
        "per_draw": per_draw,
        "draws_detail": [
            {
                "seed": r.draw.seed,
                "factors": r.draw.factors(),
                "outcomes": {v: asdict(o) for v, o in r.outcomes.items()},
            }
            for r in results
        ],
    }
    (out / "campaign.json").write_text(json.dumps(document, indent=2), encoding="utf-8")
    if not args.no_plots and args.replay is None:
        from splitter_bringup.figures.jump_campaign_plots import (
            plot_failure_modes,
            plot_success_by_factor,
        )

        title = f"{base.name}: {len(results)} draws, seed {args.seed}"
        plot_success_by_factor(results, names, out / "success_by_factor.png", title)
        plot_failure_modes(results, names, out / "failure_modes.png", title)
    _print_summary(summaries, f"{base.name} jumping campaign, seed {args.seed}")
    print(f"  wall time {wall:.1f} s")
    print(f"\nwrote {out / 'draws.csv'} and {out / 'campaign.json'}")
    return 0
