"""``splitter bench sim``: real-time factor of the bare simulator, and its physics figures.

The timed run is 10 s of lunar jumping flight with ground contact at 200 Hz
(the simulator's 5 ms step): the robot drops onto its feet, pushes off at the
paper's actuator sizing (21.7 m/s^2 over the 0.4 m stroke: 4 m/s take-off,
section IV) with a forward component, flies for about 5 s, lands, slides and
rolls to rest, and jumps again.
It is timed three ways: joints held (the bare physics), joints morphing
(25 joint commands at 100 Hz tracing a slow inertia change, as the MPC and
allocator do) and morphing with a full :class:`SimState` snapshot every step
(what the simulator node pays). The real-time factor is simulated time over
wall time on one core; the goal is >= 100.

``--physics`` adds the conservation figures of the unit tests: world angular
momentum and energy drift over 20 s of torque-free tumbling, and over 3 s of
morphing, the energy balance against the integrated actuator work.

The simulator runs its hot path as compiled C when it can
(:mod:`splitter_sim.core.kernels`; ``"compiled"`` in the JSON says which path was
timed); ``SPLITTER_SIM_COMPILED=0 splitter bench sim --json`` times the pure-Python
path. To see where a step's time goes (one morphing run, 10 s simulated)::

    python -m cProfile -s tottime -m splitter_bringup.cli.main bench sim --repeat 1 | head -40

or, per line of the step (``pip install line_profiler``, not a project dependency)::

    python - <<'PY'
    from line_profiler import LineProfiler
    from splitter_sim import bench
    from splitter_sim.core.simulator import Simulator
    profile = LineProfiler(Simulator._step_compiled, Simulator.state)
    profile.runcall(bench.run_lunar, 10.0, True, False)
    profile.print_stats(output_unit=1e-6)
    PY

and, independent of the machine's load, the instruction count of one run::

    valgrind --tool=callgrind --callgrind-out-file=/tmp/sim.callgrind \
        python -c "from splitter_sim import bench; bench.run_lunar(10.0, True, False)"
    callgrind_annotate /tmp/sim.callgrind | head -30
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from splitter_model.kinematics import joint_positions_from_radii
from splitter_model.model import GRAVITY_PRESETS, RobotModel
from splitter_sim.core.simulator import InitialState, SimConfig, Simulator

LOG = logging.getLogger(__name__)
DURATION_S = 10.0  # [s] simulated
JUMPS = ((0.3, 0.485), (7.5, 7.685))  # [s] thrust windows: 4.0 / 21.7 s of push
JUMP_FORCE_N = (100.0, 0.0, 18.0 * (21.7 + GRAVITY_PRESETS["moon"]))  # [N] world
CONTROL_PERIOD_STEPS = 2  # joint commands every 10 ms


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options of ``splitter bench sim``."""
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    parser.add_argument(
        "--duration", type=float, default=DURATION_S, help="simulated seconds per run [s]"
    )
    parser.add_argument(
        "--repeat", type=int, default=3, help="timed repetitions; the best one is reported"
    )
    parser.add_argument(
        "--physics", action="store_true", help="also measure conservation errors (about 3 s)"
    )


def _lunar_simulator(model: RobotModel) -> Simulator:
    return Simulator(
        model,
        SimConfig(gravity_m_s2=GRAVITY_PRESETS["moon"], ground_contact=True),
        InitialState(position_m=(0.0, 0.0, 0.45)),
    )


def _morph_command(model: RobotModel, t: float) -> np.ndarray:
    """Slow radii change within the reachable range (period 4 s)."""
    phase = 2.0 * math.pi * t / 4.0
    radii = (
        2.55 + 0.25 * math.cos(phase),
        0.2 + 0.06 * math.sin(phase),
        0.2 + 0.06 * math.sin(phase),
    )
    return joint_positions_from_radii(model, radii)


