"""The acceptance bench read through a rig (``benchmarks/gait_acceptance.py``, ``acceptance_rig``;
issue 21 §2, docs/gait_rigs.md *Stop 47*): a window is read from the rig as Predict Gait reads a
range, and the windows the two reads decide differently are the ones listed."""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import gait_acceptance as A  # noqa: E402
from core.gait import load_stock_library  # noqa: E402

#: Joints a synthetic rig has no bone for (``SyntheticRig``: one neck bone, no fingers or
#: thumbs); the head then turns from the neck's bone, so its DOFs are not the mocap's either.
NOT_SHOWN = ("upperneck", "head", "lfingers", "rfingers", "lthumb", "rthumb")


@pytest.fixture(scope="module")
def walk():
    """Subject 08's walk (its own skeleton, the CMU template's), its model and both readers."""
    model = load_stock_library()
    path = A.CMU / "08_01.amc"
    values, names = A.load(path)
    return (model, values, names, A.mocap_reader(model, values, names),
            A.rig_reader(model, A.synthetic_rig(path, values)))


@pytest.mark.parametrize("start", [0, 37, 75])
def test_a_window_read_through_the_rig_is_the_mocaps_window(walk, start):
    """Reading a rig gives back the walk it was retargeted from (``GaitSpace.dofs``, exact to
    round-off: ``tests/core/test_rigs_gait_space``), so the window the rig reader reads on its
    own is the mocap's window: every angle of a joint the rig shows, the root's height and
    tilt, and the root's rates from the window's second frame on (its first frame's rates
    need the frame before the window, which a range read alone does not have: the mocap's
    rows are the clip's). The joints the rig lacks are held at the model's mean pose, as
    Predict holds them (``bridge.model_hold``)."""
    model, values, names, mocap, rig = walk
    n = int(round(1.0 * A.FPS))
    want, got = mocap(start, n), rig(start, n)
    assert got.shape == want.shape == (n, len(model.channel_names))
    shown = [k for k, c in enumerate(model.channel_names[:model.n_angles])
             if c.split(".")[0] not in NOT_SHOWN]
    hidden = [k for k, c in enumerate(model.channel_names[:model.n_angles])
              if c.split(".")[0] in NOT_SHOWN[2:]]
    assert len(shown) > 40 and hidden
    np.testing.assert_allclose(got[:, shown], want[:, shown], rtol=0, atol=1e-8)
    root = list(range(model.n_angles, len(model.channel_names)))
    np.testing.assert_allclose(got[1:, root], want[1:, root], rtol=0, atol=1e-8)
    centre = model.angle_centre[:model.n_angles]
    np.testing.assert_allclose(got[:, hidden], np.broadcast_to(centre[hidden], (n, len(hidden))),
                               rtol=0, atol=1e-12)


def _decisions(rng, windows=("0.5", "1", "3")):
    return {w: [(int(s), bool(rng.random() < 0.5), None) for s in range(0, 150, 15)]
            for w in windows}


def _with_reasons(decisions, word):
    return {w: [(s, ok, None if ok else f"{word} {s}") for s, ok, _ in rows]
            for w, rows in decisions.items()}


def test_the_disagreements_are_the_windows_the_two_reads_decide_differently():
    """Every window decided differently, once, with the refusing read's reason; windows
    decided alike are not listed; windows that are not the same start raise."""
    rng = np.random.default_rng(4)
    mocap = _with_reasons(_decisions(rng), "mocap")
    rig = _with_reasons({w: [(s, ok if rng.random() < 0.7 else not ok, None)
                             for s, ok, _ in rows] for w, rows in mocap.items()}, "rig")
    got = A.disagreements(mocap, rig)
    want = {(float(w), s) for w in mocap for (s, a, _), (_, b, _) in zip(mocap[w], rig[w])
            if a != b}
    assert want and len(got) == len(want)
    assert {(d["window"], round(d["start_s"] * A.FPS)) for d in got} == want
    for d in got:
        s = round(d["start_s"] * A.FPS)
        assert d["mocap"] != d["rig"]
        assert d["refusal"] == (f"rig {s}" if d["mocap"] else f"mocap {s}")
    assert A.disagreements(mocap, mocap) == []
    shifted = {w: [(s + 1, ok, r) for s, ok, r in rows] for w, rows in rig.items()}
    with pytest.raises(AssertionError):
        A.disagreements(mocap, shifted)


def test_a_kinds_rates_count_the_windows_of_its_clips():
    """The headline counts every window of ``HEADLINE_MIN_S`` and more over every clip; per
    window the windows of every clip that has that window; each refusal counted by reason."""
    rng = np.random.default_rng(5)
    decided = {"a": _with_reasons(_decisions(rng), "no"),
               "b": _with_reasons(_decisions(rng, ("0.5", "1.25")), "no")}
    block = A.kind_block({c: A.decision_rows(d) for c, d in decided.items()})
    head = [ok for d in decided.values() for w, rows in d.items()
            if float(w) >= A.HEADLINE_MIN_S for _, ok, _ in rows]
    assert block["windows"] == len(head) == 30
    assert block["accepted"] == sum(head)
    assert block["accept_rate"] == sum(head) / 30
    assert block["per_window"]["0.5"]["windows"] == 20
    assert block["per_window"]["1.67"] == {"windows": 0, "accept_rate": None}
    for c, d in decided.items():
        for w, rows in d.items():
            refusals = block["clips"][c][w]["refusals"]
            assert refusals == {f"no {s}": 1 for s, ok, _ in rows if not ok}
