"""Paths of the project's test data (CMU excerpts shipped in sample_scenes/data/cmu)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CMU_DIR = ROOT / "sample_scenes" / "data" / "cmu"
TRIALS = sorted(p.stem for p in CMU_DIR.glob("*.amc"))


def cmu_path(name):
    """Path of a CMU file, e.g. ``cmu_path('08_01.amc')``."""
    return CMU_DIR / name


def asf_path(trial):
    """Skeleton file of a trial: '08_01' -> .../08.asf."""
    return CMU_DIR / (trial.split("_")[0] + ".asf")
