"""Parameters are declared with descriptors and an invalid one names itself.

At runtime a start-up parameter is refused as read-only and a live one is
validated (refused with a reason) and applied through the node's handler.
"""

from __future__ import annotations

import math

import pytest
import rclpy
from rclpy.parameter import Parameter

from splitter_msgs_py.parameters import (
    InvalidParameterError,
    ParameterSpec,
    declare_parameters,
    live_parameter_values,
    parameter_diagnostics,
    rejection_counts,
    warn_throttled,
)

SPECS = [
    ParameterSpec("rate_hz", 100.0, "publish rate [Hz]", min_value=1.0, max_value=1000.0),
    ParameterSpec("horizon", 50, "prediction steps", min_value=1, max_value=500),
    ParameterSpec("solver", "ipopt", "NLP solver", choices=("ipopt", "fatrop")),
    ParameterSpec("w_ref", [0.0, 1.0, 0.0], "reference [rad/s]", length=3),
    ParameterSpec("enabled", True, "controller on"),
]


def make_node(context, overrides: list[Parameter]):
    return rclpy.create_node("param_test", context=context, parameter_overrides=overrides)


def test_defaults_and_descriptors(ros_context) -> None:
    node = make_node(ros_context, [])
    try:
        values = declare_parameters(node, SPECS)
        assert values == {
            "rate_hz": 100.0,
            "horizon": 50,
            "solver": "ipopt",
            "w_ref": [0.0, 1.0, 0.0],
            "enabled": True,
        }
        desc = node.describe_parameter("rate_hz")
        assert "publish rate" in desc.description
        assert desc.floating_point_range[0].to_value == 1000.0
    finally:
        node.destroy_node()


@pytest.mark.parametrize(
    ("override", "name"),
    [
        (Parameter("rate_hz", value=0.0), "rate_hz"),
        (Parameter("rate_hz", value=float("nan")), "rate_hz"),
        (Parameter("horizon", value=0), "horizon"),
        (Parameter("solver", value="snopt"), "solver"),
        (Parameter("w_ref", value=[0.0, 1.0]), "w_ref"),
        (Parameter("enabled", value="yes"), "enabled"),
    ],
)
def test_invalid_parameter_names_itself(ros_context, override: Parameter, name: str) -> None:
    node = make_node(ros_context, [override])
    try:
        with pytest.raises(InvalidParameterError, match=f"'{name}'"):
            declare_parameters(node, SPECS)
    finally:
        node.destroy_node()


def test_integer_accepted_for_float(ros_context) -> None:
    node = make_node(ros_context, [Parameter("rate_hz", value=200)])
    try:
        assert declare_parameters(node, SPECS)["rate_hz"] == 200.0
    finally:
        node.destroy_node()


def test_warn_throttled_counts_every_rejection(ros_context) -> None:
    node = make_node(ros_context, [])
    try:
        for _ in range(5):
            warn_throttled(node, "nan_command", "rejected a NaN command")
        warn_throttled(node, "unknown_joint", "rejected an unknown joint")
        assert rejection_counts(node) == {"nan_command": 5, "unknown_joint": 1}
    finally:
        node.destroy_node()


def test_empty_list_from_a_parameter_file(ros_context, tmp_path) -> None:
    params = tmp_path / "p.yaml"
    params.write_text("param_test:\n  ros__parameters:\n    jump_times_s: []\n")
    node = rclpy.create_node(
        "param_test",
        context=ros_context,
        cli_args=["--ros-args", "--params-file", str(params)],
    )
    try:
        values = declare_parameters(node, [ParameterSpec("jump_times_s", [0.0], "jump times")])
        assert values["jump_times_s"] == []
    finally:
        node.destroy_node()


def test_string_arrays(ros_context) -> None:
    spec = ParameterSpec("wait_for", [], "node names", item_type=str)
    node = make_node(ros_context, [Parameter("wait_for", value=["recorder", "mpc"])])
    try:
        assert declare_parameters(node, [spec])["wait_for"] == ["recorder", "mpc"]
    finally:
        node.destroy_node()
    node = make_node(ros_context, [Parameter("wait_for", value=[1.0])])
    try:
        with pytest.raises(InvalidParameterError, match="'wait_for'"):
            declare_parameters(node, [spec])
    finally:
        node.destroy_node()


LIVE_SPECS = [
    ParameterSpec("gain", 1.0, "a live gain [-]", min_value=0.0, max_value=10.0, live=True),
    ParameterSpec("weights", [1.0, 2.0, 3.0], "live weights", 0.0, 1e3, length=3, live=True),
    ParameterSpec("mode", "a", "a live choice", choices=("a", "b"), live=True),
    ParameterSpec("steps", 5, "a live integer", min_value=1, max_value=100, live=True),
    ParameterSpec("flag", False, "a live switch", live=True),
    ParameterSpec("dt_s", 0.01, "read at start-up [s]", min_value=1e-3, max_value=1.0),
]


