"""``make bench-rigs``' error breakdown (``benchmarks/bench_rigs.py``), without bpy: the 26
deforming joints' names and regions, and the per-region, per-joint, per-frame and at-keys
means against direct computations."""

import numpy as np

from benchmarks.bench_rigs import REGIONS, error_breakdown, joint_names, region_of
from sample_scenes.rig_footage import END_PARTS, part_joints
from sample_scenes.rig_specs import PARTS


def test_joint_names_follow_part_joints_order():
    names = joint_names()
    # part_joints takes each part's first bone's head, then the end parts' last tails: give
    # every bone a distinct position and read back which bone each joint came from.
    parts = list(PARTS) + ["hand.L"]               # a segment of the left hand last
    n = len(parts)
    heads = np.arange(n, dtype=float)[None, :, None] * np.ones((1, 1, 3))
    tails = heads + 1000.0
    joints = part_joints(heads, tails, [f"b{i}" for i in range(n)], parts)
    assert joints.shape[1] == len(names) == len(PARTS) + len(END_PARTS)
    for name, joint in zip(names, joints[0, :, 0]):
        if name.endswith(" tip"):
            part = name[:-len(" tip")]
            last = n - 1 - parts[::-1].index(part)
            assert joint == 1000.0 + last, name
        else:
            assert joint == parts.index(name), name


def test_every_joint_has_one_region():
    regions = [region for region, _ in REGIONS]
    got = [region_of(n) for n in joint_names()]
    assert set(got) == set(regions)
    assert got[joint_names().index("toe.R tip")] == "feet"
    assert got[joint_names().index("head tip")] == "head"
    assert got[joint_names().index("clavicle.L")] == "arms"
    assert got[joint_names().index("shin.R")] == "legs"
    assert got[joint_names().index("neck")] == "trunk"


def test_breakdown_means_match_direct_computation():
    rng = np.random.default_rng(3)
    frames = list(range(1, 32))
    keys = [1, 16, 31]
    errors = rng.uniform(0.5, 5.0, size=(len(frames), len(joint_names())))
    errors[[0, 15, 30]] = 0.0                      # the keys are the truth
    errors[15, 4] = 0.25                           # ...but one joint is off at a key
    out = error_breakdown(errors, frames, keys)
    inner = np.delete(errors, [0, 15, 30], axis=0)
    names = joint_names()
    for region, value in out["in_between_by_region_cm"].items():
        cols = [i for i, n in enumerate(names) if region_of(n) == region]
        assert np.isclose(value, inner[:, cols].mean())
    assert np.allclose(list(out["in_between_by_joint_cm"].values()), inner.mean(axis=0))
    assert list(out["in_between_by_joint_cm"]) == names
    assert np.allclose(out["per_frame_cm"], errors.mean(axis=1))
    assert np.isclose(out["at_keys_cm"], 0.25 / (3 * len(names)))
    assert out["at_keys_max_cm"] == 0.25
    # The regions weight joints equally: their joint-weighted mean is the overall mean.
    sizes = {r: sum(region_of(n) == r for n in names) for r, _ in REGIONS}
    total = sum(out["in_between_by_region_cm"][r] * sizes[r] for r in sizes) / len(names)
    assert np.isclose(total, inner.mean())
