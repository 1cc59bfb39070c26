"""Two suites side by side build a cached asset once: ``cache_lock`` serialises them.

(``make test`` and ``make test BPY=4.5.15`` in one checkout both rendered the two-people clip
into the same folder at once; one read the other's half-written scratch frame.)
"""

import threading
import time

from sample_scenes import footage_scenes
from sample_scenes.cache_lock import cache_lock


def test_the_lock_is_exclusive_across_open_handles(tmp_path):
    """A second holder (another open file: flock conflicts like another process) waits until
    the first lets go."""
    order = []
    first_in = threading.Event()

    def hold():
        with cache_lock(tmp_path / "clip"):
            first_in.set()
            order.append("first in")
            time.sleep(0.3)
            order.append("first out")

    thread = threading.Thread(target=hold)
    thread.start()
    assert first_in.wait(10)
    with cache_lock(tmp_path / "clip"):
        order.append("second in")
    thread.join()
    assert order == ["first in", "first out", "second in"]


def test_two_callers_render_a_clip_once(tmp_path, monkeypatch):
    """``ensure_footage`` called twice at once renders once; the second finds it current."""
    renders = []

    def fake_render(motion, width, height, frames, step, start, out, python, view, condition):
        renders.append(out)
        time.sleep(0.3)                  # long enough for the other caller to arrive
        out.mkdir(parents=True, exist_ok=True)
        (out / "ground_truth.npz").write_bytes(b"")
        params = footage_scenes.render_params(motion, width, height, frames, step, start,
                                              view, condition)
        (out / "params.json").write_text(footage_scenes.json.dumps(params))

    monkeypatch.setattr(footage_scenes, "_render_footage", fake_render)
    results = []

    def call():
        results.append(footage_scenes.ensure_footage("walk", 64, 36, 3, root=tmp_path))

    threads = [threading.Thread(target=call) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(renders) == 1
    assert len(results) == 2 and results[0] == results[1] == renders[0]
