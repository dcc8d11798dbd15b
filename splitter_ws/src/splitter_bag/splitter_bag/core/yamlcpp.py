"""A YAML emitter that lays documents out the way yaml-cpp does.

rosbag2 writes ``metadata.yaml``, the ``rosbag2`` MCAP metadata record and the
channels' ``offered_qos_profiles`` with yaml-cpp's emitter (block style, two
spaces, sequences indented under their key, ``~`` for null, ``""`` for the empty
string, no final newline). Emitting the same layout makes our files identical
to rosbag2's, not merely equivalent. Only the node kinds rosbag2 uses are
supported: mappings with string keys, sequences, str, int, bool and None.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence

import yaml

YamlValue = Mapping[str, "YamlValue"] | Sequence["YamlValue"] | str | int | bool | None

_INDENT = 2


def _scalar(value: str | int | bool | None) -> str:
    if value is None:
        return "~"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return _string(value)
    raise TypeError(f"cannot emit {type(value).__name__} as YAML")


def _string(text: str) -> str:
    """Plain when it reads back as the same string, double-quoted (JSON escapes) otherwise."""
    plain_ok = (
        text != ""
        and text == text.strip()
        and "\n" not in text
        and not text.startswith(("-", "?", ":", ",", "[", "]", "{", "}", "#", "&", "*", "!"))
        and not text.startswith(("|", ">", "'", '"', "%", "@", "`"))
        and ": " not in text
        and " #" not in text
        and not text.endswith(":")
    )
    if plain_ok:
        try:
            plain_ok = yaml.safe_load(text) == text
        except yaml.YAMLError:
            plain_ok = False
    return text if plain_ok else json.dumps(text, ensure_ascii=False)


def _is_block(value: object) -> bool:
    return isinstance(value, Mapping | list | tuple) and len(value) > 0


def _empty_collection(value: object) -> str | None:
    if isinstance(value, Mapping) and not value:
        return "{}"
    if isinstance(value, list | tuple) and not value:
        return "[]"
    return None


def _emit(value: YamlValue, indent: int, lines: list[str], first_prefix: str | None) -> None:
    """Append ``value`` as a block at ``indent``; ``first_prefix`` replaces the first indent."""
    pad = " " * indent

    def start(i: int) -> str:
        return first_prefix if (i == 0 and first_prefix is not None) else pad

    if isinstance(value, Mapping):
        for i, (key, item) in enumerate(value.items()):
            head = f"{start(i)}{_string(str(key))}:"
            if _is_block(item):
                lines.append(head)
                _emit(item, indent + _INDENT, lines, None)
            elif (empty := _empty_collection(item)) is not None:
                lines.append(head)
                lines.append(" " * (indent + _INDENT) + empty)
            else:
                lines.append(f"{head} {_scalar(item)}")  # type: ignore[arg-type]
        return
    if isinstance(value, list | tuple):
        for i, item in enumerate(value):
            dash = f"{start(i)}- "
            if _is_block(item):
                _emit(item, indent + _INDENT, lines, dash)
            elif (empty := _empty_collection(item)) is not None:
                lines.append(dash + empty)
            else:
                lines.append(dash + _scalar(item))  # type: ignore[arg-type]
        return
    lines.append(start(0) + _scalar(value))


def dump(value: YamlValue) -> str:
    """``value`` as yaml-cpp's ``YAML::Dump`` writes it (no trailing newline)."""
    if (empty := _empty_collection(value)) is not None:
        return empty
    lines: list[str] = []
    _emit(value, 0, lines, None)
    return "\n".join(lines)
