"""core.gait.learning and core.gait.model: learning from CMU walks, save/load, file errors."""

import io
import zipfile

import numpy as np
import pytest

from core.gait import GaitModel, GaitModelFileError, learn_model, predict
from core.gait.model import FORMAT_VERSION, checksum
from tests.gait_data import SMALL_TRAIN, small_model, trial


def test_learned_model_structure():
    model = small_model()
    assert model.n_channels == 63 and model.n_angles == 56 and model.n_bases == 3
    assert model.channel_names[:56] == tuple(n for n in trial("35_01")[1] if not
                                             n.startswith("root."))
    assert model.units[:56] == ("rad",) * 56 and model.units[56:58] == ("m", "m/s")
    np.testing.assert_array_equal(model.A, [[1.0, 0.0], [1.0, 1.0]])
    np.testing.assert_array_equal(model.bases[:, 0], model.bases[:, -1])     # eq. 9
    assert model.styles.shape == (5, 3) and model.style_names == SMALL_TRAIN
    assert model.fps == 60.0 and model.n_phase == 33
    np.testing.assert_array_equal(model.channel_scale[:56], 1.0)
    assert np.all(model.channel_scale > 0) and model.r > 0
    assert np.all(np.linalg.eigvalsh(model.style_cov) > 0)
    # Periods in model frames: walks about 1.1-1.3 s, the run about 0.75 s.
    np.testing.assert_allclose(model.periods / 60.0, [1.32, 1.29, 1.12, 1.13, 0.75], atol=0.03)
    for name in ("bases", "styles", "beta", "Q", "angle_centre"):
        assert np.all(np.isfinite(getattr(model, name)))


def test_learning_from_120_hz_equals_learning_from_60_hz():
    names = trial("35_01")[1]
    raw = [np.asarray(trial(t, 120)[0]) for t in SMALL_TRAIN[:3]]
    pre = [np.asarray(trial(t)[0]) for t in SMALL_TRAIN[:3]]
    a = learn_model(raw, names, 120.0, n_styles=2, refinement="svd", gp_beta=[1, 1, 1, 1e4])
    b = learn_model(pre, names, 60.0, n_styles=2, refinement="svd", gp_beta=[1, 1, 1, 1e4])
    np.testing.assert_allclose(a.bases, b.bases, atol=1e-12)
    np.testing.assert_allclose(a.styles, b.styles, atol=1e-12)
    # One rate per sequence (a list of floats), mixing 120 Hz and 60 Hz inputs.
    mixed = learn_model([raw[0], pre[1], raw[2]], names, [120.0, 60.0, 120.0], n_styles=2,
                        refinement="svd", gp_beta=[1, 1, 1, 1e4])
    np.testing.assert_allclose(mixed.bases, b.bases, atol=1e-12)


def test_channel_scale_and_energy_default():
    model = learn_model([np.asarray(trial(t)[0]) for t in SMALL_TRAIN], trial("35_01")[1], 60.0,
                        refinement="svd")
    s = model.singular_values
    energy = np.cumsum(s**2) / np.sum(s**2)
    assert model.n_bases == int(np.argmax(energy >= 0.99 - 1e-12)) + 1
    # Root channels in scaled units have the median spread of the joint angles.
    data = np.vstack([np.asarray(trial(t)[0]) for t in SMALL_TRAIN])
    height_sd = data[:, 2].std()
    ratio = height_sd / model.channel_scale[model.channel_names.index("root.height")]
    angle_sd = np.median([d for d in data[:, 6:].std(0) if d > 1e-9])
    np.testing.assert_allclose(ratio, angle_sd, rtol=0.05)


def test_angle_only_model():
    model = small_model(root_travel=False)
    assert model.n_channels == 56 and model.angle_names == model.channel_names
    assert not model.rate_mask.any()


