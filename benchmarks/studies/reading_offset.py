"""Stop 47 (``docs/gait.md``, *Stop 47, the rig's reading offset*): what a rig read through the
CMU template adds to a walker's posture offset, subject by subject.

A rig's pose is read in the model's joint space through the CMU template's rest directions and
axes (``core.rigs.gait_space``; the template is subject 08's ASF). A walk keyed on a rig was made
on some other skeleton (the test rigs carry subject 35's walk, retargeted bone direction by bone
direction): its rest convention -- where its bones point at rest, how its joints' axes sit --
differs from the template's, and read through the template every frame carries a constant
difference in the angle channels, the *reading offset* ``r_s``. Nothing on the rig tells it:
a rig at rest reads zero whatever walk is keyed on it.

Per subject with its own ASF (the clips of ``sample_scenes/data/cmu``, its ``not_gaits`` and
``style_walks`` folders: 05, 06, 08, 35, 49, 64, 74, 79, 120, 124, 126), one clip is
retargeted onto the synthetic rig of ``tests/core/test_rigs_gait_space.SyntheticRig`` (each
bone its CMU bone's world rotation change after turning its rest direction the least onto the
CMU bone's, as ``sample_scenes/rig_walk.py`` keys the test rigs), read through the template as
Predict reads a reference range, and compared with the clip's own DOFs: ``r_s`` is the
per-channel median difference (observed angle channels; its spread over the clip says
whether it is a constant). The spread of ``r_s`` over the subjects, ``E_s[r_s²]``, is the variance
:data:`core.rigs.gait_space.READING_OFFSET_SD` ships (``--table`` prints it): a walker read
through the template has the offset prior ``N(0, offset_var · c^p + r²)``, of which only the
walker's part is tightened on a short window (``core.gait.em.short_window_context``).

Run (seconds)::

    .venv/bin/python benchmarks/studies/reading_offset.py [--table] [--without 35]
"""

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from core.gait import load_stock_library  # noqa: E402
from core.mocap import read_amc, read_asf  # noqa: E402
from tests.core.test_rigs_gait_space import SyntheticRig  # noqa: E402

CMU = ROOT / "sample_scenes" / "data" / "cmu"
FOLDERS = (CMU, CMU / "not_gaits", CMU / "style_walks")
FRAMES = 240                                  # 2 s of the clip at 120 Hz


def subject_clips():
    """{subject: (its ASF path, its first clip's AMC path)} of every subject with an ASF."""
    out = {}
    for folder in FOLDERS:
        for asf in sorted(folder.glob("*.asf")):
            clips = sorted(folder.glob(f"{asf.stem}_*.amc"))
            if clips and asf.stem not in out:
                out[asf.stem] = (asf, clips[0])
    return out


def reading_offset(asf_path, amc_path, model, seed=47):
    """(r, spread): per model angle channel (radians; NaN where the rig does not observe it),
    the median over the clip's frames of rig read − own DOFs (wrapped), and half the spread of
    its middle 80 % (an Euler branch the two readings take differently near a pole, as 64's
    raised arm, is a few frames, not an offset)."""
    asf = read_asf(asf_path)
    values = read_amc(amc_path, asf).values[:FRAMES]
    rig = SyntheticRig(asf, values=values, rng=np.random.default_rng(seed), two_neck=True)
    space = rig.space()
    dofs = space.dofs(rig.root_translation, rig.local)
    names = list(rig.cmu.dof_names())
    r = np.full(model.n_angles, np.nan)
    spread = np.full(model.n_angles, np.nan)
    for k, name in enumerate(model.angle_names):
        col = space.dof_names.index(name)
        if not space.observed[col]:
            continue
        d = (dofs[:, col] - values[:, names.index(name)] + np.pi) % (2 * np.pi) - np.pi
        r[k] = np.median(d)
        spread[k] = np.diff(np.percentile(d, [10, 90]))[0] / 2
    return r, spread


def table_sd(offsets):
    """Root mean square over subjects (rows) of each channel's reading offset (NaN where no
    subject's rig observes the channel)."""
    seen = np.any(np.isfinite(offsets), axis=0)
    sd = np.full(offsets.shape[1], np.nan)
    sd[seen] = np.sqrt(np.nanmean(offsets[:, seen] ** 2, axis=0))
    return sd


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--table", action="store_true", help="print the READING_OFFSET_SD table")
    ap.add_argument("--without", nargs="*", default=(), help="subjects left out of the table")
    args = ap.parse_args(argv)
    model = load_stock_library()
    rows = {}
    for subject, (asf, amc) in subject_clips().items():
        r, spread = reading_offset(asf, amc, model)
        rows[subject] = r
        big = np.argsort(-np.abs(np.nan_to_num(r)))[:4]
        print(f"{subject:>4s} {amc.stem:8s} max spread over the clip "
              f"{np.degrees(np.nanmax(spread)):5.2f}°; largest |r|: " + ", ".join(
                  f"{model.angle_names[i]} {np.degrees(r[i]):+.1f}°" for i in big))
    kept = np.array([r for s, r in rows.items() if s not in args.without])
    sd = table_sd(kept)
    print(f"sd over {len(kept)} subjects (deg): " + ", ".join(
        f"{n} {np.degrees(v):.1f}" for n, v in zip(model.angle_names, sd) if v > np.radians(1)))
    if args.table:
        print("READING_OFFSET_SD = {  # degrees")
        for n, v in zip(model.angle_names, sd):
            if np.isfinite(v):
                print(f'    "{n}": {np.degrees(v):.2f},')
        print("}")
    return rows


if __name__ == "__main__":
    main()
