"""Parameters are declared with descriptors and an invalid one names itself."""

from __future__ import annotations

import pytest
import rclpy
from rclpy.parameter import Parameter

from splitter_msgs_py.parameters import (
    InvalidParameterError,
    ParameterSpec,
    declare_parameters,
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
