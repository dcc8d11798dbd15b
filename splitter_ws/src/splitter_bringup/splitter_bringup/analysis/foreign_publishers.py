"""Publishers on the graph's topics that the graph did not start.

ROS-free: the watchdog node (and ``splitter launch --in-process``) hands
:class:`ForeignPublisherTracker` the publishers the ROS graph lists on each of the
graph's topics (node name and endpoint GID) and reports the new foreign ones:

* a publisher whose node is not one of the graph's (a ``ros2 topic pub``, a fault
  injector, a node of another project on this domain);
* a second publisher under the name of one of the graph's nodes on a topic: each of
  the graph's nodes has one publisher per topic, so a second one is another graph
  of this project on the same domain (the one the first to be seen is kept as
  ours).

While discovery is still matching an endpoint to its node, the rmw lists it under
the placeholder names ``_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_`` (two graphs
started at once on a loaded machine showed two such publishers of their own
nodes). Such an endpoint is looked at again on later updates and is foreign only
when it is still nameless after ``unknown_grace_updates`` of them (a DDS writer
that is no ROS node never gets a name).
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass, field

FOREIGN_PREFIX = "FOREIGN"  # the launcher matches "FOREIGN publisher <node> on <topic>: ..."
UNKNOWN_NODE_NAME = "_NODE_NAME_UNKNOWN_"  # rmw's name for an endpoint not matched to a node yet
UNKNOWN_NODE_NAMESPACE = "_NODE_NAMESPACE_UNKNOWN_"
UNKNOWN_GRACE_UPDATES = 5  # updates an endpoint may stay nameless before it is foreign


def qualified_name(namespace: str, name: str) -> str:
    """``/namespace/name`` as ROS prints it (``/name`` in the root namespace)."""
    return f"{namespace.rstrip('/')}/{name}" if namespace not in ("", "/") else f"/{name}"


def is_unnamed(node: str) -> bool:
    """True for the rmw's placeholder of an endpoint whose node discovery has not matched."""
    return UNKNOWN_NODE_NAME in node or UNKNOWN_NODE_NAMESPACE in node


@dataclass(frozen=True)
class ForeignPublisher:
    """A publisher the graph did not start."""

    topic: str
    node: str  # fully qualified node name
    gid: bytes
    reason: str

    def line(self) -> str:
        """The log line the launcher reads."""
        return f"{FOREIGN_PREFIX} publisher {self.node} on {self.topic}: {self.reason}"


@dataclass
class ForeignPublisherTracker:
    """Remembers every publisher seen; :meth:`update` returns the foreign ones seen first."""

    graph_nodes: Collection[str]  # the graph's node names (plain or fully qualified)
    found: list[ForeignPublisher] = field(default_factory=list)
    unknown_grace_updates: int = UNKNOWN_GRACE_UPDATES
    _ours: dict[tuple[str, str], bytes] = field(default_factory=dict, init=False)
    _reported: set[tuple[str, bytes]] = field(default_factory=set, init=False)
    _nameless: dict[tuple[str, bytes], int] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        self._names = {n if n.startswith("/") else f"/{n}" for n in self.graph_nodes}

    def update(
        self, publishers: Mapping[str, Iterable[tuple[str, bytes]]]
    ) -> list[ForeignPublisher]:
        """``publishers``: per topic, (fully qualified node name, endpoint GID) of each."""
        new = []
        for topic, endpoints in publishers.items():
            for node, gid in endpoints:
                if (topic, gid) in self._reported:
                    continue
                if is_unnamed(node):
                    seen = self._nameless.get((topic, gid), 0) + 1
                    self._nameless[(topic, gid)] = seen
                    if seen <= self.unknown_grace_updates:
                        continue  # discovery may still name it
                    reason = f"no ROS node owns it after {seen} looks (a plain DDS writer?)"
                elif node not in self._names:
                    reason = "not a node of this graph"
                else:
                    ours = self._ours.setdefault((topic, node), gid)
                    if ours == gid:
                        continue
                    reason = "a second publisher of that name: another graph on this ROS domain"
                self._reported.add((topic, gid))
                foreign = ForeignPublisher(topic, node, bytes(gid), reason)
                self.found.append(foreign)
                new.append(foreign)
        return new

    @property
    def count(self) -> int:
        """Foreign publishers seen so far."""
        return len(self.found)
