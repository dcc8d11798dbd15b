"""What is left after a fault: the limbs' roles and the reachable set that remains.

The paper (section VIII): inertial morphing "can provide redundancy in attitude
control for cases when one of the limbs is damaged or malfunctions". The
allocator and the MPC use this module to re-plan with the working joints only.

**The roles.** A limb with a failed joint (``splitter_model.faults``, as the
detector reports it) is *held*: it stays where its joints put it (the working
joints of that limb are held too, so a locked knee keeps its tip on its axis).
Its *mirror*, the other limb of the same hemi along the same body axis
(``y_pos`` <-> ``y_neg``, ``z_pos`` <-> ``z_neg``), copies its joint angles, so the
hemi stays balanced: the two tips are mirror images through the tether axis,
the centre of mass stays on it and the pair adds no product of inertia
``I_xy`` (``I_xz`` for z limbs), which with the tips ``r_x`` (up to 3 m) from the
centre would otherwise tilt the principal axes (a y limb held at 0.4 m against its
sibling at 0.11 m, r_x 2.8 m: ``I_xy`` = 1.2 kg m^2, the spin axis 0.5 deg off body y;
at r_x 0.5 m, 3.6 deg). The remaining limbs along that axis are *free*: they move
together, as before.

**The held limb's pose.** Its working joints fold it out of the way: a limb
whose knee failed turns its hip pitch to :data:`FOLD_STOP_PITCH_RAD`; one
whose hip pitch (or abduction) failed folds its knee to the stop. Why: in a
spin across the tether (the goal, and any spin the tether carries) the load on
a tip is the centrifugal pull along the tether, outward (``v``); a limp knee
swings its shank towards ``v``, to ``hip_pitch + knee = pi / 2``. With the hip
pitch at -1.35 rad that is beyond the folded stop (2.6 rad): the pull holds the
knee folded there instead of leaving it a pendulum (an undamped one: a limp
joint has no friction to stop it). A limp hip pitch keeps swinging, but with the
knee folded its tip is 0.11 m from the hip, four times less than stretched. The
swing is a pendulum in the centrifugal pull (period ~1 s at 1 rad/s) in the plane of
the tether and the limb's axis, so its products of inertia are ``I_xy`` for a y limb
and ``I_xz`` for a z limb. ``I_xy`` tilts the reference spin axis (y,
:data:`SPIN_AXIS`): the mirror of a y limb copies the swing to cancel it. ``I_xz``
leaves y principal, and the mirror of a z limb does not chase the swing: it folds its
knee too but keeps its hip pitch (:func:`mirror_limb_command`). A mirror chasing a
swing through its servos kept the pair swinging to the end of the flight; left alone,
the swing couples into the body's rotation, where the MPC's feedback takes it out.
Seed 0's campaign (README, "A limb or the reel fails"): 27 of 28 z limb draws
stabilized against 21 copying; 17 of the 28 limbs came to rest against the hip
pitch's stop at +-pi, past the swing's inverted pose, where the pull holds them.

**The effective radius.** The moments depend on the limbs of one axis only
through the mean of their squared reaches (paper eq. 2, ``4 m_y r_y^2``), so the
model keeps its form with ``r_y^2`` the mean over the four y limbs: with held and
mirror limbs of reach ``r_h`` and ``n`` free limbs of reach ``r``,
``r_y^2 = (sum r_h^2 + n r^2) / 4``, a box again (``r`` over the knee range): the
reachable set that remains is :class:`~splitter_model.reachable.ReachableSet` with
narrower bounds. A locked reel fixes ``r_x``. Exact for tips on their axes;
a limp joint can swing its tip off its axis (a limp hip pitch turns the tip
towards the tether), which this model counts by its distance only (the
products of inertia of a limb that stays are what its mirror cancels; those of a
swinging limp hip pitch, and the rest, are the MPC's feedback).

ROS-free, numpy only.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from splitter_model.joints import (
    LIMB_AXIS_OF,
    LIMB_HEMIS,
    LIMB_JOINTS,
    LIMB_RADIUS_INDEX,
    N_LIMBS,
    TETHER_INDEX,
    limb_joints,
)
from splitter_model.kinematics import limb_forward_kinematics
from splitter_model.model import RobotModel, principal_inertia
from splitter_model.reachable import ReachableSet, reachable_set

# [rad] hip pitch of a limb whose knee failed: the radial pitch of the folded knee
# (-1.30 rad for the paper's limb) less 0.05 rad, so a limp knee rests on its fold stop
FOLD_STOP_MARGIN_RAD = 0.05
# [-] the body axis of the reference spin (y: w_ref of every spinning scenario, paper
# Table I); a limp hip pitch's swing in the plane of the tether and a limb along another
# axis leaves it a principal axis
SPIN_AXIS = 1
# [m] half-width kept around a radius that cannot move (a locked reel, an axis with no
# free limb): the MPC's bounds stay a box with an interior
FIXED_RADIUS_TOLERANCE_M = 1e-3


def mirror_limb(limb: int) -> int:
    """The limb of the same hemi reaching the opposite way along the same body axis."""
    for other in range(N_LIMBS):
        if (
            other != limb
            and LIMB_HEMIS[other] == LIMB_HEMIS[limb]
            and LIMB_AXIS_OF[other][0] == LIMB_AXIS_OF[limb][0]
        ):
            return other
    raise ValueError(f"limb {limb} has no mirror")  # (every limb has one)


def limb_of_joint(joint: int) -> int | None:
    """The limb (0..7) a joint belongs to; None for the tether."""
    return None if joint == TETHER_INDEX else joint // len(LIMB_JOINTS)


@dataclass(frozen=True)
class LimbRoles:
    """Which limbs are held (a failed joint), which mirror a held one, which are free."""

    held: frozenset[int]
    mirrors: tuple[tuple[int, int], ...]  # (mirror limb, the held limb it copies)
    reel_locked: bool

    @classmethod
    def from_failed_joints(cls, failed_joints: Iterable[int]) -> LimbRoles:
        """The roles when the joints ``failed_joints`` (``JOINT_NAMES`` indices) have failed.

        A failed hip abduction holds nothing: the limb's radial pose keeps its tip on the
        abduction axis, where that joint moves no mass (and a limp one feels no torque),
        so hip pitch and knee still set its reach (the allocator keeps the abduction
        where it is)."""
        joints = set(failed_joints)
        abduction = LIMB_JOINTS.index("hip_abduction")
        held = frozenset(
            limb
            for j in joints
            if (limb := limb_of_joint(j)) is not None and j % len(LIMB_JOINTS) != abduction
        )
        mirrors = tuple(
            sorted((mirror_limb(limb), limb) for limb in held if mirror_limb(limb) not in held)
        )
        return cls(held, mirrors, TETHER_INDEX in joints)

    @property
    def healthy(self) -> bool:
        """Nothing has failed."""
        return not self.held and not self.reel_locked

    @property
    def copied(self) -> frozenset[int]:
        """Limbs whose joints are not the allocator's to plan: held and mirrors."""
        return self.held | {m for m, _ in self.mirrors}

    def free_limbs(self, radius_index: int) -> tuple[int, ...]:
        """The free limbs of the y (1) or z (2) radius."""
        return tuple(
            limb
            for limb in range(N_LIMBS)
            if LIMB_RADIUS_INDEX[limb] == radius_index and limb not in self.copied
        )