def test_save_load_roundtrip(tmp_path):
    model = small_model()
    path = tmp_path / "walk.npz"
    model.save(path)
    loaded = GaitModel.load(path)
    for name in ("bases", "styles", "beta", "Q", "A", "channel_scale", "angle_centre",
                 "style_mean", "style_cov", "periods", "root_rest"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(model, name))
    for name in ("channel_names", "units", "style_names", "dof_names", "fps", "r",
                 "root_travel", "root_order", "forward_axis", "alignment", "refinement"):
        assert getattr(loaded, name) == getattr(model, name)
    state = np.array([0.09, 1.3])
    np.testing.assert_array_equal(predict(loaded, state, model.styles[1], 20),
                                  predict(model, state, model.styles[1], 20))
    again = GaitModel.from_bytes(model.to_bytes())
    assert again.to_bytes() == model.to_bytes()
    with zipfile.ZipFile(path) as zf:
        assert all(name.endswith(".npy") for name in zf.namelist())
    with np.load(path, allow_pickle=False) as npz:      # no object arrays anywhere
        assert int(npz["format_version"]) == FORMAT_VERSION


def _arrays(model):
    with np.load(io.BytesIO(model.to_bytes()), allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def _bytes(arrays):
    """A model file of ``arrays``, re-signed (a new checksum) so that the checks behind the
    checksum are what the mutation meets."""
    arrays = dict(arrays, checksum=np.array(checksum(arrays)))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def test_corrupt_and_incompatible_files_raise(tmp_path):
    model = small_model()
    good = model.to_bytes()
    with pytest.raises(GaitModelFileError, match="not a gait model file"):
        GaitModel.from_bytes(b"certainly not a zip file")
    with pytest.raises(GaitModelFileError):
        GaitModel.from_bytes(good[: len(good) // 2])
    arrays = _arrays(model)
    arrays["format_version"] = np.array(FORMAT_VERSION + 1)
    with pytest.raises(GaitModelFileError, match=f"version {FORMAT_VERSION + 1} is not supported"):
        GaitModel.from_bytes(_bytes(arrays))
    arrays = _arrays(model)
    del arrays["bases"]
    with pytest.raises(GaitModelFileError, match="missing .*bases"):
        GaitModel.from_bytes(_bytes(arrays))
    arrays = _arrays(model)
    arrays["styles"] = arrays["styles"][:, :2]
    with pytest.raises(GaitModelFileError, match="styles"):
        GaitModel.from_bytes(_bytes(arrays))
    arrays = _arrays(model)
    arrays["Q"] = arrays["Q"] * np.nan
    with pytest.raises(GaitModelFileError, match="finite"):
        GaitModel.from_bytes(_bytes(arrays))
    arrays = _arrays(model)
    arrays["A"] = np.array([[0.0, 1.0], [1.0, 1.0]])                 # the paper's typo
    with pytest.raises(GaitModelFileError, match="A must be"):
        GaitModel.from_bytes(_bytes(arrays))
    arrays = _arrays(model)
    arrays["channel_names"] = np.array([object()] * 63, dtype=object)
    buf = io.BytesIO()
    np.savez(buf, **arrays)                                          # pickled object array
    with pytest.raises(GaitModelFileError):
        GaitModel.from_bytes(buf.getvalue())
    path = tmp_path / "bad.npz"
    path.write_bytes(b"PK\x03\x04 broken")
    with pytest.raises(GaitModelFileError, match=str(path.name)):
        GaitModel.load(path)
    with pytest.raises(GaitModelFileError, match="no format_version"):
        GaitModel.from_bytes(_bytes({"bases": np.zeros(3)}))


def test_checksum_refuses_a_changed_file_and_version_1_files_still_load():
    model = small_model()
    arrays = _arrays(model)
    assert str(arrays["checksum"]) == checksum(arrays) and model.has_offset
    changed = dict(arrays, r=np.array(float(arrays["r"]) * 1.001))       # not re-signed
    buf = io.BytesIO()
    np.savez(buf, **changed)
    with pytest.raises(GaitModelFileError, match="checksum mismatch"):
        GaitModel.from_bytes(buf.getvalue(), source="edited.npz")
    unsigned = {k: v for k, v in arrays.items() if k != "checksum"}
    buf = io.BytesIO()
    np.savez(buf, **unsigned)
    with pytest.raises(GaitModelFileError, match="without its checksum"):
        GaitModel.from_bytes(buf.getvalue())
    # A version 1 file (before the checksum and the offset prior) loads, without offset.
    old = {k: v for k, v in unsigned.items() if k != "offset_var"}
    old["format_version"] = np.array(1)
    buf = io.BytesIO()
    np.savez(buf, **old)
    loaded = GaitModel.from_bytes(buf.getvalue())
    assert not loaded.has_offset and np.array_equal(loaded.bases, model.bases)
    assert GaitModel.from_bytes(loaded.to_bytes()).format_version == FORMAT_VERSION


def test_version_3_keeps_the_cadence_direction_and_version_2_files_load_without_it():
    """Version 3 (issue 25) adds ``cadence_style``, learned from the training walks; a
    version 2 file (signed, with its offset prior) loads with a zero direction (retiming then
    plays the walk faster)."""
    model = small_model()
    assert model.cadence_style.shape == (model.n_bases,) and np.any(model.cadence_style)
    again = GaitModel.from_bytes(model.to_bytes())
    assert np.array_equal(again.cadence_style, model.cadence_style)
    arrays = _arrays(model)
    old = {k: v for k, v in arrays.items() if k not in ("checksum", "cadence_style")}
    old["format_version"] = np.array(2)
    old["checksum"] = np.array(checksum(old))
    buf = io.BytesIO()
    np.savez(buf, **old)
    loaded = GaitModel.from_bytes(buf.getvalue())
    assert loaded.has_offset and not np.any(loaded.cadence_style)
    assert np.array_equal(loaded.styles, model.styles)
    # A version 3 file without the field is incomplete.
    del arrays["cadence_style"]
    arrays["checksum"] = np.array(checksum({k: v for k, v in arrays.items()
                                            if k != "checksum"}))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    with pytest.raises(GaitModelFileError, match="cadence_style"):
        GaitModel.from_bytes(buf.getvalue())


def test_learning_errors():
    names = trial("35_01")[1]
    good = [np.asarray(trial(t)[0]) for t in ("35_01", "35_02")]
    with pytest.raises(ValueError, match=r"^the walk short:.*shorter than one cycle"):
        learn_model([good[0], good[1][:40]], names, 60.0, ["long", "short"])
    with pytest.raises(ValueError, match=r"^the walk style0: expected shape \(N, 62\)"):
        learn_model([good[0][:, :60], good[1]], names, 60.0)
    with pytest.raises(ValueError, match="root DOF channels missing"):
        learn_model([g[:, 3:] for g in good], names[3:], 60.0)
    with pytest.raises(ValueError, match="alignment"):
        learn_model(good, names, 60.0, alignment="median")
    with pytest.raises(ValueError, match="style names"):
        learn_model(good, names, 60.0, names=["a"])
    with pytest.raises(ValueError, match="at least one"):
        learn_model([], names, 60.0)


def test_model_lookups():
    model = small_model()
    np.testing.assert_array_equal(model.style("35_02"), model.styles[3])
    with pytest.raises(ValueError, match="unknown style 'nobody'"):
        model.style("nobody")
    np.testing.assert_array_equal(model.channel_index(["root.height", "lfemur.rx"]),
                                  [56, 0])
    with pytest.raises(ValueError, match=r"unknown channels \['tail.rx'\]"):
        model.channel_index(["tail.rx"])
    lo, hi = model.omega_range(120.0)
    np.testing.assert_allclose([lo, hi], [2 * np.pi / 240, 2 * np.pi / 60])
    np.testing.assert_allclose(model.process_noise(30.0)[0, 0], model.Q[0, 0] * 8)


@pytest.mark.parametrize("content, reason", [
    (b"", "the file is empty"),
    (b"hello, not a model", "it is another kind of file"),
    (None, "it holds Python objects"),                      # an .npz of object arrays
    (b"PK\x03\x04 cut short", "the archive is damaged or cut short"),
])
def test_a_corrupt_model_file_says_what_is_wrong_once(tmp_path, content, reason):
    """Not NumPy's advice to load it "unsafely using allow_pickle", and the path once."""
    path = tmp_path / "walks.npz"
    if content is None:
        np.savez(path, a=np.array([{"x": 1}], dtype=object))
    else:
        path.write_bytes(content)
    with pytest.raises(GaitModelFileError) as err:
        GaitModel.load(path)
    message = str(err.value)
    assert message == f"{path}: not a gait model file: " + message.split(": ", 2)[2]
    assert reason in message and message.count(str(path)) == 1 and "walks.npz" not in \
        message.replace(str(path), "")
    assert "pickle" not in message.replace("Python objects", "") and "allow" not in message
