"""Which node stalls the graph: progress of each node judged from the stamps it publishes.

Each node of the data path answers a control tick ``t`` with one message stamped
``t`` on its progress topic (:data:`PROGRESS_TOPICS`): the simulator its state
(``/splitter/imu``), the gait phase manager its jump command, the MPC its inertia
setpoint, the allocator its joint commands. :class:`GraphWatchdog` keeps the
latest stamp of each and when it arrived (wall time), and :meth:`GraphWatchdog.check`
names a stalled node:

* **lockstep**: the simulator waits for the tick's commands, so a stall stops the
  simulated time. Once it has not advanced for ``stall_timeout_s``, the stalled
  node is the first one, in data-path order (:data:`UPSTREAM`), that has not
  answered the simulator's latest tick although everything it needs has; when
  every node answered, it is the simulator itself.
* **real time**: the simulator steps on a wall clock and nothing waits; a node
  whose latest output is older than ``stall_timeout_s`` of wall time while the
  simulator advances is stalled (each stall reported once, and its recovery).

ROS-free: the launcher's watchdog node feeds it the stamps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from splitter_msgs_py import names

SIMULATOR = "simulator"
GAIT = "gait_phase_manager"
MPC = "inertial_morphing_mpc"
ALLOCATOR = "ik_tether_allocator"
# the topic on which each node answers a control tick, stamped with that tick
PROGRESS_TOPICS = {
    SIMULATOR: names.IMU,
    GAIT: names.JUMP_COMMAND,
    MPC: names.INERTIA_SETPOINT,
    ALLOCATOR: names.JOINT_COMMANDS,
}
# what each node needs, stamped t, before it can answer t (data-path order)
UPSTREAM = {GAIT: (SIMULATOR,), MPC: (SIMULATOR,), ALLOCATOR: (MPC,)}
DEFAULT_STALL_TIMEOUT_S = 10.0  # [s] wall
MAX_LEAD_NS = 1_000_000_000  # [ns] a stamp further ahead of the simulator's is corrupt


@dataclass(frozen=True)
class Stall:
    """A node that makes no progress."""

    node: str
    t_ns: int  # [ns] the tick it has not answered (lockstep) / its latest stamp (real time)
    waited_s: float  # [s] wall time without progress
    reason: str

    def __str__(self) -> str:
        return f"{self.node} stalled: {self.reason}"


@dataclass
class _Progress:
    stamp_ns: int = -1
    wall_s: float = math.nan  # when the stamp last advanced


@dataclass
class GraphWatchdog:
    """Latest output stamp per node; :meth:`check` names a stalled node (module doc)."""

    nodes: tuple[str, ...]
    lockstep: bool = True
    stall_timeout_s: float = DEFAULT_STALL_TIMEOUT_S
    control_period_ns: int = 10_000_000
    _progress: dict[str, _Progress] = field(default_factory=dict, init=False)
    _reported: set[str] = field(default_factory=set, init=False)
    _started_wall_s: float = field(default=math.nan, init=False)  # the simulator's first state

    def __post_init__(self) -> None:
        if not (math.isfinite(self.stall_timeout_s) and self.stall_timeout_s > 0.0):
            raise ValueError(f"stall_timeout_s must be finite and > 0, got {self.stall_timeout_s}")
        unknown = [n for n in self.nodes if n not in PROGRESS_TOPICS]
        if unknown:
            raise ValueError(f"no progress topic known for {unknown}")
        if SIMULATOR not in self.nodes:
            raise ValueError("the watchdog judges progress against the simulator's")
        self._progress = {n: _Progress() for n in self.nodes}

    def on_output(self, node: str, stamp_ns: int, wall_s: float) -> None:
        """``node`` published a message stamped ``stamp_ns`` on its progress topic.

        A stamp more than :data:`MAX_LEAD_NS` ahead of the simulator's latest (or, for
        the simulator, of its own) is corrupt, not progress: ignored.
        """
        progress = self._progress[node]
        reference = self._progress[SIMULATOR].stamp_ns
        if reference >= 0 and stamp_ns > reference + MAX_LEAD_NS:
            return
        if node == SIMULATOR and progress.stamp_ns < 0:
            self._started_wall_s = float(wall_s)
        if stamp_ns > progress.stamp_ns:
            progress.stamp_ns, progress.wall_s = int(stamp_ns), float(wall_s)

    def stamp_ns(self, node: str) -> int:
        """Latest stamp seen from ``node`` (-1: none yet)."""
        return self._progress[node].stamp_ns

    def check(self, wall_s: float) -> list[Stall]:
        """Stalls found at ``wall_s``; each real-time stall is returned once."""
        sim = self._progress[SIMULATOR]
        if sim.stamp_ns < 0:
            return []  # not started: the simulator's start-up wait covers it
        if self.lockstep:
            stall = self._lockstep_stall(wall_s)
            return [] if stall is None else [stall]
        return self._real_time_stalls(wall_s)

    def _lockstep_stall(self, wall_s: float) -> Stall | None:
        sim = self._progress[SIMULATOR]
        waited = wall_s - sim.wall_s
        if waited < self.stall_timeout_s:
            return None
        tick = sim.stamp_ns - sim.stamp_ns % self.control_period_ns
        for node in (GAIT, MPC, ALLOCATOR):
            if node not in self._progress or self._progress[node].stamp_ns >= tick:
                continue
            needs = [n for n in UPSTREAM[node] if n in self._progress]
            if all(self._progress[n].stamp_ns >= tick for n in needs):
                return Stall(
                    node,
                    tick,
                    waited,
                    f"no {PROGRESS_TOPICS[node]} stamped t = {tick * 1e-9:.3f} s for "
                    f"{waited:.1f} s (its inputs for that tick were published)",
                )
        return Stall(
            SIMULATOR,
            sim.stamp_ns,
            waited,
            f"no state after t = {sim.stamp_ns * 1e-9:.3f} s for {waited:.1f} s although every "
            "node answered it",
        )

    def _real_time_stalls(self, wall_s: float) -> list[Stall]:
        out = []
        for node, progress in self._progress.items():
            since = progress.wall_s if progress.stamp_ns >= 0 else self._started_wall_s
            silent = wall_s - since
            if silent < self.stall_timeout_s:
                self._reported.discard(node)  # progresses (again)
                continue
            if node in self._reported:
                continue
            self._reported.add(node)
            latest = (
                "nothing yet"
                if progress.stamp_ns < 0
                else f"the latest stamped t = {progress.stamp_ns * 1e-9:.3f} s"
            )
            out.append(
                Stall(
                    node,
                    progress.stamp_ns,
                    silent,
                    f"nothing on {PROGRESS_TOPICS[node]} for {silent:.1f} s ({latest})",
                )
            )
        return out

    @property
    def stalled(self) -> set[str]:
        """Real time: nodes reported stalled that have not published since."""
        return set(self._reported)
