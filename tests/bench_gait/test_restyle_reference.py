"""The restyle table's reference figures for the join (``benchmarks/gait_restyle.py``, issue 25
item 6; docs/gait.md, *Stop 39*): the join against the requested style's captured walks, and
the Euler flips of some captures left out of their angles' 99th percentile."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import gait_restyle as R  # noqa: E402
from core.gait.root_travel import ROOT_DOF_NAMES  # noqa: E402

H = 3                     # JOIN_SPACING_S at 60 fps


def test_the_join_against_the_walker_s_own_capture_as_style_is_the_goal_s_figure():
    """With the walker's own capture's 99th percentiles as the style's, the reference figures
    are the goal's, exactly (the same join, the same bound)."""
    values, names = R.gait_lowo.load("07_04")
    values = np.asarray(values)
    angles = [i for i, n in enumerate(names) if n not in ROOT_DOF_NAMES]
    root, ang = R.acceleration_norms(values, angles, H)
    own = (float(np.percentile(root, 99)), float(np.percentile(ang, 99)))
    out = R.join_ratio(values[:100], values[100:], values, list(names), 46.0, own)
    assert out["join_root_ratio_style"] == out["join_root_ratio"]
    assert out["join_angles_ratio_style"] == out["join_angles_ratio"]
    assert out["join_accel_ratio_style"] == max(out["join_root_ratio"], out["join_angles_ratio"])
    assert out["join_accel_ratio_either"] == out["join_accel_ratio_style"]
    # A style that accelerates twice as much halves the ratios; "either" keeps the larger bound.
    twice = R.join_ratio(values[:100], values[100:], values, list(names), 46.0,
                         (2 * own[0], 2 * own[1]))
    assert np.isclose(twice["join_root_ratio_style"], out["join_root_ratio"] / 2)
    assert np.isclose(twice["join_accel_ratio_either"], out["join_accel_ratio_style"] / 2)
    assert "join_accel_ratio_style" not in R.join_ratio(values[:100], values[100:], values,
                                                         list(names), 46.0)


def test_a_euler_flip_is_left_out_of_the_style_s_angles_but_not_its_root(monkeypatch):
    """08_01's and 06_03's hands jump by about π in one frame (an Euler flip), which read 2500
    and 1230 rad/s² at the angles' 99th percentile. A flip put into 07_04 (a hand angle + π over
    5 frames) leaves exactly the stencils that do not span it; the root is untouched."""
    clean, names = R.gait_lowo.load("07_04")
    clean = np.asarray(clean)
    angles = [i for i, n in enumerate(names) if n not in ROOT_DOF_NAMES]
    k = 120
    flipped = clean.copy()
    flipped[k:k + 5, names.index("rhand.rz")] += np.pi
    monkeypatch.setattr(R.gait_lowo, "load", lambda trial: (flipped, names))
    (root, ang), = R.style_join_p99({"x": ("07_04",)}).values()
    clean_root, clean_ang = R.acceleration_norms(clean, angles, H)
    # Stencil i (frames i, i + 3, i + 6) spans the steps into frame k and out of k + 4.
    keep = np.ones(len(clean_ang), dtype=bool)
    keep[k - 2 * H:k + 5] = False
    assert root == float(np.percentile(clean_root, 99))
    assert ang == float(np.percentile(clean_ang[keep], 99))
    unfiltered = np.percentile(R.acceleration_norms(flipped, angles, H)[1], 99)
    assert unfiltered > 3 * ang             # the flip alone would have set the bound
