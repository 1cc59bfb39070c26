"""Stop 47 (issue 21 §1, the circling walker's cycle; ``docs/gait.md``, *Stop 47, the
circling walker's cycle*): every window of the acceptance bench through check 5 as main
fd65bdc makes it and with this stop's two changes, window by window.

* ``main``: the phase turn of the adapted model read as one stride
  (``checks.walker_cycle(result, fps)``) and the rhythm pooling the same leg a cycle later
  with the other leg's step half a cycle later, mirrored.
* ``stride``: the stride read as the phase turn over the strides the adapted cycle holds
  (``checks.strides_per_cycle``: the hip flexion's strongest harmonic).
* ``same_leg``: the rhythm also takes the same leg a cycle later alone
  (``checks.SAME_LEG_ALONE``).
* ``both``: what ships.

Per variant and window: accepted or the refusal's first words; what it prints: every window
whose outcome differs from main's, and the accept rates at windows >= 0.75 s. Also, for the
gait windows main adapts in check 5 (a weak rhythm), the phase turn, the strides read and the
leg frequency.

::

    OPENBLAS_NUM_THREADS=1 nice -n 5 .venv/bin/python benchmarks/studies/stride_cycle47.py \\
        --out build/c47/stride_cycle47.pkl [--variants main,both]
"""

import argparse
import pickle
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import gait_acceptance as A  # noqa: E402
from core.gait import load_stock_library, observations_from_dofs  # noqa: E402
from core.gait import checks  # noqa: E402

VARIANTS = {"main": (False, False), "stride": (True, False), "same_leg": (False, True),
            "both": (True, True)}
_CYCLE = checks.walker_cycle


def set_variant(name):
    """Switch check 5 to a variant: (stride read, same leg alone)."""
    stride, same = VARIANTS[name]
    checks.SAME_LEG_ALONE = same
    checks.walker_cycle = _CYCLE if stride else \
        (lambda result, fps, model=None: _CYCLE(result, fps))


def outcomes(model, variant):
    """{(kind, clip, window, start): 'accepted' or the refusal's words before ' in '}."""
    set_variant(variant)
    out = {}
    for kind, folder, gait in (("gait", A.CMU, True), ("not_gait", A.NOT_GAITS, False)):
        for path in sorted(folder.glob("*.amc")):
            values, names = A.load(path)
            cols = [names.index(n) for n in model.dof_names]
            obs = observations_from_dofs(model, values[:, cols], model.dof_names, A.FPS)
            angles = values[:, [names.index(n) for n in model.angle_names]]
            for window in A.WINDOWS:
                n = int(round(window * A.FPS))
                for s in A.window_starts(values, names, window, gait):
                    w = A.window_observations(model, obs, angles, s, n)
                    refusal = checks.check_gait(model, w, A.FPS).refusal
                    out[(kind, path.stem, window, s)] = \
                        "accepted" if refusal is None else refusal.split(" in ")[0]
        print(f"{variant}: {kind} done", flush=True)
    return out


def rates(res):
    """Accept rates (gait, not gait) over windows of ``HEADLINE_MIN_S`` and more."""
    got = {}
    for kind in ("gait", "not_gait"):
        rows = [v for k, v in res.items() if k[0] == kind and k[2] >= A.HEADLINE_MIN_S]
        got[kind] = (sum(v == "accepted" for v in rows), len(rows))
    return got


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "build" / "c47" / "stride_cycle47.pkl"))
    parser.add_argument("--variants", default="main,both")
    args = parser.parse_args(argv)
    model = load_stock_library()
    results = {v: outcomes(model, v) for v in args.variants.split(",")}
    set_variant("both")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "wb") as f:
        pickle.dump(results, f)
    base = results.get("main")
    for v, res in results.items():
        r = rates(res)
        print(f"{v}: gaits {r['gait'][0]} of {r['gait'][1]}, not gaits {r['not_gait'][0]} of "
              f"{r['not_gait'][1]} (windows >= {A.HEADLINE_MIN_S} s)")
        if base is None or v == "main":
            continue
        for key in sorted(res):
            if res[key] != base[key]:
                print(f"  {key}: {base[key]} -> {res[key]}")
    accepted = {v: sorted(k for k, o in res.items() if k[0] == "not_gait" and o == "accepted")
                for v, res in results.items()}
    for v, keys in accepted.items():
        print(f"{v}: non-gait windows accepted {keys}")


if __name__ == "__main__":
    main()
