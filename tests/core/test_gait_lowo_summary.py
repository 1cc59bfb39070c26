"""benchmarks/gait_lowo.summarise: a baseline that runs on only some cases is compared with the
method on those cases, over the whole horizon and in every horizon bin."""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import gait_lowo  # noqa: E402


def _case(subject, t0, method, keyed, hold, last=None):
    total = {"method": method, "method_forecast": keyed, "hold": hold}
    if last is not None:
        total["last_cycle"] = last
    bins = {p: {gait_lowo.bin_label(*h): v for h in gait_lowo.HORIZONS} for p, v in total.items()}
    sq = {p: np.full(gait_lowo.N_ANGLES, np.radians(v) ** 2) for p, v in total.items()}
    return gait_lowo.CaseScore(subject, "t", t0, 1.67, total, bins, sq,
                               {p: None for p in total})


def test_baselines_are_compared_on_their_own_cases():
    scores = [_case("a", 0, 2.0, 2.5, 9.0, last=4.0),      # last cycle runs here only
              _case("a", 1, 10.0, 11.0, 9.0),
              _case("b", 0, 6.0, 5.0, 8.0, last=5.0)]
    names = [f"bone{k // 3}.r{'xyz'[k % 3]}" for k in range(gait_lowo.N_ANGLES)]
    block = gait_lowo.summarise(scores, names)["windows"]["1.67"]
    # Means over subjects of subject means: method (6 + 6) / 2, on last cycle's cases (2 + 6) / 2.
    assert np.isclose(block["method"], 6.0)
    assert np.isclose(block["method_forecast"], (6.75 + 5.0) / 2)
    assert np.isclose(block["method_on_last_cycle_cases"], 4.0)
    assert np.isclose(block["baselines"]["last_cycle"], 4.5)
    assert np.isclose(block["ratio_to_best_baseline"], max(6.0 / 8.5, 4.0 / 4.5))
    for b in block["horizons"].values():
        assert np.isclose(b["method_on_baseline_cases"]["last_cycle"], 4.0)
        assert np.isclose(b["method_forecast_on_baseline_cases"]["last_cycle"], 3.75)
        assert np.isclose(b["method_on_baseline_cases"]["hold"], 6.0)
        assert np.isclose(b["ratio_to_best_baseline"], 4.0 / 4.5)
        assert b["ratio_baseline"] == "last_cycle"
