"""Replay for regression: feed a recorded bag's inputs to a fresh MPC node, compare setpoints.

The bag's messages go out in their recorded order, as raw CDR bytes, on the
topics the ``inertial_morphing_mpc`` node listens to (state, gait phase,
attitude reference, /clock). Each time the bag holds a recorded setpoint, the
replay waits until the new MPC has answered the same tick, exactly as the
simulator waits in lockstep, so the replay is deterministic and as fast as the
solver. Same code, same parameters, same inputs: the setpoints must match.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import NDArray
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message

from splitter_msgs_py import names
from splitter_msgs_py.bag import read_messages
from splitter_msgs_py.conversions import TOPIC_MESSAGE_CLASSES, vector3_from_msg
from splitter_msgs_py.qos import qos_for

LOG = logging.getLogger(__name__)

MPC_INPUT_TOPICS = (
    names.CLOCK,
    names.IMU,
    names.INERTIA,
    names.GAIT_PHASE,
    names.ATTITUDE_REFERENCE,
    names.ATTITUDE_REFERENCE_POSE,
)


class ReplayError(RuntimeError):
    """The replayed MPC did not answer a recorded tick in time, or the bag lacks inputs."""


@dataclass(frozen=True)
class ReplayResult:
    """Recorded and replayed setpoints, tick by tick."""

    stamps_ns: NDArray[np.int64]  # (n,)
    recorded_kg_m2: NDArray[np.float64]  # (n, 3)
    replayed_kg_m2: NDArray[np.float64]  # (n, 3)

    @property
    def max_abs_diff_kg_m2(self) -> float:
        """Largest difference between a recorded and a replayed setpoint [kg m^2]."""
        if len(self.stamps_ns) == 0:
            return 0.0
        return float(np.max(np.abs(self.recorded_kg_m2 - self.replayed_kg_m2)))


def mpc_parameters_of_run(bag_dir: Path) -> dict:
    """The MPC parameters a launcher run used (``<run>/params/inertial_morphing_mpc.yaml``)."""
    path = Path(bag_dir).parent / "params" / "inertial_morphing_mpc.yaml"
    if not path.is_file():
        return {"use_sim_time": True}
    with path.open(encoding="utf-8") as stream:
        content = yaml.safe_load(stream)
    return dict(next(iter(content.values()))["ros__parameters"])


class _Feeder(Node):
    """Publishes the bag's MPC inputs and collects the replayed setpoints."""

    def __init__(self, **kwargs) -> None:
        super().__init__("bag_replay_feeder", **kwargs)
        self.pubs = {
            topic: self.create_publisher(TOPIC_MESSAGE_CLASSES[topic], topic, qos_for(topic))
            for topic in MPC_INPUT_TOPICS
        }
        self.setpoints: dict[int, NDArray[np.float64]] = {}
        self.create_subscription(
            TOPIC_MESSAGE_CLASSES[names.INERTIA_SETPOINT],
            names.INERTIA_SETPOINT,
            self._on_setpoint,
            qos_for(names.INERTIA_SETPOINT),
        )

    def _on_setpoint(self, msg) -> None:
        sample = vector3_from_msg(msg)
        self.setpoints[sample.t_ns] = sample.vector


def replay_mpc(
    bag_dir: Path,
    context: Context,
    parameters: dict | None = None,
    tick_timeout_s: float = 10.0,
    end_s: float | None = None,
) -> ReplayResult:
    """Re-run the MPC node on ``bag_dir``'s inputs; see the module docstring."""
    from splitter_mpc.inertial_morphing_mpc_node import InertialMorphingMpcNode

    params = mpc_parameters_of_run(bag_dir) if parameters is None else dict(parameters)
    params["use_sim_time"] = True
    overrides = [Parameter(k, value=v) for k, v in params.items()]
    mpc = InertialMorphingMpcNode(context=context, parameter_overrides=overrides)
    feeder = _Feeder(context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(mpc)
    executor.add_node(feeder)
    try:
        _wait_for_discovery(executor, feeder, tick_timeout_s)
        stamps, recorded = [], []
        end_ns = None if end_s is None else round(end_s * 1e9)
        for message in read_messages(bag_dir, topics=(*MPC_INPUT_TOPICS, names.INERTIA_SETPOINT)):
            if message.topic != names.INERTIA_SETPOINT:
                feeder.pubs[message.topic].publish(message.data)
                executor.spin_once(timeout_sec=0.0)
                continue
            sample = vector3_from_msg(
                deserialize_message(message.data, TOPIC_MESSAGE_CLASSES[names.INERTIA_SETPOINT])
            )
            if end_ns is not None and sample.t_ns > end_ns:
                break
            deadline = time.monotonic() + tick_timeout_s
            while sample.t_ns not in feeder.setpoints:
                if time.monotonic() > deadline:
                    raise ReplayError(
                        f"the replayed MPC did not answer t = {sample.t_ns * 1e-9:.3f} s "
                        f"within {tick_timeout_s} s"
                    )
                executor.spin_once(timeout_sec=0.01)
            stamps.append(sample.t_ns)
            recorded.append(sample.vector)
        if not stamps:
            raise ReplayError(f"{bag_dir} holds no {names.INERTIA_SETPOINT} to compare with")
        replayed = [feeder.setpoints[t] for t in stamps]
        return ReplayResult(np.array(stamps), np.array(recorded), np.array(replayed))
    finally:
        executor.remove_node(mpc)
        executor.remove_node(feeder)
        mpc.destroy_node()
        feeder.destroy_node()
        executor.shutdown()


def _wait_for_discovery(executor: SingleThreadedExecutor, feeder: _Feeder, timeout_s: float):
    deadline = time.monotonic() + timeout_s
    needed = (names.IMU, names.INERTIA)
    while any(feeder.pubs[t].get_subscription_count() == 0 for t in needed):
        if time.monotonic() > deadline:
            raise ReplayError("the MPC node did not subscribe to the state topics")
        executor.spin_once(timeout_sec=0.01)
