"""How far ahead the allocator stamps its joint commands: the latency it measures, planned for.

A joint command is a point of a stamped, piecewise-linear joint trajectory: the
position at its stamp and the velocity until the next point. The simulator's
joint controllers follow it at its stamps (a point stamped in the future waits in
their queue, as a joint trajectory controller's does). In lockstep an input
stamped ``t`` is answered before the simulator leaves ``t``, so the answer is
stamped ``t``. In real time the simulator goes on stepping while the state
travels to the MPC, the MPC solves and its setpoint reaches the allocator: the
answer to the state of ``t`` cannot take effect before ``t + latency``. A command
stamped ``t`` would then arrive after its own stamp, and the joints would jump
to where its trajectory already is (the reel braking or pulling harder than the
plan: a slack tether).

:class:`CommandLead` measures that latency (the allocator's simulated clock when
an input is used, minus the input's stamp) and stamps each answer ``lead`` ahead:
``factor`` times the largest latency of the last ``window`` of simulated time plus
a margin for the way to the simulator, rounded up to whole control periods. The commands then
arrive before their stamps and the joints follow the allocator's trajectory as
planned (taut by construction), ``lead`` late. When the lead grows, the periods
it skips are filled (:meth:`CommandLead.output_stamps`: one allocation per
control period, from the latest setpoint); when it shrinks, answers pause until
the input catches up, so stamps never go backwards. A latency of exactly 0
(lockstep, the library loop) gives lead 0: every answer stamped with its input.
:class:`CommandLeadConfig` holds the node's settings of it (parameters). ROS-free.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from splitter_msgs_py.core.parameter_fields import parameter_field

NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class CommandLeadConfig:
    """Whether and how the allocator stamps its commands ahead (parameters, seconds)."""

    command_lead: bool = parameter_field(
        False,
        "stamp commands ahead of their inputs by the latency measured, as points of a "
        "trajectory the simulator follows at their stamps (real time; lockstep needs "
        "each tick answered with its own stamp)",
    )
    command_lead_margin_s: float = parameter_field(  # [s]
        0.002,
        "real time: commands are stamped ahead of their input by the largest latency "
        "measured plus this margin for their way to the simulator, in whole control "
        "periods (lockstep: latency 0, no lead) [s]",
        bounds=(0.0, 1.0),
        live=True,
    )
    command_lead_window_s: float = parameter_field(  # [s]
        2.0,
        "the command lead plans for the largest input latency of this much simulated time [s]",
        bounds=(0.0, 100.0),
        live=True,
    )
    command_lead_max_s: float = parameter_field(  # [s]
        0.5,
        "longest command lead: a larger latency is followed late, not planned for [s]",
        bounds=(0.0, 5.0),
        live=True,
    )


@dataclass
class CommandLead:
    """The lead [ns] of the allocator's command stamps over its inputs' stamps."""

    period_ns: int  # control period: stamps are whole multiples of it
    margin_ns: int = 2_000_000  # [ns] for the command's way to the simulator
    factor: float = 1.5  # [-] the lead covers this many times the largest latency
    window_ns: int = 2_000_000_000  # [ns] simulated time the largest latency is taken over
    max_lead_ns: int = 500_000_000  # [ns] never planned further ahead than this
    _samples: deque[tuple[int, int]] = field(default_factory=deque, init=False)
    _window_max_ns: int = field(default=0, init=False)

    def __post_init__(self) -> None:
        if self.period_ns <= 0:
            raise ValueError(f"period_ns must be > 0, got {self.period_ns}")
        for name in ("margin_ns", "window_ns", "max_lead_ns"):
            if getattr(self, name) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")

    def configure(self, config: CommandLeadConfig) -> None:
        """Take the margin, window and longest lead of ``config`` (from the next input on)."""
        self.margin_ns = round(config.command_lead_margin_s * NS_PER_S)
        self.window_ns = round(config.command_lead_window_s * NS_PER_S)
        self.max_lead_ns = round(config.command_lead_max_s * NS_PER_S)
        self.__post_init__()

    def record(self, input_stamp_ns: int, now_ns: int | None) -> int:
        """Record the latency of an input stamped ``input_stamp_ns`` used at ``now_ns``.

        Returns the latency [ns] (0 without a clock or when the clock is behind).
        """
        latency = 0 if now_ns is None else max(0, int(now_ns) - int(input_stamp_ns))
        samples = self._samples
        samples.append((int(input_stamp_ns), latency))
        oldest = int(input_stamp_ns) - self.window_ns
        while samples and samples[0][0] < oldest:
            samples.popleft()
        self._window_max_ns = max(lat for _, lat in samples)
        return latency

    @property
    def lead_ns(self) -> int:
        """Lead of the answers' stamps [ns]: 0 while nothing was late."""
        worst = self._window_max_ns
        if worst <= 0:
            return 0
        periods = math.ceil((self.factor * worst + self.margin_ns) / self.period_ns)
        return min(periods * self.period_ns, self.max_lead_ns - self.max_lead_ns % self.period_ns)

    def output_stamps(self, input_stamp_ns: int, last_output_ns: int | None) -> list[int]:
        """Stamps to answer the input stamped ``input_stamp_ns`` with, oldest first.

        Lead 0: the input's own stamp (as in lockstep, a repeated tick included).
        Otherwise every control period after ``last_output_ns`` up to the input's
        stamp plus the lead; none while the lead shrinks and the input catches up.
        """
        lead = self.lead_ns
        target = int(input_stamp_ns) + lead
        if lead == 0 or last_output_ns is None:
            return [target] if last_output_ns is None or target >= last_output_ns else []
        first = last_output_ns + self.period_ns
        return list(range(first, target + 1, self.period_ns))
