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
"""

from __future__ import annotations

from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass, field

FOREIGN_PREFIX = "FOREIGN"  # the launcher matches "FOREIGN publisher <node> on <topic>: ..."


def qualified_name(namespace: str, name: str) -> str:
    """``/namespace/name`` as ROS prints it (``/name`` in the root namespace)."""
    return f"{namespace.rstrip('/')}/{name}" if namespace not in ("", "/") else f"/{name}"


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
    _ours: dict[tuple[str, str], bytes] = field(default_factory=dict, init=False)
    _reported: set[tuple[str, bytes]] = field(default_factory=set, init=False)

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
                if node not in self._names:
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
