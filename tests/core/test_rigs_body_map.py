"""Body maps: recognised rigs, the refusal of a rig that lacks parts, name patterns for other
humanoids, preset files (round trip; a malformed file names the file and line)."""

import json

import numpy as np
import pytest

from core.rigs import (OPTIONAL, PARTS, REQUIRED, BodyMapError, BoneConstraint, RigBones,
                       body_map_from_json, body_map_to_json, pattern_body_map,
                       read_body_map, recognise_body_map, write_body_map)
from rig_bone_lists import arp_rig, cmu_acclaim_rig, cmu_bvh_rig, mixamo_rig, stored_rig


def test_generated_rigify_maps_deforming_bones_pose_bones_controls_and_ik():
    m = recognise_body_map(stored_rig("rigify"))
    assert m.rig == "Rigify" and m.travel_control == "torso" and not m.missing()
    thigh = m.parts["left thigh"]
    assert thigh.bones == ("DEF-thigh.L", "DEF-thigh.L.001")          # segments belong to it
    assert (thigh.pose, thigh.control) == ("ORG-thigh.L", "thigh_fk.L")
    assert m.parts["hips"].control == "hips" and m.parts["spine"].control is None
    leg = m.limbs["right leg"]
    assert (leg.target, leg.pole, leg.twist) == ("foot_ik.R", "thigh_ik_target.R", "thigh_ik.R")
    assert (leg.switch.bone, leg.switch.property) == ("thigh_parent.R", "IK_FK")
    assert leg.switch.is_on(0.0) and not leg.switch.is_on(1.0)        # Rigify: 0 = IK
    assert m.parts["right foot"].ik_control == "foot_ik.R"
    # No face, finger, tweak or mechanism bone among the deforming bones of the map.
    deforming = {b for p in m.parts.values() for b in p.bones}
    assert all(b.startswith("DEF-") for b in deforming)
    assert not any(w in b for b in deforming for w in ("face", "f_", "palm", "tweak", "lip"))
    rig = stored_rig("rigify")
    assert m.bones() <= set(rig.names)


def test_metarig_mixamo_arp_and_cmu_are_recognised():
    expected = {"Blender metarig": stored_rig("metarig"), "Mixamo": mixamo_rig(),
                "Auto-Rig Pro": arp_rig(), "CMU (Acclaim)": cmu_acclaim_rig()[0],
                "CMU (BVH)": cmu_bvh_rig()}
    for kind, rig in expected.items():
        m = recognise_body_map(rig)
        assert m.rig == kind and not m.missing(), kind
        assert set(m.parts) == set(PARTS), kind
        assert m.bones() <= set(rig.names), kind
    mixamo = recognise_body_map(mixamo_rig())
    assert mixamo.parts["left thigh"].bones == ("mixamorig:LeftUpLeg",)
    assert mixamo.parts["left thigh"].control == "mixamorig:LeftUpLeg"
    arp = recognise_body_map(arp_rig())
    assert arp.parts["left thigh"].bones == ("thigh_stretch.l", "thigh_twist.l")
    assert arp.limbs["left leg"].switch.property == "ik_fk_switch"
    assert recognise_body_map(cmu_bvh_rig()).parts["hips"].bones == ("Hips", "LHipJoint",
                                                                     "RHipJoint")


@pytest.mark.parametrize("prefix", ["mixamorig:", "mixamorig1:", "mixamorig_", ""])
def test_mixamo_prefixes_and_leaf_bones(prefix):
    m = recognise_body_map(mixamo_rig(prefix, leaf_bones=True))
    assert m.rig == "Mixamo" and m.parts["head"].bones == (f"{prefix}Head",)
    assert not any(b.endswith("_end") for b in m.bones())


def test_a_rig_missing_parts_is_refused_in_plain_words_pointing_at_the_panel():
    rig = mixamo_rig(drop=("LeftHand", "LeftFoot") + tuple(
        f"LeftHand{f}{k}" for f in ("Thumb", "Index", "Middle", "Ring", "Pinky")
        for k in range(1, 5)) + ("LeftToeBase", "LeftToe_End"))
    with pytest.raises(BodyMapError) as err:
        recognise_body_map(rig)
    message = str(err.value)
    assert "Mixamo" in message and "left hand" in message and "left foot" in message
    assert "Body Map panel" in message
    assert "LeftHand" not in message                      # parts, not bone names
    # A rig that is nothing humanoid.
    with pytest.raises(BodyMapError, match="Body Map panel"):
        recognise_body_map(RigBones(["Bone", "Bone.001"], [-1, 0], [True, True]))


def test_optional_parts_may_be_missing():
    rig = mixamo_rig(drop=("LeftShoulder", "RightShoulder", "Neck", "LeftToeBase",
                           "LeftToe_End"))
    m = recognise_body_map(rig)
    assert not m.missing()
    assert {"left clavicle", "right clavicle", "neck", "left toe"}.isdisjoint(m.parts)
    assert {"left clavicle", "neck", "left toe", "spine"} <= OPTIONAL
    assert set(REQUIRED) | OPTIONAL == set(PARTS)


def test_ik_constraints_of_a_plain_rig_make_limb_maps():
    base = stored_rig("metarig")
    names = list(base.names) + ["foot_ik.L", "knee_pole.L"]
    parents = list(base.parents) + [-1, -1]
    cons = list(base.constraints) + [(), ()]
    i = names.index("shin.L")
    cons[i] = (BoneConstraint("IK", "IK", "foot_ik.L", "knee_pole.L", True, 1.0, 2),)
    j = names.index("foot.L")
    cons[j] = (BoneConstraint("COPY_ROTATION", "Copy Rotation", "foot_ik.L"),)
    m = recognise_body_map(RigBones(names, parents, np.ones(len(names), bool), tuple(cons)))
    leg = m.limbs["left leg"]
    assert (leg.target, leg.pole, leg.switch.constraint) == ("foot_ik.L", "knee_pole.L", "IK")
    assert leg.target_rotates_end and m.parts["left foot"].ik_control == "foot_ik.L"
    assert "right leg" not in m.limbs


