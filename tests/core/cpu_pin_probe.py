"""A small learning run whose bytes show the CPU's arithmetic (run by test_cpu_pin.py).

    python tests/core/cpu_pin_probe.py

Learns the stock library's recipe in miniature (steady pieces of four CMU trials, named styles,
walkers for the posture-offset prior, as ``tools/build_stock_gaits.py``), adapts it to 1 s of an
unseen walk and predicts 1 s (as ``make bench-gait``'s leave-one-walker-out folds), and prints
the SHA-256 of the model file's bytes and of the prediction's bytes. About 1 s of computing.
"""

import hashlib
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from core.gait import adapt, learn_model, observations_from_dofs, predict  # noqa: E402
from core.gait.segments import steady_segments  # noqa: E402
from tests.gait_data import trial  # noqa: E402

TRAIN = {"walk": ("35_01", "08_04"), "run": ("35_17",), "stroll": ("08_07",)}
TEST = "35_03"


def main():
    seqs, styles, walkers = [], [], []
    names = None
    for style, trials in TRAIN.items():
        for name in trials:
            values, names = trial(name)
            for start, stop in steady_segments(values, names, 60.0):
                seqs.append(values[start:stop])
                styles.append(style)
                walkers.append(name.split("_")[0])
    model = learn_model(seqs, names, 60.0, styles, walkers=walkers)
    values, test_names = trial(TEST)
    obs = observations_from_dofs(model, values, test_names, 60.0)
    res = adapt(model, obs[:60])
    pred = predict(model, res.state, res.w, 60, residual=res.residual, offset=res.offset,
                   start=res.last_observation, fps=60.0)
    model_hash = hashlib.sha256(model.to_bytes()).hexdigest()
    pred_hash = hashlib.sha256(np.ascontiguousarray(pred).tobytes()).hexdigest()
    print(model_hash, pred_hash)


if __name__ == "__main__":
    main()
