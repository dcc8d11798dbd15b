"""Message definitions and type hashes of ROS types, as rosbag2 stores them in a bag.

ROS-free (reads the installed ``share/<pkg>/msg`` files, never imports rclpy).

* :func:`message_definition` concatenates a type's ``.msg`` text with every type it
  depends on, as rosbag2_cpp's ``LocalMessageDefinitionSource::get_full_text``
  (Jazzy) does: the root text first, then, depth first and in sorted order of the
  dependency names as written in the field declarations, ``"\\n"``, a line of 80
  ``=``, ``MSG: <name>`` and the dependency's text; each dependency once. The
  schema encoding is ``ros2msg`` (``ros2idl`` when only ``.idl`` files exist).
* :func:`type_description_hash` is the REP-2011 ``RIHS01_`` hash of the type
  description, read from ``share/<pkg>/msg/<Type>.json`` and recomputed from the
  description when the file does not carry it.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import json
import logging
import re
import struct
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

_log = logging.getLogger(__name__)

DELIMITER = "=" * 80 + "\n"
MAX_RECURSION_DEPTH = 50  # ROSBAG2_CPP_LOCAL_MESSAGE_DEFINITION_SOURCE_MAX_RECURSION_DEPTH
_PACKAGE_TYPENAME = re.compile(r"^([a-zA-Z0-9_]+)/(?:msg/|srv/)?([a-zA-Z0-9_]+)$")
# Field types in .msg text ("foo_msgs/Bar" in "foo_msgs/Bar[] bar"); no MULTILINE, like std::regex.
_MSG_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_IDL_FIELD_TYPE = re.compile(r"(?:^|\n)#include\s+(?:\"|<)([a-zA-Z0-9_/]+)\.idl(?:\"|>)")
_PRIMITIVE_TYPES = frozenset(
    (
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
    )
)
HEADER_TYPES = frozenset(("std_msgs/Header", "std_msgs/msg/Header"))


class DefinitionNotFoundError(LookupError):
    """No ``.msg`` / ``.idl`` file for a type in any installed ``share`` directory."""


@dataclass(frozen=True)
class MessageDefinition:
    """What an MCAP schema record holds for a topic type."""

    topic_type: str
    encoding: str  # "ros2msg", "ros2idl" or "unknown"
    encoded_message_definition: str


def split_type_name(type_name: str) -> tuple[str, str]:
    """(package, Type) of ``pkg/msg/Type`` or ``pkg/Type``."""
    match = _PACKAGE_TYPENAME.match(type_name)
    if match is None:
        raise ValueError(f"type name {type_name!r} is not 'pkg/msg/Type'")
    return match.group(1), match.group(2)


@functools.cache
def package_share_directory(package: str) -> Path:
    """``share/<package>`` from the ament index, else under the running Python prefix."""
    try:
        from ament_index_python.packages import (
            PackageNotFoundError,
            get_package_share_directory,
        )
    except ImportError:
        pass
    else:
        try:
            return Path(get_package_share_directory(package))
        except (PackageNotFoundError, OSError):  # OSError: AMENT_PREFIX_PATH unset
            pass
    candidate = Path(sys.prefix) / "share" / package
    if candidate.is_dir():
        return candidate
    raise DefinitionNotFoundError(f"package {package!r} not found (AMENT_PREFIX_PATH, sys.prefix)")


def _interface_file(type_name: str, extension: str) -> Path:
    package, name = split_type_name(type_name)
    folder = "srv" if extension == ".srv" else "msg"
    path = package_share_directory(package) / folder / f"{name}{extension}"
    if not path.is_file():
        raise DefinitionNotFoundError(f"{path} does not exist")
    return path


def parse_msg_dependencies(text: str, package_context: str) -> set[str]:
    """Non-primitive field types of a ``.msg`` text, qualified with the package if bare."""
    deps = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        type_name = match.group(1)
        if type_name in _PRIMITIVE_TYPES:
            continue
        deps.add(type_name if "/" in type_name else f"{package_context}/{type_name}")
    return deps


@functools.cache
def _load(type_name: str, extension: str) -> tuple[str, tuple[str, ...]]:
    path = _interface_file(type_name, extension)
    text = path.read_text(encoding="utf-8")
    package, _ = split_type_name(type_name)
    if extension == ".idl":
        deps = {m.group(1) for m in _IDL_FIELD_TYPE.finditer(text)}
    else:
        deps = parse_msg_dependencies(text, package)
    return text, tuple(sorted(deps))


def _full_text(root: str, extension: str, tag: str) -> str:
    seen: set[str] = set()

    def append(type_name: str, depth: int) -> str:
        if depth <= 0:
            raise RecursionError(f"reached max recursion depth resolving definition of {root}")
        text, deps = _load(type_name, extension)
        out = [text]
        for dep in deps:
            if dep not in seen:
                seen.add(dep)
                out.append(f"\n{DELIMITER}{tag}: {dep}\n")
                out.append(append(dep, depth - 1))
        return "".join(out)

    return append(root, MAX_RECURSION_DEPTH)


@functools.cache
def message_definition(type_name: str) -> MessageDefinition:
    """The concatenated definition rosbag2 writes into the MCAP schema of ``type_name``.

    Falls back to IDL when there is no ``.msg`` file, and to an empty definition
    with encoding ``unknown`` (logged) when there is neither, as rosbag2 does.
    """
    try:
        split_type_name(type_name)
    except ValueError:
        _log.error("message type name %r not understood; definition left empty", type_name)
        return MessageDefinition(type_name, "unknown", "")
    try:
        return MessageDefinition(type_name, "ros2msg", _full_text(type_name, ".msg", "MSG"))
    except DefinitionNotFoundError as exc:
        _log.warning("no .msg definition for %s (%s), falling back to IDL", type_name, exc)
    try:
        package, name = split_type_name(type_name)
        idl_root = f"{package}/msg/{name}"
        text = f"{DELIMITER}IDL: {idl_root}\n" + _full_text(idl_root, ".idl", "IDL")
        return MessageDefinition(type_name, "ros2idl", text)
    except DefinitionNotFoundError as exc:
        _log.warning("no definition found for %s (%s); schema left empty", type_name, exc)
        return MessageDefinition(type_name, "unknown", "")


def compute_type_hash(type_description_msg: dict[str, Any]) -> str:
    """REP-2011 ``RIHS01`` hash of a ``type_description_msg`` (rosidl's algorithm).

    The description without ``default_value`` fields, dumped as JSON with
    ``", "`` / ``": "`` separators and ASCII escapes, hashed with SHA-256.
    """
    hashable = copy.deepcopy(type_description_msg)
    for description in (hashable["type_description"], *hashable["referenced_type_descriptions"]):
        for f in description["fields"]:
            f.pop("default_value", None)
    text = json.dumps(hashable, ensure_ascii=True, separators=(", ", ": "), allow_nan=False)
    return "RIHS01_" + hashlib.sha256(text.encode("utf-8")).hexdigest()


@functools.cache
def type_description_hash(type_name: str) -> str:
    """``RIHS01_...`` of ``pkg/msg/Type`` from its installed ``.json``; "" when unknown."""
    try:
        package, name = split_type_name(type_name)
        path = _interface_file(f"{package}/msg/{name}", ".json")
    except (ValueError, DefinitionNotFoundError) as exc:
        _log.warning("no type description for %s: %s", type_name, exc)
        return ""
    data = json.loads(path.read_text(encoding="utf-8"))
    full_name = f"{package}/msg/{name}"
    for entry in data.get("type_hashes", ()):
        if entry.get("type_name") == full_name:
            return str(entry["hash_string"])
    return compute_type_hash(data["type_description_msg"])


def _first_field_type(text: str) -> str | None:
    for line in text.splitlines():
        code = line.split("#", 1)[0].strip()
        if not code:
            continue
        type_name, _, rest = code.partition(" ")
        if "=" in rest:  # a constant takes no room in the message
            continue
        return type_name
    return None


@functools.cache
def starts_with_header(type_name: str) -> bool:
    """True when the first field of ``type_name`` is a ``std_msgs/Header``."""
    try:
        package, _ = split_type_name(type_name)
        text, _ = _load(type_name, ".msg")
    except (ValueError, DefinitionNotFoundError):
        return False
    first = _first_field_type(text)
    if first is None:
        return False
    return first in HEADER_TYPES or (package == "std_msgs" and first == "Header")


def header_stamp_ns(cdr: bytes) -> int | None:
    """``header.stamp`` [ns] of a CDR message whose first field is a Header, or None.

    The stamp (int32 sec, uint32 nanosec) follows the 4-byte encapsulation header.
    """
    if len(cdr) < 12:
        return None
    kind = cdr[1]
    if kind in (0, 2):  # CDR_BE, PL_CDR_BE
        sec, nanosec = struct.unpack_from(">iI", cdr, 4)
    elif kind in (1, 3):  # CDR_LE, PL_CDR_LE
        sec, nanosec = struct.unpack_from("<iI", cdr, 4)
    else:
        return None
    t_ns = sec * 1_000_000_000 + nanosec
    return t_ns if t_ns >= 0 else None
