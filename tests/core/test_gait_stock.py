"""core.gait.stock, segments and restyle: the shipped library, steady pieces of long captures,
restyling by named styles."""

import numpy as np
import pytest

from core.gait import STOCK_RECIPE, adapt, load_stock_library, observations_from_dofs, \
    periodicity, predict, restyle, steady_segments
from core.gait.model import GaitModel, GaitModelFileError
from tests.gait_data import trial


def test_stock_library_loads_with_its_named_styles_and_predicts():
    model = load_stock_library()
    assert model.style_names == tuple(STOCK_RECIPE) and model.has_offset
    assert "mocap.cs.cmu.edu" in model.notes and model.root_travel
    # Cadences in the order of the recipe's character: the run is quickest, the sneaking walk
    # of 120 (2-2.5 s a stride) slowest, then the stroll.
    hz = dict(zip(model.style_names, model.fps / model.periods))
    assert max(hz, key=hz.get) == "run" and min(hz, key=hz.get) == "sneaking"
    assert sorted(hz, key=hz.get)[1] == "stroll"
    values, names = trial("35_02")
    obs = observations_from_dofs(model, values, names, 60.0)
    res = adapt(model, obs[:60])
    pred = predict(model, res.state, res.w, 60, residual=res.residual, offset=res.offset,
                   start=res.last_observation, fps=60.0)
    truth = obs[60:120, :56]
    hold = np.sqrt(np.mean((obs[59, :56] - truth) ** 2))
    assert np.all(np.isfinite(pred)) and np.sqrt(np.mean((pred[:, :56] - truth) ** 2)) < 0.5 * hold


def test_a_damaged_stock_file_is_refused(tmp_path):
    from core.gait.stock import STOCK_PATH

    data = bytearray(STOCK_PATH.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path = tmp_path / "stock_gaits.npz"
    path.write_bytes(bytes(data))
    with pytest.raises(GaitModelFileError, match="stock_gaits.npz"):
        load_stock_library(path)
    with pytest.raises(GaitModelFileError, match="missing"):
        load_stock_library(tmp_path / "nowhere.npz")


def test_steady_segments_leave_out_standing_and_keep_clean_walks_whole():
    values, names = trial("35_03")
    assert steady_segments(values, names, 60.0) == [(0, len(values))]
    # A capture that stands still for 2 s, then walks: the standing part is left out.
    stand = np.repeat(values[:1], 120, axis=0)
    walk = values.copy()
    walk[:, :3] += stand[-1, :3] - walk[0, :3]
    both = np.vstack([stand, walk])
    pieces = steady_segments(both, names, 60.0)
    assert len(pieces) == 1 and 110 <= pieces[0][0] <= 150 and pieces[0][1] == len(both)
    # A frozen pose is no gait at all; its periodicity test refuses it.
    assert steady_segments(stand, names, 60.0) == []
    with pytest.raises(ValueError, match="do not vary"):
        periodicity(stand[:, 6:], 60.0)
    period, strength = periodicity(values[:, 6:], 60.0)
    assert 0.8 < strength <= 1.0 and 60 < period < 75


def test_restyle_moves_along_the_difference_of_two_named_styles():
    model = load_stock_library()
    w = model.style("normal") + 0.1
    same, factor = restyle(model, w, "normal", "careful", 0.0)
    np.testing.assert_array_equal(same, w)
    assert factor == 1.0
    full, factor = restyle(model, w, "normal", "run", 1.0)
    np.testing.assert_allclose(full - w, model.style("run") - model.style("normal"))
    i, j = model.style_names.index("normal"), model.style_names.index("run")
    assert factor == pytest.approx(model.periods[i] / model.periods[j])
    with pytest.raises(ValueError, match="unknown style 'jog'"):
        restyle(model, w, "normal", "jog", 0.5)


def test_sequences_sharing_a_name_become_one_style():
    from core.gait import learn_model

    data = [trial(t) for t in ("35_01", "35_02", "35_17")]
    model = learn_model([d[0] for d in data], data[0][1], 60.0, ["walk", "walk", "run"],
                        n_styles=2)
    alone = learn_model([d[0] for d in data], data[0][1], 60.0, ["a", "b", "run"], n_styles=2)
    assert model.style_names == ("walk", "run") and isinstance(model, GaitModel)
    # Two walks of one walker learned at the same phase: their re-aligned mean is their mean.
    np.testing.assert_allclose(model.styles[0], alone.styles[:2].mean(axis=0),
                               atol=0.01 * np.linalg.norm(model.styles[0]))
    np.testing.assert_allclose(model.periods[0], np.sqrt(alone.periods[0] * alone.periods[1]))
    np.testing.assert_allclose(model.style_mean, alone.style_mean)
    np.testing.assert_array_equal(model.bases, alone.bases)


def test_pieces_of_a_name_learned_at_different_phases_are_aligned_before_averaging():
    """The stock careful pieces: five of nine learned a quarter cycle off the common phase, and
    their plain mean cancelled the legs' motion. A named style is the mean of its pieces'
    cycles shifted to the model's mean cycle: two pieces of one sinusoidal swing a quarter cycle
    apart keep the swing's full amplitude, at the phase of the mean cycle."""
    from core.gait.learning import _merge_named
    from core.gait.factorization import reconstruct

    phase = np.linspace(0.0, 2.0 * np.pi, 33)
    bases = np.zeros((3, 33, 2))
    bases[0, :, 0], bases[0, :, 1] = np.sin(phase), np.cos(phase)
    bases[1, :, 0], bases[1, :, 1] = np.cos(phase), -np.sin(phase)
    bases[2] = 1.0
    bases /= np.linalg.norm(bases.reshape(3, -1), axis=1)[:, None, None]
    # swing(φ + δ) = cos δ · bases[0] + sin δ · bases[1] (up to the norm); δ = 0, π/2, 0.
    styles = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]])
    names, merged, periods = _merge_named(["careful", "careful", "normal"], styles,
                                          np.array([60.0, 60.0, 70.0]), bases)
    assert names == ["careful", "normal"]
    np.testing.assert_allclose(periods, [60.0, 70.0])
    swing = reconstruct(merged, bases)[:, :, 0]
    pieces = reconstruct(styles, bases)[:, :, 0]
    # Full amplitude (the plain mean of the two styles: 1/√2 of it), at the phase of the mean
    # cycle, the common phase every named style is shifted to (one piece too).
    mean_cycle = reconstruct(styles.mean(axis=0)[None], bases)[0, :, 0]
    for k in range(2):
        np.testing.assert_allclose(np.ptp(swing[k]), np.ptp(pieces[0]), rtol=0.02)
        assert np.corrcoef(swing[k], mean_cycle)[0, 1] > 0.99
    np.testing.assert_allclose(merged[:, 2], 1.0, rtol=1e-9)


def test_a_model_file_is_the_same_bytes_every_time_it_is_written(tmp_path):
    """The stock rebuild is reproducible bit for bit (tools/build_stock_gaits.py): the file
    holds no timestamp, its entries are written in name order."""
    model = load_stock_library()
    first = model.to_bytes()
    assert model.to_bytes() == first
    path = tmp_path / "again.npz"
    GaitModel.from_bytes(first).save(path)
    assert path.read_bytes() == first
