"""The reading offset's prior (``core.rigs.reading_offset``, docs/gait.md *Stop 47, the rig's
reading offset*): the shipped table is what the study measures on the CMU subjects' own ASFs,
and it enters the model's channels in scaled units."""

import sys
from pathlib import Path

import numpy as np

from core.gait import load_stock_library
from core.rigs.reading_offset import READING_OFFSET_SD, reading_offset_variance

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks" / "studies"))


def test_the_shipped_table_is_the_spread_of_the_subjects_reading_offsets():
    """Each subject with its own ASF walked on a synthetic rig and read through the template:
    the root mean square over the subjects of the per-channel offsets is the shipped table
    (to its rounding), the hips and knees read with no offset (a leg's bones point as the
    walk's), and the largest are where the CMU ASFs' rest conventions differ most (the
    clavicles and upper arms)."""
    import reading_offset as study

    model = load_stock_library()
    rows = {}
    for subject, (asf, amc) in study.subject_clips().items():
        rows[subject] = study.reading_offset(asf, amc, model)[0]
    assert len(rows) == 11 and "08" in rows and "35" in rows
    sd = np.degrees(study.table_sd(np.array(list(rows.values()))))
    measured = {n: v for n, v in zip(model.angle_names, sd) if np.isfinite(v)}
    assert set(measured) == set(READING_OFFSET_SD)
    for name, value in measured.items():
        assert abs(READING_OFFSET_SD[name] - value) <= 0.005 + 1e-9, (name, value)
    for name in ("lfemur.rx", "rfemur.rz", "ltibia.rx", "rtibia.rx"):
        assert measured[name] < 0.01
    arms = [n for n in measured if n[1:].split(".")[0] in ("clavicle", "humerus")]
    assert max(measured, key=measured.get) in arms
    assert min(measured[n] for n in ("rhumerus.ry", "lclavicle.ry", "rclavicle.rz")) > 5.0


def test_the_variance_is_the_tables_in_the_models_scaled_units():
    model = load_stock_library()
    var = reading_offset_variance(model)
    assert var.shape == (model.n_channels,)
    for k, name in enumerate(model.channel_names):
        sd = np.radians(READING_OFFSET_SD.get(name, 0.0))
        np.testing.assert_allclose(np.sqrt(var[k]) * model.channel_scale[k], sd, rtol=1e-12)
    assert np.all(var[model.n_angles:] == 0)               # root features: none