def fold_stop_pitch_rad(model: RobotModel) -> float:
    """Hip pitch [rad] that leaves a limp knee resting on its folded stop (module doc)."""
    from splitter_model.kinematics import radial_limb_joint_angles

    folded = radial_limb_joint_angles(model, model.limb_radius_min_m)
    return float(folded[1]) - FOLD_STOP_MARGIN_RAD


def held_limb_command(
    model: RobotModel, limb: int, measured: ArrayLike, moving_faults: Iterable[int]
) -> NDArray[np.float64]:
    """Joint command (3) of a held limb: where it is, folded by its working joints when one of
    its joints in ``moving_faults`` (failed joints that move: limp) would swing it."""
    q = np.asarray(measured, dtype=float).reshape(3).copy()
    first = limb_joints(limb).start
    moving = {j - first for j in moving_faults if limb_of_joint(j) == limb}
    hip_pitch, knee = LIMB_JOINTS.index("hip_pitch"), LIMB_JOINTS.index("knee")
    if knee in moving:
        q[hip_pitch] = fold_stop_pitch_rad(model)
    elif hip_pitch in moving:
        q[knee] = model.knee_max_rad
    return q


def mirror_limb_command(
    limb: int, held_command: ArrayLike, mirror_previous: ArrayLike, moving_faults: Iterable[int]
) -> NDArray[np.float64]:
    """Joint command (3) of the mirror of held limb ``limb``: a copy of ``held_command``,
    except for the limp hip pitch of a limb across the spin axis (a z limb), whose swing
    it does not chase: it keeps its hip pitch where ``mirror_previous`` (its last
    command) has it and copies the rest (module doc)."""
    q = np.asarray(held_command, dtype=float).reshape(3).copy()
    hip_pitch = LIMB_JOINTS.index("hip_pitch")
    across_spin = LIMB_RADIUS_INDEX[limb] != SPIN_AXIS
    if across_spin and limb_joints(limb).start + hip_pitch in set(moving_faults):
        q[hip_pitch] = float(np.asarray(mirror_previous, dtype=float).reshape(3)[hip_pitch])
    return q


