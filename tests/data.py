"""Paths of the project's test data (CMU excerpts shipped in sample_scenes/data/cmu)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CMU_DIR = ROOT / "sample_scenes" / "data" / "cmu"
# Trials with their subject's own .asf (07, 91, 132 and 139 come without one: read them with
# core.mocap.bvh.cmu_template_asf(), see the data folder's README).
TRIALS = sorted(p.stem for p in CMU_DIR.glob("*.amc")
                if (CMU_DIR / (p.stem.split("_")[0] + ".asf")).exists())


def cmu_path(name):
    """Path of a CMU file, e.g. ``cmu_path('08_01.amc')``."""
    return CMU_DIR / name


def asf_path(trial):
    """Skeleton file of a trial: '08_01' -> .../08.asf."""
    return CMU_DIR / (trial.split("_")[0] + ".asf")
