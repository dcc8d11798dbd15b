"""Real time without ROS: the paper's tumble with its controllers' answers 40 ms late.

The same core objects as the library loop (simulator, gait, MPC, allocator), but every
setpoint reaches the allocator 40 ms of simulated time after the state it answers, as
in a real-time graph. Commands applied when they arrive (the old simulator) push a
taut tether; commands stamped ahead by the latency the allocator measures, queued and
followed at their stamps with rounded corners, the MPC planning from the setpoints it
already sent (issue 28), keep it taut.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from splitter_bringup.run.library import (
    controller_config,
    received_quaternion,
    simulator_for,
)
from splitter_bringup.scenario.definition import load_scenario
from splitter_bringup.scenario.graph_config import gait_parameters
from splitter_ik.core.allocator import AllocatorConfig, TetherLimbAllocator
from splitter_ik.core.command_lead import CommandLead
from splitter_ik.core.projection import project_inertia
from splitter_model.actuators import TETHER_INDEX
from splitter_model.model import RobotModel, angular_velocity_after_morphing
from splitter_mpc.core.controller import MorphingController
from splitter_mpc.core.gait import GaitPhaseMachine, gait_config_from_parameters
from splitter_sim.core.stepping import CommandQueue

LATENCY_NS = 40_000_000  # [ns] state -> setpoint at the allocator
PERIOD_NS = 10_000_000  # [ns] control tick
DURATION_S = 8.0  # [s]


def _fly(stamped: bool) -> dict[str, float]:
    """The tumble with late answers; ``stamped``: the issue 28 protocol, else on arrival."""
    scenario = load_scenario("spin_stabilization", "mpc")
    model = RobotModel()
    sim = simulator_for(scenario, model)
    if stamped:
        sim.config = dataclasses.replace(
            sim.config, command_extrapolation_s=0.25, knot_blend_s=0.01
        )
    start = project_inertia(model, sim.state().principal_inertia_kg_m2).radii_m
    allocator = TetherLimbAllocator(model, AllocatorConfig(), start)
    lead = CommandLead(PERIOD_NS)
    queue = CommandQueue()
    gait = GaitPhaseMachine(gait_config_from_parameters(gait_parameters(scenario)))
    in_flight: list[tuple[int, int, np.ndarray, np.ndarray]] = []  # (arrival, stamp, I, w)
    last_command: int | None = None
    last_setpoint: np.ndarray | None = None
    slack_events, was_slack, tension_min = 0, False, math.inf
    steps = round(DURATION_S / sim.config.dt_s)
    with MorphingController(model, controller_config(scenario)) as controller:
        for step in range(steps + 1):
            state = sim.state()
            t = state.t_ns
            tension_min = min(tension_min, state.tether_tension_n)
            slack_events += state.tether_slack and not was_slack
            was_slack = state.tether_slack
            if t % PERIOD_NS == 0 and step < steps:
                q = received_quaternion(state.orientation_wxyz, hops=1)
                out = gait.update(
                    t,
                    state.position_m,
                    state.velocity_m_s,
                    q,
                    state.angular_velocity_rad_s,
                    float(state.joint_position[TETHER_INDEX]) / 2.0,
                    state.contact_force_n[:, 2],
                    state.principal_inertia_kg_m2,
                )
                if out.reference is not None:
                    ref = out.reference
                    controller.set_reference(
                        ref.stamp_ns, ref.w_ref_rad_s, received_quaternion(ref.q_ref_wxyz, hops=1)
                    )
                w, inertia = state.angular_velocity_rad_s, state.principal_inertia_kg_m2
                if stamped and last_setpoint is not None:  # the MPC node's plan_from_setpoints
                    w = angular_velocity_after_morphing(w, inertia, last_setpoint)
                    inertia = last_setpoint
                setpoint = controller.on_state(t, w, q, inertia, out.phase.value)
                last_setpoint = setpoint
                in_flight.append((t + LATENCY_NS, t, setpoint, state.angular_velocity_rad_s))
            while in_flight and in_flight[0][0] <= t:  # the allocator answers what arrived
                _, t_in, setpoint, w = in_flight.pop(0)
                if not stamped:
                    a = allocator.allocate(t_in, setpoint, w)
                    sim.command_joints(a.joint_position, a.joint_velocity)  # on arrival
                    continue
                lead.record(t_in, t)
                for stamp in lead.output_stamps(t_in, last_command):
                    a = allocator.allocate(stamp, setpoint, w, t_in)
                    last_command = stamp
                    queue.push(stamp, (a.joint_position, a.joint_velocity))
            if step < steps:
                due = queue.due(t)
                if due is not None:
                    stamp, (position, velocity) = due
                    sim.command_joints(position, velocity, stamp_ns=stamp)
                upcoming = queue.peek()
                if upcoming is not None:
                    sim.preview_next_point(upcoming[0], upcoming[1][1])
                sim.step()
    w = state.angular_velocity_rad_s
    return {
        "slack_events": slack_events,
        "tension_min_n": tension_min,
        "residual": max(abs(w[0]), abs(w[2])),
        "lead_ms": lead.lead_ns * 1e-6,
    }


@pytest.mark.slow
def test_commands_stamped_ahead_keep_the_tether_taut_where_late_ones_do_not() -> None:
    on_arrival = _fly(stamped=False)
    stamped = _fly(stamped=True)
    assert on_arrival["slack_events"] > 0, on_arrival
    assert stamped["lead_ms"] == pytest.approx(70.0)  # 1.5 x 40 ms + 2 ms, whole periods
    assert stamped["slack_events"] == 0, stamped
    assert stamped["tension_min_n"] > 0.5, stamped
    assert stamped["residual"] < 0.01, stamped
