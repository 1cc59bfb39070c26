"""Build the stock gait library shipped with the extension (``core/gait/data/stock_gaits.npz``).

    python tools/build_stock_gaits.py [--output core/gait/data/stock_gaits.npz]

(``make stock-gaits``.) Reads the CMU trials of ``core.gait.stock.STOCK_RECIPE`` from
``sample_scenes/data/cmu`` (subjects without an .asf through the CMU template skeleton),
resamples them to 60 Hz, cuts each into steady pieces (``core.gait.segments``), and learns one
model with the default settings: every piece is a training sequence named after its style (the
pieces of a style become one named style), the CMU subject is the walker (posture-offset prior).
The same recipe, without the held-out subject, is what ``make bench-gait`` evaluates leave one
walker out. Reproducible across CPUs: the script re-executes itself under the CPU pin of
``tools/cpu_pin.py`` (default ``x86-64-v3``: one BLAS thread, OpenBLAS's Haswell kernels,
NumPy's loops up to AVX2/FMA3, no AVX-512) and the file is written without timestamps, so a
rebuild is the shipped file, bit for bit, on every CPU with AVX2 and FMA with the same venv and
glibc (``make check-stock-gaits`` rebuilds into build/ and compares). ``--pin none``: this CPU's
own kernels (the bytes then follow the CPU); ``--pin x86-64-baseline``: the same bytes on every
x86-64 CPU, but another library (docs/gait.md, Stop 46). About 12 s of CPU time (1-2 min on the
shared 2-core development machine).
"""

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tools.cpu_pin import PIN_VAR, add_pin_argument, pin_from_command_line  # noqa: E402

if __name__ == "__main__":
    # The CPU pin before NumPy computes anything: the same bytes on every CPU the pin runs on
    # (glibc reads its tunables when a process starts, hence a re-execution).
    pin_from_command_line()

# One BLAS thread (also without the pin): sums of products then round the same way on every
# run, so a rebuild on the same machine is byte-identical.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from core.gait import learn_model  # noqa: E402
from core.gait.segments import steady_segments  # noqa: E402
from core.gait.stock import STOCK_LAG_RANGE, STOCK_PATH, STOCK_RECIPE, STOCK_VERSION  # noqa: E402
from core.mocap import asf_to_skeleton, read_amc, read_asf, resample  # noqa: E402
from core.mocap.bvh import cmu_template_asf  # noqa: E402

CMU = ROOT / "sample_scenes" / "data" / "cmu"
FPS = 60.0
NOTES = (f"Track & Stride stock gaits v{STOCK_VERSION}: learned by tools/build_stock_gaits.py "
         "from CMU motion capture (mocap.cs.cmu.edu; the database was created with funding "
         "from NSF EIA-0196217), subjects 06, 07, 08, 35, 74, 91, 120, 132, 139.")


def load_trial(name, folder=CMU):
    """(DOFs at 60 Hz (N, 62), DOF names) of a CMU trial; the template skeleton for subjects
    without an .asf."""
    subject = name.split("_")[0]
    path = Path(folder) / f"{subject}.asf"
    asf = read_asf(path) if path.exists() else cmu_template_asf()
    values = read_amc(Path(folder) / f"{name}.amc", asf).values
    values = resample(values, 120.0, FPS, np.arange(3, values.shape[1]))
    return values, tuple(asf_to_skeleton(asf).dof_names())


def training_pieces(recipe, folder=CMU, exclude_subjects=(), exclude_trials=(),
                    lag_range=STOCK_LAG_RANGE):
    """(sequences, DOF names, style names, walker names) of the recipe's steady pieces
    (``lag_range``: the segmentation's period search, seconds)."""
    seqs, styles, walkers = [], [], []
    names = None
    for style, trials in recipe.items():
        for trial in trials:
            subject = trial.split("_")[0]
            if subject in exclude_subjects or trial in exclude_trials:
                continue
            values, names = load_trial(trial, folder)
            for start, stop in steady_segments(values, names, FPS, lag_range=lag_range):
                seqs.append(values[start:stop])
                styles.append(style)
                walkers.append(subject)
    return seqs, names, styles, walkers


def build_stock(recipe=STOCK_RECIPE, folder=CMU, exclude_subjects=(), exclude_trials=(),
                **learn_kw):
    """The stock model of ``recipe`` (optionally without some subjects or trials: the
    benchmark's folds); ``learn_kw`` go to ``learn_model`` (its ``lag_range``, default
    ``STOCK_LAG_RANGE``, also bounds the segmentation's period search)."""
    learn_kw.setdefault("lag_range", STOCK_LAG_RANGE)
    seqs, names, styles, walkers = training_pieces(recipe, folder, exclude_subjects,
                                                   exclude_trials, learn_kw["lag_range"])
    return learn_model(seqs, names, FPS, styles, walkers=walkers, notes=NOTES, **learn_kw)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default=str(STOCK_PATH))
    add_pin_argument(parser)
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    model = build_stock()
    output = Path(args.output)
    output.parent.mkdir(parents=True, exist_ok=True)
    model.save(output)
    size = output.stat().st_size
    print(f"wrote {output} ({size / 1024:.0f} KiB) in {time.perf_counter() - t0:.1f} s: "
          f"J={model.n_bases}, styles {', '.join(model.style_names)}; CPU pin: "
          f"{os.environ.get(PIN_VAR, 'none')}")


if __name__ == "__main__":
    main()
