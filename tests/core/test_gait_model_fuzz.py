"""Fuzzing the gait model file: every corrupt or inconsistent file ends in GaitModelFileError
naming the source, never another exception, and a file that loads gives a model that predicts
finite values (``predict``, ``predict_dofs``, ``observations_from_dofs``).

Seeded mutations of a learned model's ``.npz`` (bytes and fields), like the Acclaim fuzz tests.
Mutations marked ``must_fail`` always make the model invalid and must raise.
"""

import io

import numpy as np
import pytest

from core.gait import GaitModel, GaitModelFileError, observations_from_dofs, predict, \
    predict_dofs
from core.gait.model import checksum
from tests.gait_data import small_model, trial

SOURCE = "fuzz.npz"
NAMES = ["x", "root.height", "lfemur.rx", "root.tx", "deg", "m", "rad/s", ""]


def _arrays(data):
    with np.load(io.BytesIO(data), allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def _bytes(arrays):
    """A model file of ``arrays``, re-signed (a new checksum) so that the checks behind the
    checksum are what the mutation meets."""
    arrays = dict(arrays, checksum=np.array(checksum(arrays)))
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _mutation(good, rng):
    """(name, bytes, must_fail) of one seeded mutation of the model file ``good``."""
    kind = int(rng.integers(0, 10))
    if kind == 0:
        data = bytearray(good)
        i = int(rng.integers(len(data)))
        data[i] = (data[i] + int(rng.integers(1, 256))) % 256
        return "flip-byte", bytes(data), False
    if kind == 1:
        return "truncate", good[:int(rng.integers(len(good)))], True
    arrays = _arrays(good)
    # The checksum is re-signed by _bytes (test_gait_model checks the checksum itself).
    field = str(rng.choice(sorted(k for k in arrays if k != "checksum")))
    value = arrays[field]
    if kind == 2:
        arrays[field] = value.ravel()[:-1] if value.size > 1 else np.zeros(2)
        return "reshape-field", _bytes(arrays), False
    if kind == 3:
        arrays[field] = np.array("walk") if value.dtype.kind != "U" else np.arange(3.0)
        return "retype-field", _bytes(arrays), False
    if kind == 4:
        del arrays[field]
        return "drop-field", _bytes(arrays), True
    if kind == 5:
        name = str(rng.choice(["channel_names", "dof_names", "units"]))
        values = arrays[name].tolist()
        i = int(rng.integers(len(values)))
        new = str(rng.choice([n for n in NAMES if n != values[i]]))
        # Renaming one root DOF to another repeats it; renaming a joint-angle DOF to another
        # name keeps dof_names consistent only if the channel is renamed too (it is not here).
        values[i] = new
        arrays[name] = np.array(values)
        return "rename-entry", _bytes(arrays), True
    if kind == 6:
        name = str(rng.choice(["channel_names", "dof_names", "units"]))
        values = arrays[name].tolist()
        del values[int(rng.integers(len(values)))]
        arrays[name] = np.array(values)
        return "delete-entry", _bytes(arrays), True
    if kind == 7:
        arrays["root_travel"] = np.array(1 - int(arrays["root_travel"]))
        return "toggle-root-travel", _bytes(arrays), True
    if kind == 8:
        name = str(rng.choice(["root_order", "alignment", "refinement", "forward_axis"]))
        arrays[name] = np.array(str(rng.choice(["ZYX", "XXY", "", "abc", "1", "7"]))) \
            if name != "forward_axis" else np.array(int(rng.integers(-2, 5)))
        return "edit-setting", _bytes(arrays), False
    i, j = (str(n) for n in rng.choice(["channel_names", "dof_names", "units", "style_names"],
                                        2, replace=False))
    arrays[i], arrays[j] = arrays[j], arrays[i]
    return "swap-name-fields", _bytes(arrays), True


def _dofs_in_layout(model, values, names):
    """The trial's DOF rows rearranged into the model's DOF layout (zeros for unknown names)."""
    lookup = {n: k for k, n in enumerate(names)}
    out = np.zeros((len(values), len(model.dof_names)))
    for k, name in enumerate(model.dof_names):
        if name in lookup:
            out[:, k] = values[:, lookup[name]]
    return out


def test_seeded_model_file_mutations_end_in_gait_model_file_error():
    model = small_model()
    good = model.to_bytes()
    values, names = trial("08_01")
    values = values[:40]
    rng = np.random.default_rng(2024)
    kinds, loaded = set(), 0
    for _ in range(400):
        name, data, must_fail = _mutation(good, rng)
        kinds.add(name)
        try:
            m = GaitModel.from_bytes(data, source=SOURCE)
        except GaitModelFileError as err:
            assert str(err).startswith(SOURCE), (name, str(err))
            continue
        assert not must_fail, f"an always-invalid mutation ({name}) loaded"
        loaded += 1
        state = np.array([0.09, 1.3])
        assert np.all(np.isfinite(predict(m, state, m.styles[0], 8)))
        dofs = _dofs_in_layout(m, values, names)
        assert np.all(np.isfinite(predict_dofs(m, state, m.styles[0], 8, dofs[-1], 60.0)))
        assert np.all(np.isfinite(observations_from_dofs(m, dofs, m.dof_names, 60.0)))
    assert len(kinds) == 10           # every mutation kind was exercised
    assert loaded > 0                 # some harmless mutations (settings, padding bytes) load


@pytest.mark.parametrize("field, entry, new", [
    ("dof_names", 10, "lfemur.rz_typo"),     # a joint-angle DOF the channels no longer match
    ("dof_names", 0, "root.height"),         # a root DOF lost: root travel cannot be written
    ("channel_names", 57, "root.tilt_x"),    # a repeated root feature
    ("units", 0, "m"),                        # a joint angle that is not in radians
])
def test_inconsistent_channel_layout_is_refused_at_load(field, entry, new):
    model = small_model()
    arrays = _arrays(model.to_bytes())
    values = arrays[field].tolist()
    values[entry] = new
    arrays[field] = np.array(values)
    with pytest.raises(GaitModelFileError, match=SOURCE):
        GaitModel.from_bytes(_bytes(arrays), source=SOURCE)


def test_toggled_root_travel_is_refused_at_load():
    arrays = _arrays(small_model().to_bytes())
    arrays["root_travel"] = np.array(0)
    with pytest.raises(GaitModelFileError, match="channel names"):
        GaitModel.from_bytes(_bytes(arrays), source=SOURCE)


# ------------------------------------------------------------------ absurd but finite values
# Every numeric field scaled by a huge or tiny factor: the file must be refused at load (a
# GaitModelFileError naming the source) or load and give finite results everywhere — adapting
# (batch EM and the online filter) included, since that is where r, Q, the style prior and the
# period range act.
SCALED_FIELDS = [("fps", None), ("r", None), ("lag_range", None), ("lag_range", 0),
                 ("lag_range", 1), ("beta", None), ("beta", 0), ("beta", 1), ("beta", 2),
                 ("beta", 3), ("Q", None), ("Q", 0), ("Q", 3), ("channel_scale", None),
                 ("channel_scale", 60), ("style_mean", None), ("style_cov", None),
                 ("bases", None), ("styles", None), ("styles", 0), ("periods", None),
                 ("periods", 0), ("angle_centre", None), ("singular_values", None)]
FACTORS = [1e-300, 1e-30, 1e-8, 1e8, 1e30, 1e300]


def _check_finite_everywhere(m):
    from core.gait import OnlineEM, adapt

    values, names = trial("08_01")
    dofs = _dofs_in_layout(m, values[:150], names)
    obs = observations_from_dofs(m, dofs, m.dof_names, 60.0)
    assert np.all(np.isfinite(obs[1:]))
    res = adapt(m, obs, fps=60.0)
    for arr in (res.state, res.covariance, res.w, res.residual):
        assert np.all(np.isfinite(arr))
    assert np.all(np.isfinite(predict(m, res.state, res.w, 8, residual=res.residual)))
    assert np.all(np.isfinite(predict_dofs(m, res.state, res.w, 8, dofs[-1], 60.0)))
    online = OnlineEM(m, fps=60.0)
    for y in obs[:60]:
        online.step(y)
    assert np.all(np.isfinite([online.omega, online.phase]))
    assert np.all(np.isfinite(online.w)) and np.all(np.isfinite(online.predict(8)))


@pytest.mark.parametrize("factor", FACTORS)
@pytest.mark.parametrize("field, entry", SCALED_FIELDS)
def test_scaled_field_is_refused_or_gives_finite_results(field, entry, factor):
    arrays = _arrays(small_model().to_bytes())
    value = np.array(arrays[field], dtype=float)
    if entry is None:
        value = value * factor
    else:
        value.reshape(-1)[entry] *= factor
    arrays[field] = value
    try:
        m = GaitModel.from_bytes(_bytes(arrays), source=SOURCE)
    except GaitModelFileError as err:
        assert str(err).startswith(SOURCE)
        return
    with np.errstate(over="raise", divide="raise", invalid="raise"):  # no inf or 0/0 on the way
        _check_finite_everywhere(m)


@pytest.mark.parametrize("field, factor", [
    ("r", 1e-300), ("r", 1e300), ("fps", 1e300), ("fps", 1e-300), ("lag_range", 1e300),
    ("lag_range", 1e-300), ("Q", 1e300), ("Q", 1e-300), ("beta", 1e300), ("style_cov", 1e-300),
    ("style_cov", 1e300), ("bases", 1e300), ("styles", 1e300), ("style_mean", 1e300),
    ("channel_scale", 1e300), ("channel_scale", 1e-300), ("periods", 1e-300),
    ("periods", 1e300)])
def test_absurd_field_is_refused_at_load(field, factor):
    arrays = _arrays(small_model().to_bytes())
    arrays[field] = np.asarray(arrays[field], dtype=float) * factor
    with pytest.raises(GaitModelFileError, match=f"^{SOURCE}: .*{field}"):
        GaitModel.from_bytes(_bytes(arrays), source=SOURCE)


ALL_CMU = ("08_01", "08_04", "08_07", "35_01", "35_02", "35_03", "35_04", "35_05", "35_06",
           "35_07", "35_08", "35_17", "35_18", "35_20", "35_21")


@pytest.mark.parametrize("fps, model_fps, names", [
    (24, 24.0, ("08_04", "35_01", "35_17")), (30, 30.0, ("08_04", "35_01", "35_17")),
    (60, 60.0, ALL_CMU), (120, 120.0, ("08_04", "35_01", "35_17")),
    (120, 240.0, ("08_04", "35_01", "35_17")), (60, 60.0, ("35_02",)),
    (30, 30.0, ("08_07",))])
def test_models_learned_from_cmu_pass_the_plausibility_checks(fps, model_fps, names):
    from core.gait import learn_model

    data = [trial(n, fps) for n in names]
    model = learn_model([d[0] for d in data], data[0][1], float(fps), list(names),
                        model_fps=model_fps)        # the constructor runs the checks
    loaded = GaitModel.from_bytes(model.to_bytes(), source=SOURCE)
    assert loaded.fps == model_fps and loaded.style_names == tuple(names)
    np.testing.assert_array_equal(loaded.bases, model.bases)