def test_name_patterns_fill_a_renamed_humanoid():
    """A humanoid with names no recogniser knows (``Thigh_L``, ``Calf_L``, ``Pelvis``, a
    ``Spine`` chain) is filled from name patterns and the tree."""
    tree = [("Root", None), ("Pelvis", "Root"), ("Spine_01", "Pelvis"), ("Spine_02", "Spine_01"),
            ("Spine_03", "Spine_02"), ("Neck_01", "Spine_03"), ("Head", "Neck_01"),
            ("Jaw", "Head"), ("Eye_L", "Head")]
    for s in "LR":
        tree += [(f"Clavicle_{s}", "Spine_03"), (f"UpperArm_{s}", f"Clavicle_{s}"),
                 (f"LowerArm_{s}", f"UpperArm_{s}"), (f"Hand_{s}", f"LowerArm_{s}"),
                 (f"Index_01_{s}", f"Hand_{s}"), (f"Thigh_{s}", "Pelvis"),
                 (f"Calf_{s}", f"Thigh_{s}"), (f"Foot_{s}", f"Calf_{s}"),
                 (f"Ball_{s}", f"Foot_{s}")]
    index = {n: i for i, (n, _) in enumerate(tree)}
    rig = RigBones([n for n, _ in tree], [index[p] if p else -1 for _, p in tree],
                   [n != "Root" for n, _ in tree])
    m = recognise_body_map(rig)
    assert m.rig == "Custom" and not m.missing()
    got = {p: m.parts[p].bones for p in m.parts}
    assert got["hips"] == ("Pelvis",) and got["chest"] == ("Spine_03",)
    assert got["spine"] == ("Spine_01", "Spine_02") and got["head"] == ("Head",)
    assert got["left shin"] == ("Calf_L",) and got["right toe"] == ("Ball_R",)
    assert got["left forearm"] == ("LowerArm_L",) and got["neck"] == ("Neck_01",)
    # The same patterns find the metarig as its own recogniser does.
    metarig = stored_rig("metarig")
    auto, known = pattern_body_map(metarig), recognise_body_map(metarig)
    assert {p: v.bones[0] for p, v in auto.parts.items()} == \
        {p: v.bones[0] for p, v in known.parts.items()}


def test_preset_files_round_trip(tmp_path):
    for rig in (stored_rig("rigify"), mixamo_rig(), arp_rig()):
        m = recognise_body_map(rig)
        path = tmp_path / "map.json"
        write_body_map(path, m)
        assert read_body_map(path) == m
        assert body_map_from_json(body_map_to_json(m)) == m


def _broken(text, old, new):
    assert old in text
    return text.replace(old, new, 1)


@pytest.mark.parametrize("change, message", [
    (lambda t: _broken(t, '"control": "thigh_fk.L"', '"control": "thigh_fk.L",,'),
     "not a JSON file"),
    (lambda t: _broken(t, '"left thigh": {', '"left tigh": {'), "unknown part 'left tigh'"),
    (lambda t: _broken(t, '"control": "shin_fk.R"', '"control": 3'), "expected a bone name"),
    (lambda t: _broken(t, '"bones": [\n        "DEF-foot.L"\n      ]', '"bones": []'),
     "must list its deforming bones"),
    (lambda t: _broken(t, '"property": "IK_FK"', '"property": "IK_FK", "constraint": "IK"'),
     "either a custom"),
    (lambda t: _broken(t, '"target_rotates_end": true', '"target_rotates_end": 1'),
     "true or false"),
    (lambda t: _broken(t, '"version": 1', '"version": 7'), "version 7"),
    (lambda t: _broken(t, '"format": "track_and_stride.body_map"', '"format": "x"'),
     "not a Track & Stride body map"),
])
def test_a_malformed_preset_names_the_file_and_the_line(tmp_path, change, message):
    text = body_map_to_json(recognise_body_map(stored_rig("rigify")))
    bad = change(text)
    path = tmp_path / "bad.json"
    path.write_text(bad)
    with pytest.raises(BodyMapError) as err:
        read_body_map(path)
    text_err = str(err.value)
    assert text_err.startswith(f"{path}, line ") and message in text_err
    line = int(text_err.split("line ")[1].split(":")[0])
    # The line named is the line that was changed.
    changed = next(i for i, (a, b) in enumerate(zip(text.splitlines(), bad.splitlines()))
                   if a != b) + 1
    assert line == changed, (line, changed, text_err)


def test_a_preset_that_is_not_text_is_refused(tmp_path):
    path = tmp_path / "bad.json"
    path.write_bytes(b'{\n"format": "\xff"}\n')
    with pytest.raises(BodyMapError, match=r"line 2: not UTF-8"):
        read_body_map(path)


def test_check_names_missing_parts_and_unknown_bones():
    m = recognise_body_map(mixamo_rig())
    with pytest.raises(BodyMapError, match=r"lacks \(mixamorig:LeftUpLeg\)"):
        m.check("Armature", bone_names=set(mixamo_rig().names) - {"mixamorig:LeftUpLeg"})
    parts = dict(m.parts)
    del parts["right shin"]
    from core.rigs import BodyMap
    with pytest.raises(BodyMapError, match="the right shin: fill them in the Body Map panel"):
        BodyMap("Mixamo", parts, m.travel).check("Armature")
    json.loads(body_map_to_json(m))
