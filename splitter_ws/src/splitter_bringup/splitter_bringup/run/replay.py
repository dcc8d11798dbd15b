"""Replay for regression: feed a recorded bag's inputs to a fresh MPC node, compare setpoints.

Parameters: the MPC's, as the bag carries them (the MCAP attachment
``params/inertial_morphing_mpc.yaml``, :mod:`splitter_bag.core.node_parameters`),
else the run folder's ``params/inertial_morphing_mpc.yaml`` beside the bag (bags
recorded before the attachment), else the caller's. A bag with none of them is
refused (:class:`ReplayError`): it is never replayed with default parameters.
Each solve gets the lockstep deadline (:data:`LOCKSTEP_MAX_TIME_S`), so the
replay computes what the MPC answers given time, whatever the replaying
machine's load.

Feeding, by stamps (not by log time, whose order among messages of equal log
time is the recorder's): the messages of the topics the ``inertial_morphing_mpc``
node listens to (/clock, state, inertia, gait phase, attitude reference, the gait
manager's jump command) go out as raw CDR bytes, one at a time, each once the
previous one reached the node, in the order of their stamp; at one stamp /clock
first, then the gait manager's outputs (phase, reference), then the state and
inertia, then the jump command (the gait manager publishes its phase and
reference of tick ``t`` before its jump command ``t``). The phase, a String
without a stamp, and the reference take the stamp of the gait tick that
published them: that of the first jump command logged at or after them. For
every setpoint the bag holds, in stamp order, everything stamped up to it is fed
and then the replay waits until the new MPC answered the same tick, exactly as
the simulator waits in lockstep: deterministic, and as fast as the solver. The
state and inertia of a tick the recorded MPC did not answer (a real-time run's
skipped tick) are not fed, so the replayed MPC solves the ticks the recorded one
solved.

The comparison and why a tick differs: :mod:`splitter_bringup.analysis.replay_accounting`.
"""

from __future__ import annotations

import bisect
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message

from splitter_bag import read_messages
from splitter_bag.core.definitions import header_stamp_ns
from splitter_bag.core.node_parameters import (
    ParameterFileError,
    attachment_name,
    bag_node_parameters,
    read_parameter_file,
)
from splitter_bringup.analysis.replay_accounting import ReplayAccount, Solve, account
from splitter_mpc.core.solvers import LOCKSTEP_MAX_TIME_S
from splitter_msgs_py import names
from splitter_msgs_py.conversions import (
    TOPIC_MESSAGE_CLASSES,
    diagnostics_from_msg,
    vector3_from_msg,
)
from splitter_msgs_py.qos import qos_for

LOG = logging.getLogger(__name__)

MPC_NODE = "inertial_morphing_mpc"
MPC_INPUT_TOPICS = (
    names.CLOCK,
    names.IMU,
    names.INERTIA,
    names.GAIT_PHASE,
    names.STANCE_SHAPE,
    names.ATTITUDE_REFERENCE,
    names.ATTITUDE_REFERENCE_POSE,
    names.JUMP_COMMAND,
)
GAIT_OUTPUTS = (
    names.GAIT_PHASE,
    names.STANCE_SHAPE,
    names.ATTITUDE_REFERENCE,
    names.ATTITUDE_REFERENCE_POSE,
)
TICK_INPUTS = (names.IMU, names.INERTIA)  # answered once both of a tick are in
# order of the topics at one stamp (module doc)
_RANK = {
    names.CLOCK: 0,
    **{t: 1 for t in GAIT_OUTPUTS},
    names.IMU: 2,
    names.INERTIA: 2,
    names.JUMP_COMMAND: 3,
}
DEFAULT_TOLERANCE_KG_M2 = 1e-9  # [kg m^2] largest setpoint component difference of a match
DEFAULT_CONTROL_PERIOD_S = 0.01  # [s] the MPC node's default control_period_s
DELIVERY_TIMEOUT_S = 10.0  # [s] wall time for one fed message to reach the MPC
# the replay gives every solve the lockstep deadline and waits for a restarted worker
REPLAY_OVERRIDES = {
    "use_sim_time": True,
    "max_solve_time_s": LOCKSTEP_MAX_TIME_S,
    "wait_for_solver_start": True,
}


