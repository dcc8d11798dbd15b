"""Joint and reel faults: what can break, how, and when (paper section VIII's redundancy).

The paper's discussion: an inertial-morphing design "can provide redundancy in
attitude control for cases when one of the limbs is damaged or malfunctions".
A fault is one of the 25 actuated joints (``joints.JOINT_NAMES``) failing at a
time, in one of two ways:

* ``locked``: the joint stops where it is and holds (a seized gearbox, a
  brake that engaged); its velocity drops to zero at once (the impulse is
  internal: the angular momentum is kept, the body's rate changes with the
  relative momentum the joint carried);
* ``limp``: the motor gives no torque (a cut phase, a failed driver); the
  lumped mass then moves as the dynamics push it (in a spinning body the
  centrifugal load swings it out) within the joint's range, stopping
  inelastically at its ends.

The tether reel can only lock: a free-running spool would pay the tether out
to its end under the centrifugal tension, which is a different robot.

ROS-free: the simulator injects these (``splitter_sim``), the scenario language
and the campaigns describe them, the detector (``splitter_ik.core.joint_health``)
never reads them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Final

from splitter_model.joints import JOINT_INDEX, JOINT_NAMES, TETHER_INDEX, TETHER_JOINT

LOCKED: Final = "locked"
LIMP: Final = "limp"
FAULT_KINDS: Final = (LOCKED, LIMP)
# Numeric code of each kind on a joint (0 healthy): the simulator's ground truth array.
FAULT_CODES: Final[Mapping[str, int]] = {LOCKED: 1, LIMP: 2}
FAULT_NAMES: Final[Mapping[int, str]] = {code: kind for kind, code in FAULT_CODES.items()}


@dataclass(frozen=True)
class JointFault:
    """``joint`` (a ``JOINT_NAMES`` entry) fails as ``kind`` at ``time_s`` [s]."""

    joint: str
    kind: str
    time_s: float = 0.0  # [s] simulated time of the failure

    def __post_init__(self) -> None:
        if self.joint not in JOINT_INDEX:
            raise ValueError(
                f"joint: unknown joint {self.joint!r}; one of {', '.join(JOINT_NAMES)}"
            )
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"kind: {self.kind!r} is not one of {', '.join(FAULT_KINDS)}")
        if self.joint == TETHER_JOINT and self.kind != LOCKED:
            raise ValueError(
                f"kind: the tether reel can only be {LOCKED!r} (a free spool pays the "
                f"tether out to its end), got {self.kind!r}"
            )
        t = self.time_s
        if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t) or t < 0:
            raise ValueError(f"time_s: must be a finite number >= 0 s, got {t!r}")

    @property
    def joint_index(self) -> int:
        """Index of the joint in ``JOINT_NAMES`` order."""
        return JOINT_INDEX[self.joint]

    @property
    def time_ns(self) -> int:
        """``time_s`` in integer nanoseconds."""
        return round(self.time_s * 1e9)

    @property
    def is_reel(self) -> bool:
        """True for the tether reel."""
        return self.joint_index == TETHER_INDEX


def faults_from_records(
    records: Sequence[Mapping[str, object]], where: str
) -> tuple[JointFault, ...]:
    """Faults from mappings ``{joint, kind, time_s}``; ValueError naming ``where[i].field``."""
    if isinstance(records, str | bytes) or not isinstance(records, Sequence):
        raise ValueError(f"{where}: a list of faults, got {records!r}")
    faults = []
    for i, record in enumerate(records):
        if not isinstance(record, Mapping):
            raise ValueError(f"{where}[{i}]: a mapping with joint, kind, time_s, got {record!r}")
        unknown = set(record) - {"joint", "kind", "time_s"}
        if unknown:
            raise ValueError(f"{where}[{i}]: unknown field(s) {', '.join(sorted(unknown))}")
        for name in ("joint", "kind"):
            if name not in record:
                raise ValueError(f"{where}[{i}].{name}: missing")
        try:
            faults.append(
                JointFault(str(record["joint"]), str(record["kind"]), record.get("time_s", 0.0))
            )
        except ValueError as exc:
            raise ValueError(f"{where}[{i}].{exc}") from None
    return _each_joint_once(faults, f"{where}[{{}}].joint")


def fault_parameters(faults: Sequence[JointFault]) -> dict[str, tuple]:
    """The simulator's parameters ``fault_joints``, ``fault_kinds``, ``fault_times_s``."""
    return {
        "fault_joints": tuple(f.joint for f in faults),
        "fault_kinds": tuple(f.kind for f in faults),
        "fault_times_s": tuple(float(f.time_s) for f in faults),
    }


def faults_from_parameters(
    joints: Sequence[str], kinds: Sequence[str], times_s: Sequence[float]
) -> tuple[JointFault, ...]:
    """The inverse of :func:`fault_parameters`; ValueError naming the parameter."""
    if not len(joints) == len(kinds) == len(times_s):
        raise ValueError(
            "fault_joints, fault_kinds, fault_times_s: must have the same length, got "
            f"{len(joints)}, {len(kinds)}, {len(times_s)}"
        )
    names = {"joint": "fault_joints", "kind": "fault_kinds", "time_s": "fault_times_s"}
    faults = []
    for i, (joint, kind, time_s) in enumerate(zip(joints, kinds, times_s, strict=True)):
        try:
            faults.append(JointFault(str(joint), str(kind), float(time_s)))
        except ValueError as exc:
            field, _, reason = str(exc).partition(": ")
            raise ValueError(f"{names.get(field, field)}[{i}]: {reason}") from None
    return _each_joint_once(faults, "fault_joints[{}]")


def _each_joint_once(faults: list[JointFault], where: str) -> tuple[JointFault, ...]:
    """``faults`` as a tuple; ValueError at ``where.format(i)`` when a joint fails twice."""
    seen: set[str] = set()
    for i, fault in enumerate(faults):
        if fault.joint in seen:
            raise ValueError(f"{where.format(i)}: {fault.joint!r} fails twice")
        seen.add(fault.joint)
    return tuple(faults)
