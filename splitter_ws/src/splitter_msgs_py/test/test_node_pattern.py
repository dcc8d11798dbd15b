"""The house's node pattern: run_node's exit codes, stamp admission, parameters from configs."""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from rclpy.node import Node

from splitter_msgs_py.core.parameter_fields import parameter_field, parameter_fields
from splitter_msgs_py.core.stamps import MessageValidationError, StampGate
from splitter_msgs_py.node_pattern import run_node
from splitter_msgs_py.parameters import (
    InvalidParameterError,
    config_from_values,
    specs_from_config,
)


@dataclass(frozen=True)
class _Config:
    gain: float = parameter_field(2.0, "a gain [-]", min_value=0.0, max_value=10.0, live=True)
    axis: tuple[float, float, float] = parameter_field((0.0, 0.0, 1.0), "an axis [-]", length=3)
    mode: str = parameter_field("a", "a mode", choices=("a", "b"))
    internal: int = 7  # not a parameter

    def __post_init__(self) -> None:
        if self.axis == (0.0, 0.0, 0.0):
            raise ValueError("axis must not be zero")


def test_specs_come_from_the_config_fields():
    specs = {s.name: s for s in specs_from_config(_Config)}
    assert set(specs) == {"gain", "axis", "mode"}
    assert specs["gain"].live and specs["gain"].max_value == 10.0
    assert specs["axis"].default == [0.0, 0.0, 1.0] and specs["axis"].length == 3
    assert not specs["mode"].live and specs["mode"].choices == ("a", "b")
    assert [n for n, _, _ in parameter_fields(_Config)] == ["gain", "axis", "mode"]
    assert {s.name for s in specs_from_config(_Config, exclude=("mode",))} == {"gain", "axis"}
    assert specs_from_config(_Config, live=("mode",))[2].live


def test_config_from_values_converts_arrays_and_names_a_refused_value():
    config = config_from_values(_Config, {"gain": 3.0, "axis": [1.0, 0.0, 0.0]}, internal=9)
    assert config == _Config(gain=3.0, axis=(1.0, 0.0, 0.0), mode="a", internal=9)
    with pytest.raises(InvalidParameterError, match="_Config: axis must not be zero"):
        config_from_values(_Config, {"axis": [0.0, 0.0, 0.0]})


def test_stamp_gate_admit_applies_every_rule():
    gate = StampGate(max_lead_ns=100)
    assert gate.admit("a", 10) == 10
    with pytest.raises(MessageValidationError, match="earlier than the last accepted"):
        gate.admit("a", 9)
    with pytest.raises(MessageValidationError, match="ahead of the node's time"):
        gate.admit("b", 200, clock_ns=lambda: 20)
    with pytest.raises(MessageValidationError, match="earlier than the last tick answered"):
        gate.admit("b", 15, not_before_ns=20)
    assert gate.last_ns("b") is None  # refused stamps change nothing
    assert gate.admit("b", 20, not_before_ns=20) == 20
    assert gate.latest_ns == 20


class _FinishedNode(Node):
    def __init__(self, error: bool) -> None:
        super().__init__("node_pattern_test")
        self.error = error
        self.reported = False


def test_run_node_exit_codes_and_last_report():
    def refuse(stop):
        raise InvalidParameterError("parameter 'gain' must be >= 0, got -1")

    assert run_node(refuse, "refusing", args=[]) == 1

    seen = []

    def report(node):
        seen.append(node.get_name())

    code = run_node(
        lambda stop: _FinishedNode(error=True),
        "finishing",
        args=[],
        spin=lambda node, stop: None,
        exit_code=lambda node: 1 if node.error else 0,
        before_destroy=report,
    )
    assert code == 1 and seen == ["node_pattern_test"]
    assert run_node(lambda stop: _FinishedNode(error=False), "ok", [], spin=lambda n, s: None) == 0