class ReplayError(RuntimeError):
    """No parameters, no inputs, or the replayed MPC did not answer a recorded tick in time."""


@dataclass(frozen=True)
class ReplayResult:
    """Recorded and replayed setpoints tick by tick, the solves behind them, the comparison."""

    stamps_ns: NDArray[np.int64]  # (n,)
    recorded_kg_m2: NDArray[np.float64]  # (n, 3)
    replayed_kg_m2: NDArray[np.float64]  # (n, 3)
    recorded_solves: dict[int, Solve]  # tick [ns] -> recorded solve (from /diagnostics)
    replayed_solves: dict[int, Solve]
    parameters_source: str
    control_period_ns: int
    parameters_changed_ns: int | None = None  # first live change the recorded MPC reported

    @property
    def max_abs_diff_kg_m2(self) -> float:
        """Largest difference between a recorded and a replayed setpoint [kg m^2]."""
        if len(self.stamps_ns) == 0:
            return 0.0
        return float(np.max(np.abs(self.recorded_kg_m2 - self.replayed_kg_m2)))

    def account(self, tolerance_kg_m2: float = DEFAULT_TOLERANCE_KG_M2) -> ReplayAccount:
        """The comparison with every difference beyond ``tolerance_kg_m2`` classified."""
        return account(
            self.stamps_ns,
            self.recorded_kg_m2,
            self.replayed_kg_m2,
            self.recorded_solves,
            self.replayed_solves,
            tolerance_kg_m2=tolerance_kg_m2,
            control_period_ns=self.control_period_ns,
            parameters_changed_ns=self.parameters_changed_ns,
        )


def mpc_parameters_of_bag(
    bag_dir: Path, params_file: Path | None = None
) -> tuple[dict[str, Any], str]:
    """(the MPC's parameters, where they come from); :class:`ReplayError` when there are none.

    ``params_file`` (a ROS 2 parameter file) wins; then the bag's attachment; then
    ``<run>/params/inertial_morphing_mpc.yaml`` beside the bag.
    """
    bag_dir = Path(bag_dir)
    try:
        if params_file is not None:
            _, params = read_parameter_file(Path(params_file))
            return params, str(params_file)
        carried = bag_node_parameters(bag_dir).get(MPC_NODE)
        if carried is not None:
            return carried, f"the bag's attachment {attachment_name(MPC_NODE)}"
        beside = bag_dir.parent / "params" / f"{MPC_NODE}.yaml"
        if beside.is_file():
            _, params = read_parameter_file(beside)
            return params, str(beside)
    except (ParameterFileError, OSError) as exc:
        raise ReplayError(f"the MPC's parameters: {exc}") from exc
    raise ReplayError(
        f"{bag_dir} carries no parameters of the MPC (no MCAP attachment "
        f"{attachment_name(MPC_NODE)}) and there is no {beside}: not replaying with default "
        "parameters. Give the run's parameter file with --params FILE."
    )


@dataclass(frozen=True)
class _Input:
    key: tuple[int, int, int]  # (stamp [ns], rank at that stamp, log order)
    topic: str
    data: bytes


@dataclass
class _Bag:
    """What a replay needs from a bag, read once."""

    inputs: list[_Input]  # in feeding order
    setpoints: dict[int, NDArray[np.float64]]  # tick [ns] -> recorded setpoint
    recorded_solves: dict[int, Solve]
    topics: set[str]  # input topics present
    parameters_changed_ns: int | None  # the recorded MPC's first live parameter change


