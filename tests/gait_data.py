"""Cached CMU data and small models for the gait tests (tests/core/test_gait_*.py)."""

from functools import lru_cache
from pathlib import Path

import numpy as np

from core.mocap import asf_to_skeleton, read_amc, read_asf, resample
from tests.data import asf_path, cmu_path

SMALL_TRAIN = ("08_04", "08_07", "35_01", "35_02", "35_17")


def subject_asf(name):
    """The parsed ASF of a CMU trial's subject; the CMU template skeleton for a subject whose
    ASF the sample data lacks (07: the restyle table's held-out walker 07_04, as
    ``benchmarks/gait_lowo.load`` reads it)."""
    path = asf_path(name)
    if Path(path).exists():
        return read_asf(path)
    from core.mocap.bvh import cmu_template_asf
    return cmu_template_asf()


@lru_cache(maxsize=None)
def trial(name, fps=60):
    """(values (N, 62) read-only, dof names) of a CMU trial resampled from 120 Hz to ``fps``."""
    asf = subject_asf(name)
    values = read_amc(cmu_path(name + ".amc"), asf).values
    if fps != 120:
        values = resample(values, 120, fps, np.arange(3, values.shape[1]))
    values.setflags(write=False)
    return values, tuple(asf_to_skeleton(asf).dof_names())


@lru_cache(maxsize=None)
def small_model(n_styles=3, root_travel=True, n_phase=33):
    """A model learned from walks of two subjects and one run (about 0.5 s to learn)."""
    from core.gait import learn_model

    data = [trial(t) for t in SMALL_TRAIN]
    return learn_model([d[0] for d in data], data[0][1], 60.0, list(SMALL_TRAIN),
                       n_styles=n_styles, root_travel=root_travel, n_phase=n_phase)


@lru_cache(maxsize=None)
def observations(name, n_styles=3):
    """Observations of a trial for :func:`small_model` (60 Hz), read-only."""
    from core.gait import observations_from_dofs

    values, names = trial(name)
    obs = observations_from_dofs(small_model(n_styles), values, names, 60.0)
    obs.setflags(write=False)
    return obs


def adapted_walk(name, n_ref, fps=60.0):
    """The stock library batch-adapted to the first ``n_ref`` frames of CMU ``name`` at ``fps``:
    (model, skeleton, values (N, 62), dof names, observations (n_ref, D), AdaptResult)."""
    from core.gait import adapt, load_stock_library, observations_from_dofs
    model = load_stock_library()
    values, names = trial(name, int(fps))
    values = np.array(values)
    skeleton = asf_to_skeleton(subject_asf(name))
    obs = observations_from_dofs(model, values[:n_ref], names, fps)
    return model, skeleton, values, names, obs, adapt(model, obs, fps=fps)
