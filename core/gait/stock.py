"""The stock gait library shipped with the extension: a model learned from the CMU walks and runs
of ``sample_scenes/data/cmu`` with named styles, so that every .blend can predict a walk with no
learning step (``docs/gait.md``, *Stock gait library*).

The file ``core/gait/data/stock_gaits.npz`` is a :class:`~.model.GaitModel` file (format 2, with
its checksum), built by ``tools/build_stock_gaits.py`` (``make stock-gaits``) from
:data:`STOCK_RECIPE`: every trial is cut into steady pieces (:mod:`.segments`), each piece is a
training sequence, the pieces of one style name become one learned style, and the walkers
(CMU subjects) give the posture-offset prior. Loading needs NumPy only.
"""

from pathlib import Path

from .model import GaitModel, GaitModelFileError

__all__ = ["STOCK_LAG_RANGE", "STOCK_NAME", "STOCK_PATH", "STOCK_RECIPE", "STOCK_VERSION",
           "load_stock_library"]

STOCK_VERSION = 2
STOCK_NAME = "Stock Gaits"
STOCK_PATH = Path(__file__).resolve().parent / "data" / "stock_gaits.npz"

# Style name -> CMU trials (all at 120 Hz in sample_scenes/data/cmu; subject = prefix).
STOCK_RECIPE = {
    "normal": ("07_04", "07_05", "35_01", "35_02", "35_03", "35_04", "35_05", "35_06", "35_07",
               "35_08"),
    "slow": ("08_04",),
    "long stride": ("08_07",),
    "brisk": ("08_01",),
    "stroll": ("91_10", "91_27"),
    "bouncy": ("132_29", "132_30", "132_31", "132_32"),
    "careful": ("139_29", "139_31", "139_32"),
    "run": ("35_17", "35_18", "35_20", "35_21"),
    "dribble": ("06_02", "06_03"),
    "stiff": ("74_01", "74_20"),
    "sneaking": ("120_09", "120_10", "120_11"),
}
# Periods searched when learning (seconds): the sneaking walks of 120 take 2.0-2.5 s a stride.
STOCK_LAG_RANGE = (0.5, 3.0)

_CACHE = {}


def load_stock_library(path=None):
    """The stock :class:`GaitModel` (cached after the first load).

    Raises
    ------
    GaitModelFileError
        When the shipped file is missing or fails its checksum or checks.
    """
    path = Path(path) if path is not None else STOCK_PATH
    key = str(path)
    if key not in _CACHE:
        if not path.exists():
            raise GaitModelFileError(f"{path}: the stock gait library is missing from this "
                                     "installation (rebuild it with make stock-gaits)")
        _CACHE[key] = GaitModel.load(path)
    return _CACHE[key]
