"""The stamp rules every node applies to its inputs. ROS-free.

A message's ``header.stamp`` is simulated time in integer nanoseconds. A node
accepts a stamp only when it does not go backwards on its topic, does not run far
ahead of the node's time, and (for inputs that answer a control tick) is not
before the last tick the node already answered. :class:`StampGate` holds those
rules for one node; :meth:`StampGate.admit` applies them all and records the stamp.
"""

from __future__ import annotations

from collections.abc import Callable


class MessageValidationError(ValueError):
    """A message field that is non-finite, of the wrong size, or otherwise invalid."""


# [ns] how far a message stamp may run ahead of the latest time a node knows (the
# newest stamp it accepted, or its clock) before it is rejected as corrupt: a stamp
# accepted that far ahead would make every later, correct message look out of order.
MAX_STAMP_LEAD_NS = 1_000_000_000
ClockNs = int | Callable[[], int | None] | None  # [ns] a node's time, or a function giving it


def refusal_answers_tick(publishers_on_topic: int | None) -> bool:
    """Whether an input refused for its contents (its stamp good) still answers its tick.

    In lockstep a node answers each tick once every input of it arrived, and a message
    with bad contents answers it from the last good data, so that one bad message
    does not stall the loop. That holds while the graph's own node is the topic's
    only publisher (``publishers_on_topic`` 0 or 1, None: not known). With another
    publisher on the topic, a refused message may be a stranger's, stamped at a tick
    whose real input is still on its way: answering it would step past that input,
    which then arrives late. The tick waits for a good message (or the node's timeout).
    """
    return publishers_on_topic is None or publishers_on_topic <= 1


def clock_value(clock_ns: ClockNs) -> int | None:
    """The time [ns] ``clock_ns`` gives (calling it if it is a function)."""
    return clock_ns() if callable(clock_ns) else clock_ns


class StampGate:
    """Checks the stamps of a node's inputs: never backwards on a topic, never far ahead.

    Per topic, a stamp earlier than the last one accepted is rejected (out of order,
    or a stamp of 0 once time has advanced); an equal one is accepted (a repeat of
    the same tick). Across topics, a stamp more than ``max_lead_ns`` beyond the
    node's time (the newest stamp accepted on any topic, or ``clock_ns`` if later)
    is rejected. The very first stamp of a node that has no clock has nothing to be
    compared with and is accepted. Rejections raise :class:`MessageValidationError`
    and change nothing; :meth:`accept` records a stamp once the node acted on it.
    """

    def __init__(self, max_lead_ns: int = MAX_STAMP_LEAD_NS) -> None:
        if int(max_lead_ns) < 0:
            raise ValueError(f"max_lead_ns must be >= 0, got {max_lead_ns}")
        self.max_lead_ns = int(max_lead_ns)
        self._last: dict[str, int] = {}
        self._latest: int | None = None

    @property
    def latest_ns(self) -> int | None:
        """The newest stamp accepted on any topic [ns], None before any."""
        return self._latest

    def last_ns(self, topic: str) -> int | None:
        """The last stamp accepted on ``topic`` [ns], None before any."""
        return self._last.get(topic)

    def check(self, topic: str, t_ns: int, clock_ns: ClockNs = None) -> int:
        """``t_ns`` when it may be accepted on ``topic``; ``MessageValidationError`` if not.

        ``clock_ns`` may be a function returning it: it is then called only when the
        newest accepted stamp alone would not admit ``t_ns`` (reading a node's clock
        costs more than the rest of the check).
        """
        t_ns = int(t_ns)
        if t_ns < 0:
            raise MessageValidationError(f"header.stamp: negative time {t_ns} ns")
        last = self._last.get(topic)
        if last is not None and t_ns < last:
            raise MessageValidationError(
                f"header.stamp: {t_ns * 1e-9:.9f} s is earlier than the last accepted "
                f"{last * 1e-9:.9f} s (out of order, or time restarted)"
            )
        latest = self._latest
        if latest is not None and t_ns <= latest + self.max_lead_ns:
            return t_ns  # within the lead of the newest stamp: the clock cannot refuse it
        references = [v for v in (clock_value(clock_ns), latest) if v is not None]
        if references:
            now = max(references)
            if t_ns > now + self.max_lead_ns:
                raise MessageValidationError(
                    f"header.stamp: {t_ns * 1e-9:.9f} s is more than "
                    f"{self.max_lead_ns * 1e-9:g} s ahead of the node's time {now * 1e-9:.9f} s"
                )
        return t_ns

    def accept(self, topic: str, t_ns: int) -> None:
        """Record ``t_ns`` (checked) as the last stamp of ``topic``."""
        t_ns = max(int(t_ns), self._last.get(topic, 0))
        self._last[topic] = t_ns
        self._latest = t_ns if self._latest is None else max(self._latest, t_ns)

    def admit(
        self, topic: str, t_ns: int, clock_ns: ClockNs = None, not_before_ns: int | None = None
    ) -> int:
        """Check ``t_ns`` (:meth:`check`, and not before ``not_before_ns``), then accept it.

        ``not_before_ns``: the last control tick the node answered, for inputs that
        answer a tick (a message for a tick already answered is stale).
        """
        t_ns = self.check(topic, t_ns, clock_ns)
        if not_before_ns is not None and t_ns < not_before_ns:
            raise MessageValidationError(
                f"header.stamp: {t_ns * 1e-9:.9f} s is earlier than the last tick "
                f"answered {not_before_ns * 1e-9:.9f} s"
            )
        self.accept(topic, t_ns)
        return t_ns
