"""What the simulator node decides between steps: command checks, lockstep waits, real-time pace.

ROS-free; the ``simulator`` node calls these and does the messaging.

* :func:`check_jump_wrench` bounds a commanded jump wrench; :func:`jump_thrust`
  splits it over the hemis: through the hemi whose body the commanded torque about
  the centre of mass places the thrust at (:func:`pushing_hemi`), or by both at
  once.
* :class:`LockstepWait`: on a control tick the simulator steps once every
  lockstep command topic that has a publisher delivered a message stamped with
  the tick, or once it has waited ``timeout_s`` (wall) for them.
* :class:`RealTimePacer`: how many steps the wall clock (times a rate factor)
  asks for, with a cap on the catch-up of one call.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from splitter_msgs_py.core.stamps import MessageValidationError
from splitter_sim.core.simulator import HEMI_BODY_INDEX, SimState

MAX_JUMP_FORCE_N = 1.0e4  # [N] a jump command beyond this is rejected as out of range
# [N m] likewise for its torque (the force times a lever of at most ~10 m is ~1e5 N m)
MAX_JUMP_TORQUE_NM = 1.0e5
REAL_TIME_MAX_CATCH_UP = 20  # steps one real-time call may do to catch up


def check_jump_wrench(force_n: ArrayLike, torque_nm: ArrayLike) -> None:
    """Raise ``ValueError`` naming the part of a jump wrench above its bound."""
    for label, vector, limit, unit in (
        ("force", np.asarray(force_n, dtype=float), MAX_JUMP_FORCE_N, "N"),
        ("torque", np.asarray(torque_nm, dtype=float), MAX_JUMP_TORQUE_NM, "N m"),
    ):
        # component check first: the norm of a huge vector would overflow
        if np.max(np.abs(vector)) > limit or np.linalg.norm(vector) > limit:
            raise ValueError(
                f"wrench.{label}: {vector.tolist()} {unit} exceeds |{label}| <= {limit:g} {unit}"
            )


# Relative torque residual [-] within which a wrench is the thrust of a single hemi.
SINGLE_HEMI_TOLERANCE = 0.02


def pushing_hemi(state: SimState | None, force_n: ArrayLike, torque_nm: ArrayLike) -> str:
    """The hemi ("a", "b") whose body the commanded torque about the COM places the thrust at.

    The gait phase manager sends ``tau = (p_hemi - p_com) x F``; a zero torque (or
    a force along the tether), or no state yet, leaves the choice to the simulator
    ("auto").
    """
    force = np.asarray(force_n, dtype=float)
    torque = np.asarray(torque_nm, dtype=float)
    scale = float(np.linalg.norm(force))
    if state is None or scale == 0.0 or np.linalg.norm(torque) <= 1e-9 * (1.0 + scale):
        return "auto"
    levers = state.mass_positions_world_m[list(HEMI_BODY_INDEX)] - state.position_m
    errors = [float(np.linalg.norm(torque - np.cross(lever, force))) for lever in levers]
    return "a" if errors[0] <= errors[1] else "b"


@dataclass(frozen=True)
class JumpThrust:
    """How a commanded jump wrench is pushed: through one hemi, or by both at once.

    ``hemi`` is "a", "b" or "auto" (:meth:`Simulator.command_jump_force`) when
    ``per_hemi`` is None; otherwise both hemis push their own forces (world [N]).
    """

    hemi: str
    per_hemi: tuple[np.ndarray, np.ndarray] | None = None


def jump_thrust(state: SimState | None, force_n: ArrayLike, torque_nm: ArrayLike) -> JumpThrust:
    """Split a jump wrench (world force, torque about the COM) over the hemis' legs.

    The gait phase manager encodes a push with the levers ``+-d/2`` of the hemi
    bodies from their midpoint (``d`` from hemi b's body to hemi a's, the tether):
    ``tau = d/2 x F_a - d/2 x F_b``. The same levers decode it. A wrench that one
    hemi's thrust makes (``tau = +-d/2 x F`` within :data:`SINGLE_HEMI_TOLERANCE` of
    ``|tau|``), or no torque, goes through that hemi (:func:`pushing_hemi`). Any
    other wrench is pushed by both hemis at once: ``F_a = F/2 + (tau x d) / |d|^2``,
    ``F_b = F - F_a``. Across the tether these are the forces the gait encoded
    (``(tau x d) / |d|^2`` is half their difference); along it, which makes no
    torque, the force is shared equally. A torque about the tether axis, which no
    force at the two bodies makes, is left out.
    """
    force = np.asarray(force_n, dtype=float)
    torque = np.asarray(torque_nm, dtype=float)
    if state is None:
        return JumpThrust("auto")
    scale = float(np.linalg.norm(force))
    size = float(np.linalg.norm(torque))
    if scale == 0.0 or size <= 1e-9 * (1.0 + scale):
        return JumpThrust("auto")
    body_a, body_b = state.mass_positions_world_m[list(HEMI_BODY_INDEX)]
    d = body_a - body_b
    half = 0.5 * d
    for hemi, lever in (("a", half), ("b", -half)):
        if np.linalg.norm(torque - np.cross(lever, force)) <= SINGLE_HEMI_TOLERANCE * size:
            return JumpThrust(hemi)
    d2 = float(d @ d)
    force_a = 0.5 * force + np.cross(torque, d) / d2
    return JumpThrust("auto", (force_a, force - force_a))


@dataclass
class LockstepWait:
    """Which lockstep command topics answered a tick, and how long the simulator waited."""

    topics: tuple[str, ...]
    timeout_s: float  # [s] wall
    stamps: dict[str, int | None] = field(default_factory=dict, init=False)
    timeouts: int = field(default=0, init=False)
    _since: float | None = field(default=None, init=False)

    def __post_init__(self) -> None:
        self.stamps = dict.fromkeys(self.topics)

    def arrived(self, topic: str, stamp_ns: int) -> None:
        """A command of ``topic`` stamped ``stamp_ns`` answered its tick."""
        self.stamps[topic] = int(stamp_ns)

    def waiting_for(self, t_ns: int, has_publisher: Callable[[str], bool]) -> list[str]:
        """Topics with a publisher that have not answered tick ``t_ns``."""
        return [t for t in self.topics if self.stamps[t] != t_ns and has_publisher(t)]

    def may_step(self, waiting: Sequence[str], now_s: float) -> tuple[bool, float | None]:
        """(step now?, seconds waited when the wait timed out, else None)."""
        if not waiting:
            self._since = None
            return True, None
        if self._since is None:
            self._since = now_s
            return False, None
        waited = now_s - self._since
        if waited < self.timeout_s:
            return False, None
        self.timeouts += 1
        self._since = None
        return True, waited


@dataclass
class RealTimePacer:
    """Steps due by the wall clock: ``rate_factor`` simulated seconds per wall second."""

    rate_factor: float
    dt_ns: int
    origin: tuple[float, int] = (0.0, 0)  # (wall [s], simulated [ns]) of the pace's start

    def restart(self, now_s: float, t_ns: int) -> None:
        """Pace from (``now_s``, ``t_ns``) on (the start, or after dropping a backlog)."""
        self.origin = (float(now_s), int(t_ns))

    def due_ns(self, now_s: float) -> int:
        """Simulated time the wall clock asks for at ``now_s`` [ns]."""
        wall, t = self.origin
        return t + int((now_s - wall) * self.rate_factor * 1e9)

    def steps_due(self, now_s: float, t_ns: int) -> tuple[int, bool]:
        """(steps to take now, whether the backlog beyond the cap is dropped)."""
        due = self.due_ns(now_s)
        steps = max(0, (due - t_ns) // self.dt_ns)
        if steps > REAL_TIME_MAX_CATCH_UP:
            return REAL_TIME_MAX_CATCH_UP, True
        return int(steps), False


@dataclass
class CommandQueue:
    """Joint commands stamped ahead of the simulated time, each applied at its stamp.

    The points of a stamped joint trajectory (position at the stamp, velocity until
    the next point): a point that arrives before its stamp waits here. A new point
    replaces the queued ones stamped at or after it (the sender re-planned from
    there), as a joint trajectory controller replaces the rest of its trajectory.
    """

    _pending: list[tuple[int, object]] = field(default_factory=list, init=False)

    def __len__(self) -> int:
        return len(self._pending)

    def push(self, stamp_ns: int, command: object) -> None:
        """Queue ``command`` for ``stamp_ns``; queued ones from that stamp on are dropped."""
        self.drop_from(stamp_ns)
        self._pending.append((int(stamp_ns), command))

    def drop_from(self, stamp_ns: int) -> None:
        """Forget the points stamped at or after ``stamp_ns`` (a newer plan starts there)."""
        if self._pending and self._pending[-1][0] >= stamp_ns:
            self._pending = [p for p in self._pending if p[0] < stamp_ns]

    def peek(self) -> tuple[int, object] | None:
        """The earliest queued point (stamp, command), or None."""
        return self._pending[0] if self._pending else None

    def due(self, t_ns: int) -> tuple[int, object] | None:
        """The newest point stamped at or before ``t_ns`` (removed with the older ones)."""
        pending = self._pending
        if not pending or pending[0][0] > t_ns:
            return None
        k = 0
        while k < len(pending) and pending[k][0] <= t_ns:
            k += 1
        point = pending[k - 1]
        del pending[:k]
        return point


def check_trajectory_stamp(stamp_ns: int, applied_ns: int, now_ns: int, max_lead_ns: int) -> None:
    """Raise ``MessageValidationError`` unless a trajectory point stamped ``stamp_ns`` may be used.

    A point may re-plan what is queued (an earlier stamp than the last point
    received), but not what is already followed: it must not be earlier than the
    point in effect (``applied_ns``), nor more than ``max_lead_ns`` ahead of ``now_ns``.
    """
    if stamp_ns < applied_ns:
        raise MessageValidationError(
            f"header.stamp: {stamp_ns * 1e-9:.9f} s is earlier than the point in effect "
            f"({applied_ns * 1e-9:.9f} s)"
        )
    if stamp_ns > now_ns + max_lead_ns:
        raise MessageValidationError(
            f"header.stamp: {stamp_ns * 1e-9:.9f} s is more than {max_lead_ns * 1e-9:g} s "
            f"ahead of the simulated time {now_ns * 1e-9:.9f} s"
        )
