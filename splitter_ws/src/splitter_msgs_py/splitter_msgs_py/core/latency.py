"""How late a node's inputs are: simulated time at use minus the message's stamp.

In lockstep every input is used at the simulated time it is stamped with (latency
0). In real time the simulator keeps stepping while messages travel and nodes
compute, so an input answers a state that is already ``latency`` old when it is
used; :class:`InputLatency` keeps, per input, the count, mean, largest and the
last value, for ``/diagnostics`` and ``summary.json``. ROS-free.
"""

from __future__ import annotations

from dataclasses import dataclass, field

NS_PER_MS = 1_000_000


@dataclass
class _Stats:
    count: int = 0
    total_ns: int = 0
    max_ns: int = 0
    last_ns: int = 0


@dataclass
class InputLatency:
    """Latency statistics per input (a short key such as ``joint_commands``)."""

    _stats: dict[str, _Stats] = field(default_factory=dict)

    def record(self, key: str, stamp_ns: int, now_ns: int | None) -> int | None:
        """Record ``now_ns - stamp_ns`` for ``key`` (clamped at 0); None without a clock."""
        if now_ns is None:
            return None
        latency = max(0, int(now_ns) - int(stamp_ns))
        s = self._stats.setdefault(key, _Stats())
        s.count += 1
        s.total_ns += latency
        s.max_ns = max(s.max_ns, latency)
        s.last_ns = latency
        return latency

    def max_ns(self, key: str) -> int:
        """Largest latency of ``key`` so far [ns] (0 before any)."""
        s = self._stats.get(key)
        return 0 if s is None else s.max_ns

    def values(self) -> dict[str, float]:
        """``latency_<key>_{mean,max,last}_ms`` and ``latency_<key>_count`` of every input."""
        out: dict[str, float] = {}
        for key, s in sorted(self._stats.items()):
            mean = s.total_ns / s.count if s.count else 0.0
            out[f"latency_{key}_mean_ms"] = mean / NS_PER_MS
            out[f"latency_{key}_max_ms"] = s.max_ns / NS_PER_MS
            out[f"latency_{key}_last_ms"] = s.last_ns / NS_PER_MS
            out[f"latency_{key}_count"] = float(s.count)
        return out
