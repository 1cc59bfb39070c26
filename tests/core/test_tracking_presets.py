"""Yamamoto Table 1 as a DOF mask on the CMU skeleton."""

import numpy as np
import pytest

from core.mocap import asf_to_skeleton, read_asf
from core.tracking.presets import CMU_PARTS, RIG_PARTS, TABLE1, find_table1_parts, table1_dof_mask
from tests.data import cmu_path


@pytest.fixture(scope="module")
def cmu():
    return asf_to_skeleton(read_asf(cmu_path("08.asf")))


def test_table1_totals_23_dofs(cmu):
    mask, translation = table1_dof_mask(cmu)
    assert sum(TABLE1.values()) == 23
    assert mask.sum() + translation.sum() == 23
    for part, joint in CMU_PARTS.items():
        j = cmu.index(joint)
        expected = TABLE1[part] - (3 if part == "Waist" else 0)
        assert mask[j].sum() == expected, part
    # Everything else (spine above the chest, neck, clavicles, hands, feet...) is frozen.
    others = [j for j in range(cmu.n_joints) if cmu.names[j] not in CMU_PARTS.values()]
    assert not mask[others].any()


def test_table1_axes_by_role(cmu):
    mask, _ = table1_dof_mask(cmu)
    x, y, z = 0, 1, 2                      # CMU limbs lie along their joint's Y axis
    assert list(np.nonzero(mask[cmu.index("lfemur")])[0]) == [x, z]      # swing, no twist
    assert list(np.nonzero(mask[cmu.index("rtibia")])[0]) == [x]         # hinge
    assert list(np.nonzero(mask[cmu.index("lhumerus")])[0]) == [x, z]
    assert list(np.nonzero(mask[cmu.index("head")])[0]) == [x, y]        # nod and turn


def test_custom_mapping_and_errors(cmu):
    mask, translation = table1_dof_mask(cmu, {"Waist": "root", "Head": None})
    assert mask.sum() == 3 and translation.all()
    with pytest.raises(ValueError, match="unknown body parts"):
        table1_dof_mask(cmu, {"Tail": "root"})
    with pytest.raises(KeyError, match="Unknown joint"):
        table1_dof_mask(cmu, {"Chest": "spine"})


def test_rig_presets_are_found_by_bone_names(cmu):
    for rig, parts in RIG_PARTS.items():
        assert set(parts) == set(TABLE1), rig
        names = list(parts.values()) + ["extra_bone", "another"]
        found, mapping = find_table1_parts(names)
        assert found == rig and mapping == parts
    # A metarig without its head bone: still recognised, the Head part is skipped.
    names = [b for b in RIG_PARTS["Blender metarig"].values() if b != "spine.006"]
    rig, mapping = find_table1_parts(names)
    assert rig == "Blender metarig" and mapping["Head"] is None
    # The CMU skeleton's own joint names give CMU_PARTS.
    assert find_table1_parts(cmu.names) == ("CMU (Acclaim)", CMU_PARTS)


def test_non_humanoid_rigs_are_refused_with_the_missing_names():
    with pytest.raises(ValueError, match="closest: Mixamo, missing .*mixamorig:LeftLeg"):
        find_table1_parts(["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Head",
                           "mixamorig:LeftUpLeg", "Tail"])
    with pytest.raises(ValueError, match="^Simplified Joints knows the bone names of CMU, CMU "
                                         "BVH, Mixamo and Blender's metarig, and this rig is "
                                         "none of them"):
        find_table1_parts(["Bone", "Bone.001"])
