"""The one list of joint names and the indices derived from it."""

from __future__ import annotations

from splitter_model.joints import (
    JOINT_INDEX,
    JOINT_NAMES,
    LIMB_HEMI_SIGNS,
    LIMB_JOINT_SLICE,
    LIMB_JOINTS,
    LIMB_NAMES,
    LIMB_RADIUS_INDEX,
    N_JOINTS,
    N_LIMBS,
    TETHER_INDEX,
    TETHER_JOINT,
    limb_joint_index,
    limb_joints,
    limbs_along,
)


def test_joint_names_are_eight_limbs_of_three_then_the_tether() -> None:
    assert N_JOINTS == 25 == len(set(JOINT_NAMES)) and N_LIMBS == 8
    assert JOINT_NAMES[TETHER_INDEX] == TETHER_JOINT and TETHER_INDEX == N_JOINTS - 1
    assert all(JOINT_INDEX[name] == i for i, name in enumerate(JOINT_NAMES))
    assert JOINT_NAMES[LIMB_JOINT_SLICE] == JOINT_NAMES[:TETHER_INDEX]


def test_limb_helpers_index_the_joints_by_name() -> None:
    for limb, name in enumerate(LIMB_NAMES):
        assert JOINT_NAMES[limb_joints(limb)] == tuple(f"{name}_{j}" for j in LIMB_JOINTS)
        assert JOINT_NAMES[limb_joint_index(limb, "knee")] == f"{name}_knee"
        assert LIMB_HEMI_SIGNS[limb] == (1.0 if name.startswith("hemi_a") else -1.0)
        assert LIMB_RADIUS_INDEX[limb] == (1 if "_y_" in name else 2)
    assert limbs_along("y") == (0, 1, 4, 5) and limbs_along("z") == (2, 3, 6, 7)