def _read_bag(bag_dir: Path) -> _Bag:
    wanted = (*MPC_INPUT_TOPICS, names.INERTIA_SETPOINT, names.DIAGNOSTICS)
    raw: list[tuple[str, int, bytes]] = []
    setpoints: dict[int, NDArray[np.float64]] = {}
    diagnostics: list[tuple[int, dict]] = []
    for m in read_messages(bag_dir, topics=wanted):
        if m.topic == names.INERTIA_SETPOINT:
            msg = deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[m.topic])
            sample = vector3_from_msg(msg)
            setpoints[sample.t_ns] = sample.vector
        elif m.topic == names.DIAGNOSTICS:
            msg = deserialize_message(m.data, TOPIC_MESSAGE_CLASSES[m.topic])
            for status in diagnostics_from_msg(msg):
                if status.name.startswith(f"{MPC_NODE}:"):
                    diagnostics.append((header_stamp_ns(m.data) or 0, status.values))
        else:
            raw.append((m.topic, m.log_time_ns, bytes(m.data)))
    jump_logs = [(log, header_stamp_ns(d)) for t, log, d in raw if t == names.JUMP_COMMAND]
    jump_log_times = [log for log, _ in jump_logs]
    inputs = []
    for order, (topic, log_ns, data) in enumerate(raw):
        if topic in GAIT_OUTPUTS and jump_logs:
            # the gait tick that published it: its jump command is logged at or after it
            i = bisect.bisect_left(jump_log_times, log_ns)
            stamp = jump_logs[i][1] if i < len(jump_logs) else None
        elif topic in (names.GAIT_PHASE, names.STANCE_SHAPE):
            stamp = log_ns  # no gait manager's answers recorded: the phase's log time
        else:
            stamp = header_stamp_ns(data)
        if stamp is None:
            stamp = log_ns
        if topic in TICK_INPUTS and stamp not in setpoints:
            continue  # a tick the recorded MPC did not answer (or no tick at all)
        inputs.append(_Input((stamp, _RANK[topic], order), topic, data))
    inputs.sort(key=lambda i: i.key)
    changed = [
        t
        for t, v in diagnostics
        if isinstance(v.get("parameter_changes"), float) and v["parameter_changes"] > 0
    ]
    return _Bag(
        inputs,
        setpoints,
        _recorded_solves(diagnostics),
        {i.topic for i in inputs},
        min(changed) if changed else None,
    )


def _recorded_solves(diagnostics: list[tuple[int, dict]]) -> dict[int, Solve]:
    """tick -> solve, for each MPC report whose solve counter moved since the last one."""
    out = {}
    last_solves = 0.0
    for t_ns, values in sorted(diagnostics, key=lambda d: d[0]):
        solves = values.get("solves")
        if not isinstance(solves, float) or solves <= last_solves:
            continue
        last_solves = solves
        out[t_ns] = Solve(values.get("solve_ok") is True, str(values.get("solve_status", "")))
    return out


class _Feeder(Node):
    """Publishes the bag's MPC inputs and collects the replayed setpoints."""

    def __init__(self, topics: set[str], **kwargs) -> None:
        super().__init__("bag_replay_feeder", **kwargs)
        # only the topics the bag holds: the MPC waits for a gait manager it sees publish
        self.pubs = {
            topic: self.create_publisher(TOPIC_MESSAGE_CLASSES[topic], topic, qos_for(topic))
            for topic in MPC_INPUT_TOPICS
            if topic in topics
        }
        self.setpoints: dict[int, NDArray[np.float64]] = {}
        self.setpoint_sub = self.create_subscription(
            TOPIC_MESSAGE_CLASSES[names.INERTIA_SETPOINT],
            names.INERTIA_SETPOINT,
            self._on_setpoint,
            qos_for(names.INERTIA_SETPOINT),
        )

    def _on_setpoint(self, msg) -> None:
        sample = vector3_from_msg(msg)
        self.setpoints[sample.t_ns] = sample.vector


class _DeliveryCounter:
    """Counts the messages each of a node's subscriptions has taken (wraps their callbacks)."""

    def __init__(self, node: Node) -> None:
        self.delivered: dict[str, int] = {}
        for sub in node.subscriptions:
            sub.callback = self._counting(sub.topic_name, sub.callback)

    def _counting(self, topic: str, callback):
        def counted(*args):
            try:
                return callback(*args)
            finally:
                self.delivered[topic] = self.delivered.get(topic, 0) + 1

        return counted


