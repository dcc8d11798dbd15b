"""Bridge between rclpy QoS profiles and the bag's :class:`QosProfile` (imports rclpy).

The choices follow rosbag2_storage ``Rosbag2QoS``:

* a recorder requests reliable only if every publisher offers reliable, and
  transient local only if every publisher offers it (``adapt_request_to_offers``);
* a player offers the recorded profile when every recorded publisher offered the
  same compatibility-relevant policies, the default profile otherwise
  (``adapt_offer_to_recorded_offers``). The history depth is the player's own.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.topic_endpoint_info import TopicEndpointInfo

from splitter_bag.core.metadata import (
    DURABILITY_NAMES,
    DURATION_INFINITE_NS,
    HISTORY_NAMES,
    LIVELINESS_NAMES,
    RELIABILITY_NAMES,
    QosProfile,
)

_log = logging.getLogger(__name__)


def _duration_ns(duration: Duration) -> int:
    return min(int(duration.nanoseconds), DURATION_INFINITE_NS)


def _name(value: int, names: Sequence[str]) -> str:
    return names[int(value)] if 0 <= int(value) < len(names) else "unknown"


def qos_from_rclpy(profile: QoSProfile) -> QosProfile:
    """The bag's record of an rclpy profile (e.g. a publisher's offered QoS)."""
    return QosProfile(
        history=_name(profile.history, HISTORY_NAMES),
        depth=int(profile.depth),
        reliability=_name(profile.reliability, RELIABILITY_NAMES),
        durability=_name(profile.durability, DURABILITY_NAMES),
        deadline_ns=_duration_ns(profile.deadline),
        lifespan_ns=_duration_ns(profile.lifespan),
        liveliness=_name(profile.liveliness, LIVELINESS_NAMES),
        liveliness_lease_duration_ns=_duration_ns(profile.liveliness_lease_duration),
        avoid_ros_namespace_conventions=bool(profile.avoid_ros_namespace_conventions),
    )


def offered_qos_profiles(endpoints: Sequence[TopicEndpointInfo]) -> list[QosProfile]:
    """One profile per publisher, as rosbag2's recorder stores them."""
    return [qos_from_rclpy(e.qos_profile) for e in endpoints]


def type_hash_of(endpoints: Sequence[TopicEndpointInfo]) -> str | None:
    """The RIHS01 hash every publisher advertises, "" when they disagree, None when unknown."""
    hashes = {str(e.topic_type_hash) for e in endpoints}
    hashes.discard("")
    hashes = {h for h in hashes if h.startswith("RIHS01_")}
    if not hashes:
        return None
    if len(hashes) > 1:
        _log.warning("publishers disagree on the type hash: %s", sorted(hashes))
        return ""
    return hashes.pop()


def subscription_qos(endpoints: Sequence[TopicEndpointInfo], depth: int) -> QoSProfile:
    """A request compatible with every offer (``adapt_request_to_offers``), ``depth`` deep."""
    profiles = [e.qos_profile for e in endpoints]
    reliable = bool(profiles) and all(p.reliability == ReliabilityPolicy.RELIABLE for p in profiles)
    transient = bool(profiles) and all(
        p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles
    )
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE,
    )


def _compatibility_key(p: QosProfile) -> tuple[object, ...]:
    return (
        p.reliability,
        p.durability,
        p.deadline_ns,
        p.liveliness,
        p.liveliness_lease_duration_ns,
    )


def _policy(names: Sequence[str], value: str, enum: type, default: object) -> object:
    if value in names and value not in ("unknown", "best_available"):
        try:
            return enum(names.index(value))
        except ValueError:  # e.g. the deprecated manual_by_node liveliness
            pass
    return default


def _duration(ns: int) -> Duration:
    return Duration(nanoseconds=min(ns, DURATION_INFINITE_NS))


def publisher_qos(recorded: Sequence[QosProfile], depth: int, topic: str = "") -> QoSProfile:
    """What a player offers for a topic recorded with ``recorded`` offers."""
    default = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )
    if not recorded:
        return default
    if len({_compatibility_key(p) for p in recorded}) != 1:
        _log.warning("publishers of %s offered different QoS profiles; offering the default", topic)
        return default
    p = recorded[0]
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=_policy(
            RELIABILITY_NAMES, p.reliability, ReliabilityPolicy, ReliabilityPolicy.RELIABLE
        ),
        durability=_policy(
            DURABILITY_NAMES, p.durability, DurabilityPolicy, DurabilityPolicy.VOLATILE
        ),
        deadline=_duration(p.deadline_ns),
        lifespan=_duration(p.lifespan_ns),
        liveliness=_policy(
            LIVELINESS_NAMES, p.liveliness, LivelinessPolicy, LivelinessPolicy.AUTOMATIC
        ),
        liveliness_lease_duration=_duration(p.liveliness_lease_duration_ns),
        avoid_ros_namespace_conventions=p.avoid_ros_namespace_conventions,
    )