def run_lunar(
    duration_s: float, morph: bool, snapshot: bool, model: RobotModel | None = None
) -> dict[str, float]:
    """One timed run; returns wall time, steps and contact statistics."""
    model = model or RobotModel()
    sim = _lunar_simulator(model)
    steps = round(duration_s / sim.config.dt_s)
    dt = sim.config.dt_s
    commands = [
        _morph_command(model, k * dt) if morph else None
        for k in range(0, steps, CONTROL_PERIOD_STEPS)
    ]
    thrust = [any(t0 <= k * dt < t1 for t0, t1 in JUMPS) for k in range(steps)]
    in_contact_steps = 0
    airborne = 0
    start = time.perf_counter()
    for k in range(steps):
        if k % CONTROL_PERIOD_STEPS == 0 and morph:
            sim.command_joints(commands[k // CONTROL_PERIOD_STEPS])
        if k == 0 or thrust[k] != thrust[k - 1]:
            sim.command_jump_force(JUMP_FORCE_N if thrust[k] else (0.0, 0.0, 0.0))
        sim.step()
        if snapshot:
            s = sim.state()
            airborne += not s.in_contact.any()
    wall = time.perf_counter() - start
    final = sim.state()
    if not final.is_finite():
        raise RuntimeError("simulation produced non-finite values")
    in_contact_steps = sim.contact_step_count
    return {
        "wall_s": wall,
        "steps": steps,
        "sim_s": steps * dt,
        "contact_step_fraction": in_contact_steps / steps,
        "final_x_m": float(final.position_m[0]),
    }


def _best(repeat: int, fn: Callable[[], dict[str, float]]) -> dict[str, float]:
    runs = [fn() for _ in range(max(1, repeat))]
    best = min(runs, key=lambda r: r["wall_s"])
    best["real_time_factor"] = best["sim_s"] / best["wall_s"]
    best["step_us"] = best["wall_s"] / best["steps"] * 1e6
    return best


def physics_figures() -> dict[str, float]:
    """Conservation errors at the paper's step (same set-ups as the unit tests)."""
    model = RobotModel()

    def flying(**initial: Any) -> Simulator:
        """In flight, 10 m up, without ground contact."""
        state = InitialState(position_m=(0.0, 0.0, 10.0), **initial)
        return Simulator(model, SimConfig(ground_contact=False), state)

    sim = flying(angular_velocity_rad_s=(0.4, -0.9, 0.7), radii_m=(2.2, 0.33, 0.14))
    s0 = sim.state()
    for _ in range(4000):
        sim.step()
    s1 = sim.state()
    h0 = np.linalg.norm(s0.angular_momentum_world)
    out = {
        "tumbling_20s_h_rel_error": float(
            np.linalg.norm(s1.angular_momentum_world - s0.angular_momentum_world) / h0
        ),
        "tumbling_20s_energy_rel_error": abs(s1.kinetic_energy_j / s0.kinetic_energy_j - 1.0),
    }
    sim = flying(angular_velocity_rad_s=(-0.3, -0.9, 0.9))
    s0 = sim.state()
    worst_h = 0.0
    sim.command_joints(joint_positions_from_radii(model, (2.3, 0.3, 0.13)))
    for k in range(600):
        if k == 280:
            sim.command_joints(joint_positions_from_radii(model, (2.6, 0.16, 0.26)))
        sim.step()
        s = sim.state()
        worst_h = max(
            worst_h,
            float(np.linalg.norm(s.angular_momentum_world - s0.angular_momentum_world))
            / float(np.linalg.norm(s0.angular_momentum_world)),
        )
    delta_e = s.rotational_energy_j - s0.rotational_energy_j
    out["morphing_3s_h_rel_error"] = worst_h
    out["morphing_3s_energy_change_j"] = delta_e
    out["morphing_3s_actuator_work_j"] = s.actuator_work_j
    out["morphing_3s_energy_vs_work_rel_error"] = abs(delta_e - s.actuator_work_j) / abs(delta_e)
    return out


def main(args: argparse.Namespace) -> int:
    """Run the benchmark and print the figures."""
    if args.duration <= 0.0 or not math.isfinite(args.duration):
        raise SystemExit("--duration must be > 0")
    results: dict[str, object] = {
        "duration_s": args.duration,
        "dt_s": 0.005,
        "goal_rtf": 100.0,
        "compiled": _lunar_simulator(RobotModel()).compiled,
    }
    for name, morph, snapshot in (
        ("held_joints", False, False),
        ("morphing", True, False),
        ("morphing_with_state_snapshot", True, True),
    ):
        if not args.json:
            LOG.info("timing %s ...", name)
        results[name] = _best(
            args.repeat, lambda m=morph, s=snapshot: run_lunar(args.duration, m, s)
        )
    if args.physics:
        results["physics"] = physics_figures()
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        for name in ("held_joints", "morphing", "morphing_with_state_snapshot"):
            r = results[name]
            assert isinstance(r, dict)
            contact = 100.0 * r["contact_step_fraction"]
            print(
                f"{name:30s} real-time factor {r['real_time_factor']:7.1f}x "
                f"({r['step_us']:6.1f} us/step, {contact:.0f}% of steps near contact)"
            )
        if args.physics:
            for key, value in results["physics"].items():  # type: ignore[union-attr]
                print(f"{key:40s} {value:.3e}")
    return 0