def live_node(context, applied: list[dict], refuse_above: float = math.inf):
    node = make_node(context, [])

    def apply(values) -> None:
        if values["gain"] > refuse_above:
            raise ValueError(f"gain above {refuse_above} needs a rebuild")
        applied.append(dict(values))

    declare_parameters(node, LIVE_SPECS, on_live_change=apply)
    return node


def set_one(node, name: str, value):
    return node.set_parameters([Parameter(name, value=value)])[0]


@pytest.mark.parametrize(
    ("name", "value", "reason"),
    [
        ("gain", "fast", "must be a number"),
        ("gain", float("nan"), "gain"),
        ("gain", 11.0, "gain"),
        ("gain", True, "must be a number"),
        ("gain", [1.0], "must be a number"),
        ("weights", [1.0, 2.0], "must have 3 values"),
        ("weights", [1.0, float("nan"), 3.0], "must be finite"),
        ("weights", [1.0, -2.0, 3.0], "must be >= 0.0"),
        ("weights", "1,2,3", "must be a list of numbers"),
        ("weights", [True, False, True], "must be a list of numbers"),
        ("mode", "c", "must be one of"),
        ("mode", 1.0, "must be a string"),
        ("steps", 2.5, "steps"),
        ("steps", 0, "steps"),
        ("flag", "yes", "must be a bool"),
    ],
)
def test_invalid_live_value_refused_with_a_reason(ros_context, name, value, reason) -> None:
    applied: list[dict] = []
    node = live_node(ros_context, applied)
    try:
        before = node.get_parameter(name).value
        result = set_one(node, name, value)
        assert not result.successful
        assert reason in result.reason
        assert node.get_parameter(name).value == before
        assert node.describe_parameter(name).type == node.get_parameter(name).type_.value
        assert applied == []
        assert parameter_diagnostics(node) == {"parameter_changes": 0}
    finally:
        node.destroy_node()


def test_valid_live_change_applied_logged_and_counted(ros_context) -> None:
    applied: list[dict] = []
    node = live_node(ros_context, applied)
    try:
        assert set_one(node, "gain", 2.5).successful
        assert applied[-1]["gain"] == 2.5
        # an integer for a float (array) is accepted and stored as the float it stands for
        assert set_one(node, "weights", [4, 5, 6]).successful
        assert node.get_parameter("weights").type_ == Parameter.Type.DOUBLE_ARRAY
        assert applied[-1]["weights"] == [4.0, 5.0, 6.0]
        assert set_one(node, "gain", 3).successful
        assert node.get_parameter("gain").value == 3.0
        assert set_one(node, "mode", "b").successful
        assert live_parameter_values(node)["mode"] == "b"
        assert parameter_diagnostics(node) == {
            "parameter_changes": 4,
            "last_parameter_change": "mode = b",
        }
    finally:
        node.destroy_node()


def test_change_the_node_cannot_apply_is_refused(ros_context) -> None:
    applied: list[dict] = []
    node = live_node(ros_context, applied, refuse_above=5.0)
    try:
        result = set_one(node, "gain", 6.0)
        assert not result.successful
        assert "'gain' not applied: gain above 5.0 needs a rebuild" in result.reason
        assert node.get_parameter("gain").value == 1.0
        assert live_parameter_values(node)["gain"] == 1.0
    finally:
        node.destroy_node()


def test_start_up_parameters_are_read_only(ros_context) -> None:
    node = live_node(ros_context, [])
    try:
        assert node.describe_parameter("dt_s").read_only
        assert "read-only" in node.describe_parameter("dt_s").description
        assert not node.describe_parameter("gain").read_only
        for value in (0.02, "x", float("nan")):
            result = set_one(node, "dt_s", value)
            assert not result.successful
            assert "read-only" in result.reason
        assert node.get_parameter("dt_s").value == 0.01
        # rclpy's use_sim_time: rclpy refuses a wrong type; a valid one would switch the
        # clock live, which the graph's launcher chose: refused too
        assert "Wrong parameter type" in set_one(node, "use_sim_time", 1.0).reason
        result = set_one(node, "use_sim_time", True)
        assert not result.successful
        assert "read at start-up" in result.reason
        assert node.get_parameter("use_sim_time").value is False
    finally:
        node.destroy_node()


def test_a_hand_declared_parameter_not_marked_read_only_is_refused(ros_context) -> None:
    node = live_node(ros_context, [])
    try:
        node.declare_parameter("extra", "x")  # declared after the callback: allowed
        result = set_one(node, "extra", "y")
        assert not result.successful
        assert "read at start-up only" in result.reason
    finally:
        node.destroy_node()


def test_live_spec_needs_a_handler(ros_context) -> None:
    node = make_node(ros_context, [])
    try:
        with pytest.raises(TypeError, match="on_live_change"):
            declare_parameters(node, LIVE_SPECS)
    finally:
        node.destroy_node()