def limb_reaches_m(model: RobotModel, joint_positions: ArrayLike) -> NDArray[np.float64]:
    """Hip-to-tip distance (8,) [m] of every limb at the joint positions (25)."""
    q = np.asarray(joint_positions, dtype=float)
    return np.array(
        [
            float(np.linalg.norm(limb_forward_kinematics(model, limb, q[limb_joints(limb)])))
            for limb in range(N_LIMBS)
        ]
    )


@dataclass(frozen=True)
class RemainingShape:
    """The roles and where the limbs that cannot be planned are: the allocator's and MPC's view.

    ``held_reach_m``: the reach [m] of every held limb (its mirror has the same);
    ``tether_length_m``: where a locked reel holds the tether [m].
    """

    roles: LimbRoles
    failed_joints: frozenset[int] = frozenset()  # JOINT_NAMES indices
    moving_faults: frozenset[int] = frozenset()  # those that move (limp): folded away
    held_reach_m: tuple[tuple[int, float], ...] = ()  # (held limb, reach [m])
    tether_length_m: float | None = None

    def _fixed_sum_m2(self, radius_index: int) -> tuple[float, int]:
        """(sum of squared reaches of the held and mirror limbs of a radius, their count)."""
        reach = dict(self.held_reach_m)
        total, count = 0.0, 0
        for limb in self.roles.held:
            if LIMB_RADIUS_INDEX[limb] == radius_index:
                total += reach[limb] ** 2
                count += 1
        for mirror, limb in self.roles.mirrors:
            if LIMB_RADIUS_INDEX[mirror] == radius_index:
                total += reach[limb] ** 2
                count += 1
        return total, count

    def radius_squared(self, radius_index: int, free_radius_m: float) -> float:
        """Effective ``r^2`` [m^2] of the y (1) or z (2) radius with the free limbs at a reach."""
        fixed, count = self._fixed_sum_m2(radius_index)
        return (fixed + (4 - count) * free_radius_m**2) / 4.0

    def free_radius_m(self, radius_index: int, radius_squared_m2: float) -> float | None:
        """The free limbs' reach [m] that gives an effective ``r^2``; None without free limbs."""
        fixed, count = self._fixed_sum_m2(radius_index)
        if count >= 4:
            return None
        return float(np.sqrt(max(0.0, (4.0 * radius_squared_m2 - fixed) / (4 - count))))

    def reachable(self, model: RobotModel) -> ReachableSet:
        """The reachable set that remains (the nominal one when nothing has failed)."""
        nominal = reachable_set(model)
        if self.roles.healthy:
            return nominal
        lo = nominal.radius_min_m.copy()
        hi = nominal.radius_max_m.copy()
        if self.roles.reel_locked and self.tether_length_m is not None:
            lo[0] = hi[0] = self.tether_length_m / 2.0
        for axis in (1, 2):
            lo[axis] = np.sqrt(self.radius_squared(axis, float(nominal.radius_min_m[axis])))
            hi[axis] = np.sqrt(self.radius_squared(axis, float(nominal.radius_max_m[axis])))
        tol = FIXED_RADIUS_TOLERANCE_M
        narrow = hi - lo < 2.0 * tol
        middle = 0.5 * (lo + hi)
        lo = np.where(narrow, middle - tol, lo)
        hi = np.where(narrow, middle + tol, hi)
        return replace(
            nominal,
            radius_min_m=_read_only(lo),
            radius_max_m=_read_only(hi),
            inertia_min_kg_m2=_read_only(principal_inertia(model, lo)),
            inertia_max_kg_m2=_read_only(principal_inertia(model, hi)),
        )


def remaining_shape(
    model: RobotModel,
    failed_joints: Iterable[int],
    joint_positions: Sequence[float],
    moving_faults: Iterable[int] = (),
) -> RemainingShape:
    """The :class:`RemainingShape` of the failed joints, the held limbs where ``joint_positions``
    (25, measured) put them; ``moving_faults``: the failed joints that move (limp)."""
    failed_joints = frozenset(failed_joints)
    roles = LimbRoles.from_failed_joints(failed_joints)
    q = np.asarray(joint_positions, dtype=float)
    reach = limb_reaches_m(model, q)
    return RemainingShape(
        roles,
        frozenset(failed_joints),
        frozenset(moving_faults),
        tuple((limb, float(reach[limb])) for limb in sorted(roles.held)),
        float(q[TETHER_INDEX]) if roles.reel_locked else None,
    )


def _read_only(a: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.array(a, dtype=float)
    out.flags.writeable = False
    return out
