"""Inputs of a control tick gathered from several topics (the gait phase manager's tick).

Each input topic delivers one message per control tick, stamped with the tick; the
tick is answered once every input of it has arrived. :class:`TickAssembler` files
the messages under their tick and reports what happened:

* a tick completes when all of its inputs are in; older ticks still incomplete
  are skipped (a later tick completed first);
* a message for a tick already answered (late or repeated) is ignored;
* more than ``max_pending`` incomplete ticks: the oldest is dropped;
* a rejected input arrives as ``None``: it still counts for its tick, and
  :meth:`TickAssembler.samples` replaces it by the last good message of its topic.

ROS-free.
"""

from __future__ import annotations

from dataclasses import dataclass, field

MAX_PENDING_TICKS = 200  # ticks waiting for inputs before the oldest is dropped


@dataclass(frozen=True)
class TickEvents:
    """What one filed message did."""

    completed: tuple[int, dict[str, object | None]] | None = None  # (tick [ns], inputs)
    dropped: tuple[tuple[int, tuple[str, ...]], ...] = ()  # (tick [ns], topics it had)
    skipped: tuple[tuple[int, tuple[str, ...]], ...] = ()  # (tick [ns], topics it had)


@dataclass
class TickAssembler:
    """Files each topic's message under its tick; see the module doc."""

    period_ns: int
    inputs: tuple[str, ...]
    max_pending: int = MAX_PENDING_TICKS
    pending: dict[int, dict[str, object | None]] = field(default_factory=dict, init=False)
    last_good: dict[str, object] = field(default_factory=dict, init=False)
    last_tick_ns: int | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        if self.period_ns <= 0:
            raise ValueError(f"period_ns must be > 0, got {self.period_ns}")
        if not self.inputs:
            raise ValueError("a tick needs at least one input topic")

    def add(self, topic: str, t_ns: int, sample: object | None) -> TickEvents:
        """File ``sample`` (None: rejected) of ``topic`` stamped ``t_ns``."""
        if sample is not None:
            self.last_good[topic] = sample
        if t_ns % self.period_ns != 0:
            return TickEvents()
        if self.last_tick_ns is not None and t_ns <= self.last_tick_ns:
            return TickEvents()  # late or repeated: that tick is answered
        inputs = self.pending.setdefault(t_ns, {})
        inputs[topic] = sample
        dropped = ()
        if len(self.pending) > self.max_pending:
            oldest = min(self.pending)
            dropped = ((oldest, tuple(sorted(self.pending.pop(oldest)))),)
        if not all(name in inputs for name in self.inputs):
            return TickEvents(dropped=dropped)
        skipped = tuple(
            (stale, tuple(sorted(self.pending[stale])))
            for stale in sorted(self.pending)
            if stale < t_ns
        )
        for stale in [t for t in self.pending if t <= t_ns]:
            del self.pending[stale]
        self.last_tick_ns = t_ns
        return TickEvents(completed=(t_ns, inputs), dropped=dropped, skipped=skipped)

    def samples(self, inputs: dict[str, object | None]) -> dict[str, object | None]:
        """A completed tick's inputs, rejected ones replaced by their topic's last good one."""
        return {
            topic: inputs[topic] if inputs.get(topic) is not None else self.last_good.get(topic)
            for topic in self.inputs
        }
