"""SPLITTER's 25 actuated joints: the one list of their names, and each joint's index in it.

Hemi "a" sits at +x (sign s = +1), hemi "b" at -x (s = -1). Each hemi has four
limbs, each named by the body axis it reaches along (:data:`LIMB_AXES`), with three
joints (:data:`LIMB_JOINTS`); the prismatic tether (the distance between the two
hemi bodies [m]) comes last. Every array of joint values in the project (messages,
simulator, allocator, actuator limits) is in :data:`JOINT_NAMES` order;
``splitter_msgs_py.names`` takes its joint names from here. Index a joint by name
(:data:`JOINT_INDEX`) or a limb's joints by limb (:func:`limb_joints`), never by
arithmetic on literal numbers.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Final

HEMIS: Final = ("a", "b")
HEMI_SIGNS: Final[Mapping[str, float]] = MappingProxyType({"a": 1.0, "b": -1.0})
# Each hemi has four limbs; a limb is named by the body axis it reaches along.
LIMB_AXES: Final = ("y_pos", "y_neg", "z_pos", "z_neg")
LIMB_NAMES: Final = tuple(f"hemi_{h}_{axis}" for h in HEMIS for axis in LIMB_AXES)
LIMB_JOINTS: Final = ("hip_abduction", "hip_pitch", "knee")
TETHER_JOINT: Final = "tether"  # prismatic: distance between the two hemi bodies [m]
JOINT_NAMES: Final = (
    *(f"{limb}_{joint}" for limb in LIMB_NAMES for joint in LIMB_JOINTS),
    TETHER_JOINT,
)
JOINT_INDEX: Final[Mapping[str, int]] = MappingProxyType(
    {name: i for i, name in enumerate(JOINT_NAMES)}
)
N_JOINTS: Final = len(JOINT_NAMES)  # 8 limbs x 3 joints + tether = 25
N_LIMBS: Final = len(LIMB_NAMES)  # 8
TETHER_INDEX: Final = JOINT_INDEX[TETHER_JOINT]  # 24

# Per limb (LIMB_NAMES order): its hemi, that hemi's sign s, the axis it reaches along.
LIMB_HEMIS: Final = tuple(h for h in HEMIS for _ in LIMB_AXES)
LIMB_HEMI_SIGNS: Final = tuple(HEMI_SIGNS[h] for h in LIMB_HEMIS)
LIMB_AXIS_OF: Final = tuple(axis for _ in HEMIS for axis in LIMB_AXES)
# Which of the radii (r_x, r_y, r_z) each limb's reach is: 1 for the y limbs, 2 for z.
LIMB_RADIUS_INDEX: Final = tuple("xyz".index(axis[0]) for axis in LIMB_AXIS_OF)


def limb_joint_index(limb: int, joint: str) -> int:
    """Index of ``joint`` (one of :data:`LIMB_JOINTS`) of limb ``limb`` (0..7) in JOINT_NAMES."""
    return JOINT_INDEX[f"{LIMB_NAMES[limb]}_{joint}"]


def limb_joints(limb: int) -> slice:
    """The slice of limb ``limb``'s joints (:data:`LIMB_JOINTS` order) in JOINT_NAMES order."""
    first = limb_joint_index(limb, LIMB_JOINTS[0])
    return slice(first, first + len(LIMB_JOINTS))


def limbs_along(axis: str) -> tuple[int, ...]:
    """Limbs (indices into LIMB_NAMES) reaching along body axis ``axis`` ("y" or "z")."""
    return tuple(i for i, name in enumerate(LIMB_AXIS_OF) if name[0] == axis)


# All limb joints (every joint but the tether), as one slice of JOINT_NAMES order.
LIMB_JOINT_SLICE: Final = slice(limb_joints(0).start, limb_joints(N_LIMBS - 1).stop)
