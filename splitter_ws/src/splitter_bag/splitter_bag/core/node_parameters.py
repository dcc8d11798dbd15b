"""The nodes' parameters stored in a bag: one MCAP attachment per node. ROS-free.

A bag written by the project's recorder carries, for every node the launcher
started with it, that node's ROS 2 parameter file as an MCAP attachment named
``params/<node>.yaml`` (media type ``application/yaml``): the very text of the
run folder's ``params/<node>.yaml``, so the bag alone says how its nodes ran
(``splitter replay`` re-runs the MPC from it). rosbag2 ignores attachments
(``ros2 bag info`` and ``ros2 bag play`` are unaffected); the ``mcap`` CLI shows
them (``mcap list attachments BAG_0.mcap``, ``mcap get attachment --name
params/inertial_morphing_mpc.yaml BAG_0.mcap``) and the extracted file is a
valid ``--params-file``.

The parameters are those the node was started with (its overrides, as in the
run folder); a parameter left at its default is not listed, and a change made
while the node ran is not in the attachment.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import yaml

from splitter_bag.core.reader import read_attachments

ATTACHMENT_PREFIX = "params/"
MEDIA_TYPE = "application/yaml"


class ParameterFileError(ValueError):
    """Text that is not a ROS 2 parameter file of exactly one node."""


def attachment_name(node: str) -> str:
    """``params/<node>.yaml``: the attachment holding ``node``'s parameter file."""
    return f"{ATTACHMENT_PREFIX}{node}.yaml"


def parameter_file_text(node: str, parameters: Mapping[str, Any]) -> str:
    """``node``'s parameters as a ROS 2 parameter file (YAML text)."""
    return yaml.safe_dump({node: {"ros__parameters": dict(parameters)}}, sort_keys=True)


def parse_parameter_file(text: str) -> tuple[str, dict[str, Any]]:
    """(node name, parameters) of a one-node ROS 2 parameter file; ParameterFileError if not."""
    try:
        content = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ParameterFileError(f"not YAML: {exc}") from exc
    if not isinstance(content, dict) or len(content) != 1:
        raise ParameterFileError("expected one node: {NODE: {ros__parameters: {...}}}")
    ((node, body),) = content.items()
    params = body.get("ros__parameters") if isinstance(body, dict) else None
    if not isinstance(node, str) or not node or not isinstance(params, dict):
        raise ParameterFileError(f"{node!r}: expected {{ros__parameters: {{...}}}}")
    return node, dict(params)


def read_parameter_file(path: Path) -> tuple[str, dict[str, Any]]:
    """(node name, parameters) of a parameter file on disk."""
    try:
        return parse_parameter_file(Path(path).read_text(encoding="utf-8"))
    except ParameterFileError as exc:
        raise ParameterFileError(f"{path}: {exc}") from exc


def bag_node_parameters(bag_dir: Path | str) -> dict[str, dict[str, Any]]:
    """node -> parameters of every ``params/<node>.yaml`` attachment of the bag."""
    out = {}
    for name, data in read_attachments(bag_dir).items():
        if name.startswith(ATTACHMENT_PREFIX) and name.endswith(".yaml"):
            try:
                node, params = parse_parameter_file(data.decode("utf-8"))
            except (ParameterFileError, UnicodeDecodeError) as exc:
                raise ParameterFileError(f"{bag_dir}: attachment {name}: {exc}") from exc
            out[node] = params
    return out
