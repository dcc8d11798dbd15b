"""``splitter replay`` on bags as the project writes them (issue 28, item 5).

* A bag copied without its run folder replays from the MPC parameters it carries
  (the MCAP attachment ``params/inertial_morphing_mpc.yaml``), every setpoint
  identical; a bag that carries none (and has no ``params/`` beside it) is
  refused with a message, never replayed with default parameters.
* Equal log times: a bag whose every setpoint is logged before the state, inertia
  and gait messages of its own tick (a valid order the recorder can produce, which
  stopped the log-order replay: "the replayed MPC did not answer t = 2.780 s")
  replays identically: inputs are fed by their stamps.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import rclpy

from splitter_bag import BagWriter, read_messages, read_metadata
from splitter_bag.core.definitions import header_stamp_ns
from splitter_bag.core.reader import read_attachments
from splitter_bringup.run.inprocess import record_graph
from splitter_bringup.run.replay import ReplayError, replay_mpc
from splitter_bringup.scenario.definition import load_scenario
from splitter_bringup.scenario.graph_config import graph_nodes, with_parameter_attachments
from splitter_msgs_py import names

TEST_DOMAIN_ID = int(os.environ["ROS_DOMAIN_ID"])  # set by the root conftest.py
REPLAY_DOMAIN_ID = TEST_DOMAIN_ID + 13  # <= MAX_DOMAIN_OFFSET
RECORD_S = 1.0  # [s] simulated time recorded
STATE_TOPICS = (names.IMU, names.INERTIA)


@pytest.fixture(scope="module")
def recorded_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """spin_stabilization through the in-process graph, recorded with the nodes' parameters."""
    bag_dir = tmp_path_factory.mktemp("run") / "bag"
    scenario = load_scenario("spin_stabilization")
    nodes = with_parameter_attachments(graph_nodes(scenario, bag_dir=bag_dir))
    recorder_params = next(n.parameters for n in nodes if n.name == "recorder")
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=TEST_DOMAIN_ID)
    try:
        record_graph(scenario, context, recorder_params, RECORD_S)
    finally:
        context.try_shutdown()
    assert not (bag_dir.parent / "params").exists()  # only the bag carries the parameters
    return bag_dir


def replay(bag_dir: Path, **kwargs):
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=REPLAY_DOMAIN_ID)
    try:
        return replay_mpc(bag_dir, context, **kwargs)
    finally:
        context.try_shutdown()


def rewrite(bag_dir: Path, out_dir: Path, order_key=None, attachments: bool = True) -> None:
    """Copy ``bag_dir`` to ``out_dir``: messages in ``order_key`` order, attachments or not."""
    types = {t.topic_metadata.name: t for t in read_metadata(bag_dir).topics_with_message_count}
    messages = list(read_messages(bag_dir))
    if order_key is not None:
        messages = [m for _, m in sorted(enumerate(messages), key=lambda im: order_key(*im))]
    with BagWriter(out_dir) as bag:
        if attachments:
            for name, data in read_attachments(bag_dir).items():
                bag.add_attachment(name, data, "application/yaml")
        for topic, info in types.items():
            meta = info.topic_metadata
            bag.add_topic(
                topic,
                meta.type,
                meta.offered_qos_profiles,
                type_description_hash=meta.type_description_hash,
            )
        for m in messages:
            bag.write(m.topic, m.data, m.log_time_ns, m.publish_time_ns)


@pytest.mark.slow
def test_a_bag_alone_replays_from_the_parameters_it_carries(recorded_bag, tmp_path) -> None:
    alone = tmp_path / "copied" / "bag"
    shutil.copytree(recorded_bag, alone)
    result = replay(alone)
    assert "attachment params/inertial_morphing_mpc.yaml" in result.parameters_source
    acc = result.account()
    assert acc.ticks >= 0.95 * RECORD_S / 0.01
    assert acc.identical == acc.ticks and acc.skipped_ticks == 0
    assert acc.accounted_for and acc.max_abs_diff_kg_m2 == 0.0


@pytest.mark.slow
def test_a_bag_without_parameters_is_refused_not_replayed_with_defaults(
    recorded_bag, tmp_path
) -> None:
    bare = tmp_path / "bare" / "bag"
    rewrite(recorded_bag, bare, attachments=False)
    assert read_attachments(bare) == {}
    with pytest.raises(ReplayError, match="carries no parameters of the MPC") as caught:
        replay(bare)
    assert "not replaying with default parameters" in str(caught.value)
    assert "--params" in str(caught.value)
    # a params/ folder beside it (a bag recorded before the attachment) still replays
    (bare.parent / "params").mkdir()
    (bare.parent / "params" / "inertial_morphing_mpc.yaml").write_bytes(
        read_attachments(recorded_bag)["params/inertial_morphing_mpc.yaml"]
    )
    result = replay(bare, end_s=0.3)
    assert result.parameters_source.endswith("params/inertial_morphing_mpc.yaml")
    assert result.account().identical == result.account().ticks > 0


@pytest.mark.slow
def test_setpoints_logged_before_their_own_inputs_replay_identically(
    recorded_bag, tmp_path
) -> None:
    def setpoints_first(index: int, m) -> tuple[int, int, int]:
        return (m.log_time_ns, 0 if m.topic == names.INERTIA_SETPOINT else 1, index)

    reordered = tmp_path / "reordered" / "bag"
    rewrite(recorded_bag, reordered, order_key=setpoints_first)
    # the bag holds the order that stopped the log-order replay: the setpoint of
    # tick t before the state of tick t (same log time)
    seen_state: set[int] = set()
    early = 0
    for m in read_messages(reordered, topics=(names.INERTIA_SETPOINT, *STATE_TOPICS)):
        stamp = header_stamp_ns(m.data)
        if m.topic == names.INERTIA_SETPOINT:
            early += stamp not in seen_state
        else:
            seen_state.add(stamp)
    ticks = sum(1 for _ in read_messages(reordered, topics=(names.INERTIA_SETPOINT,)))
    assert early == ticks > 0
    acc = replay(reordered).account()
    assert acc.ticks == ticks
    assert acc.identical == ticks and acc.accounted_for
    assert np.isfinite(acc.max_abs_diff_kg_m2) and acc.max_abs_diff_kg_m2 == 0.0
