"""The restyle table's goals on the shipped stock library, restyled onto three walkers it was
learned from (CMU 35_01, 08_04, 35_05; every stock style × cadence 0.7 / 1.0 / 1.3 / 1.6: 132
cases), beside ``make bench-gait ONLY=restyle`` (one held-out walker, a fold model): a change to
the stock library or to ``predict_walk`` must not fail cases elsewhere (docs/gait.md, *The three
misses*). Prints each walker's failed cases and the total. The join is judged against the
walker's own (walking) capture, so a run's join counts when it exceeds a walk's 99th
percentile. About 15 s on an idle 2-core machine::

    OPENBLAS_NUM_THREADS=1 python benchmarks/studies/restyle_sweep.py [--stock PATH]
"""

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))
import gait_restyle as R  # noqa: E402
from core.gait.model import GaitModel  # noqa: E402
from core.gait.stock import STOCK_PATH  # noqa: E402

WALKERS = ("35_01", "08_04", "35_05")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stock", default=str(STOCK_PATH))
    parser.add_argument("--output", default=None, help="JSON of every case's figures")
    args = parser.parse_args(argv)
    model = GaitModel.load(args.stock)
    total, failed, beyond, by_style, either, whole, blocks = 0, 0, 0, 0, 0, 0, {}
    for walker in WALKERS:
        block = R.run_restyle(model=model, walker=walker)
        blocks[walker] = block
        s = block["summary"]
        total += s["cases"]
        failed += s["cases"] - s["met"]
        beyond += s["cases"] - s["met_with_join_vs_steady"]
        by_style += s["cases"] - s["met_with_join_vs_style"]
        either += s["cases"] - s["met_with_join_vs_either"]
        whole += s["cases"] - s["met_with_join_over_the_ramp"]
        print(f"{walker}: {s['cases'] - s['met']} of {s['cases']} failed: {s['failed']}")
        for style, by in block["cases"].items():
            for cad, r in by.items():
                if not r["met"]:
                    f = r["natural"]
                    print(f"   {style}@{cad}: slip {f['slip_cm_s']:.1f} skate {f['skate_cm_s']:.1f}"
                          f" root/legs {f['root_vs_legs']:.2f} low {f['lowest_foot_cm']:.1f}"
                          f" join {f['join_accel_ratio']:.2f} (vs steady {f['join_vs_steady']:.2f},"
                          f" vs the style's captures {f['join_accel_ratio_style']:.2f},"
                          f" vs either {f['join_accel_ratio_either']:.2f})"
                          f" drift {f['heading_drift_deg']:.1f}"
                          f" stride {f['stride_m']:.2f} ({r['fast_forward']['stride_m']:.2f})"
                          f" swing {f['hip_swing_deg']:.0f} ({r['fast_forward']['hip_swing_deg']:.0f})")
    print(f"sweep: {failed} of {total} cases failed ({beyond} with the join judged against the "
          f"larger of the capture's 99th percentile and the walk's own largest after it; "
          f"{by_style} against the requested style's captured walks' 99th percentile, {either} "
          f"against the larger of the walker's and the style's; {whole} with stop 36-40's join, "
          f"the whole ramp against the walker's)")
    if args.output:
        Path(args.output).write_text(json.dumps(blocks, indent=1, default=float))


if __name__ == "__main__":
    main()