def replay_mpc(
    bag_dir: Path,
    context: Context,
    *,
    parameters: dict | None = None,
    tick_timeout_s: float = 10.0,
    end_s: float | None = None,
    params_file: Path | None = None,
) -> ReplayResult:
    """Re-run the MPC node on ``bag_dir``'s inputs; see the module docstring.

    ``parameters`` (a dict) or ``params_file`` replace the parameters the bag carries.
    """
    from splitter_mpc.inertial_morphing_mpc_node import InertialMorphingMpcNode

    bag_dir = Path(bag_dir)
    if parameters is not None:
        params, source = dict(parameters), "given by the caller"
    else:
        params, source = mpc_parameters_of_bag(bag_dir, params_file)
    LOG.info("MPC parameters: %s", source)
    control_ns = round(float(params.get("control_period_s", DEFAULT_CONTROL_PERIOD_S)) * 1e9)
    bag = _read_bag(bag_dir)
    end_ns = None if end_s is None else round(end_s * 1e9)
    ticks = sorted(t for t in bag.setpoints if end_ns is None or t <= end_ns)
    if not ticks:
        raise ReplayError(f"{bag_dir} holds no {names.INERTIA_SETPOINT} to compare with")
    missing = [t for t in TICK_INPUTS if t not in bag.topics]
    if missing:
        raise ReplayError(f"{bag_dir} holds no {', '.join(missing)}: nothing to feed the MPC")
    overrides = [Parameter(k, value=v) for k, v in {**params, **REPLAY_OVERRIDES}.items()]
    mpc = InertialMorphingMpcNode(context=context, parameter_overrides=overrides)
    counter = _DeliveryCounter(mpc)
    feeder = _Feeder(bag.topics, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(mpc)
    executor.add_node(feeder)
    replayed_solves: dict[int, Solve] = {}
    try:
        _wait_for_discovery(executor, feeder, tick_timeout_s)
        published: dict[str, int] = {}
        next_input = 0
        for tick in ticks:
            while next_input < len(bag.inputs) and bag.inputs[next_input].key[0] <= tick:
                item = bag.inputs[next_input]
                next_input += 1
                feeder.pubs[item.topic].publish(item.data)
                published[item.topic] = published.get(item.topic, 0) + 1
                _spin_until(
                    executor,
                    lambda t=item.topic: counter.delivered.get(t, 0) >= published[t],
                    DELIVERY_TIMEOUT_S,
                    f"{item.topic} stamped {item.key[0] * 1e-9:.3f} s did not reach the MPC",
                )
            _spin_until(
                executor,
                lambda t=tick: t in feeder.setpoints,
                tick_timeout_s,
                f"the replayed MPC did not answer t = {tick * 1e-9:.3f} s "
                f"within {tick_timeout_s} s",
            )
            status = mpc.controller.status
            if status.replanned and status.t_ns == tick:
                replayed_solves[tick] = Solve(bool(status.solve_ok), str(status.solve_status))
        recorded = np.array([bag.setpoints[t] for t in ticks])
        replayed = np.array([feeder.setpoints[t] for t in ticks])
        recorded_solves = {t: s for t, s in bag.recorded_solves.items() if t <= ticks[-1]}
        return ReplayResult(
            np.array(ticks, dtype=np.int64),
            recorded,
            replayed,
            recorded_solves,
            replayed_solves,
            source,
            control_ns,
            bag.parameters_changed_ns,
        )
    finally:
        executor.remove_node(mpc)
        executor.remove_node(feeder)
        mpc.destroy_node()
        feeder.destroy_node()
        executor.shutdown()


def _spin_until(executor: SingleThreadedExecutor, done, timeout_s: float, error: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not done():
        if time.monotonic() > deadline:
            raise ReplayError(error)
        executor.spin_once(timeout_sec=0.01)


def _wait_for_discovery(executor: SingleThreadedExecutor, feeder: _Feeder, timeout_s: float):
    deadline = time.monotonic() + timeout_s
    while (
        any(pub.get_subscription_count() == 0 for pub in feeder.pubs.values())
        or feeder.setpoint_sub.get_publisher_count() == 0
    ):
        if time.monotonic() > deadline:
            raise ReplayError("the MPC node did not match the replay's topics")
        executor.spin_once(timeout_sec=0.01)
