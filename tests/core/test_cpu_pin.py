"""tools/cpu_pin.py: the same bytes from a learning run whatever the CPU (issue 21 §3, stop 46).

A CPU is emulated by the variables that make NumPy, OpenBLAS and glibc's libm behave as on an
older one (features turned off, kernels forced): an AVX2/FMA machine without AVX-512 and an
SSE4.2 machine without AVX. Each emulated CPU is pinned as ``pinned_env`` pins a real one.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tools import cpu_pin

ROOT = Path(__file__).resolve().parents[2]
PROBE = ROOT / "tests" / "core" / "cpu_pin_probe.py"
CPU_VARS = ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "NPY_ENABLE_CPU_FEATURES",
            "GLIBC_TUNABLES", cpu_pin.PIN_VAR, cpu_pin.SAVED_VAR)
AVX512 = [f for f in cpu_pin.numpy_dispatched_features() if f.startswith("AVX512")]
EMULATED = {
    "avx2": {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": " ".join(AVX512)},
    "sse42": {"OPENBLAS_CORETYPE": "Nehalem",
              "NPY_DISABLE_CPU_FEATURES": " ".join(["AVX", "F16C", "FMA3", "AVX2"] + AVX512),
              "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-FMA4,-AVX"},
}


def _features():
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:  # NumPy 1.26
        from numpy.core._multiarray_umath import __cpu_features__
    return __cpu_features__


def _clean_env(**extra):
    env = {k: v for k, v in os.environ.items() if k not in CPU_VARS}
    env["OPENBLAS_NUM_THREADS"] = "1"
    env.update(extra)
    return env


def _probe(env):
    out = subprocess.run([sys.executable, str(PROBE)], env=env, cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.split()


def test_pinned_env_pins_every_layer_and_keeps_the_rest():
    env = {"HOME": "/h", "GLIBC_TUNABLES": "glibc.malloc.check=1",
           "NPY_DISABLE_CPU_FEATURES": "AVX512F,FOO", "NPY_ENABLE_CPU_FEATURES": "AVX2",
           "OPENBLAS_CORETYPE": "Haswell"}
    pinned = cpu_pin.pinned_env(env, features=["SSSE3", "AVX2", "AVX512F"])
    assert pinned["HOME"] == "/h" and pinned["OPENBLAS_CORETYPE"] == "Prescott"
    assert pinned["NPY_DISABLE_CPU_FEATURES"].split() == ["AVX512F", "FOO", "SSSE3", "AVX2"]
    assert "NPY_ENABLE_CPU_FEATURES" not in pinned
    assert all(pinned[v] == "1" for v in cpu_pin.THREAD_VARS)
    malloc, hwcaps = pinned["GLIBC_TUNABLES"].split(":")
    assert malloc == "glibc.malloc.check=1"
    assert hwcaps.startswith("glibc.cpu.hwcaps=-AVX2,-FMA,")
    # A hwcaps tunable already there keeps its entries and gains the pin's.
    again = cpu_pin.pinned_env({"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX512F"}, features=[])
    assert again["GLIBC_TUNABLES"].startswith("glibc.cpu.hwcaps=-AVX512F,-AVX2,-FMA,")
    assert cpu_pin.is_pinned(pinned) and not cpu_pin.is_pinned(env)
    assert cpu_pin.pinned_env(pinned, features=["SSE41"]) == pinned   # pinning twice: no-op
    assert cpu_pin.unpinned_env(pinned) == env
    assert cpu_pin.describe(env) == {} and cpu_pin.describe(pinned)["OPENBLAS_CORETYPE"]


def test_a_script_reexecutes_itself_under_the_pin_unless_told_none():
    script = ("import os, sys; sys.path.insert(0, '.'); from tools import cpu_pin; "
              "cpu_pin.pin_from_command_line(); import numpy as np; "
              "print(os.environ.get(cpu_pin.PIN_VAR), np.exp(np.arange(3.0)).sum() > 0)")
    env = _clean_env()
    for args, expect in (([], "x86-64-baseline True"), (["--pin", "none"], "None True")):
        out = subprocess.run([sys.executable, "-c", script, *args], env=env, cwd=ROOT,
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr[-2000:]
        assert out.stdout.strip() == expect
        assert "Warning" not in out.stderr   # NumPy knows every feature the pin names


@pytest.mark.slow
def test_a_learning_run_gives_the_same_bytes_on_emulated_cpus_under_the_pin():
    features = _features()
    if not (features.get("AVX2") and features.get("FMA3")):
        pytest.skip("emulating an AVX2/FMA CPU needs one (OpenBLAS's Haswell kernels)")
    raw = {name: _probe(_clean_env(**emu)) for name, emu in EMULATED.items()}
    pinned = {name: _probe(cpu_pin.pinned_env(_clean_env(**emu))) for name, emu in EMULATED.items()}
    # The emulated CPUs round differently (model file and prediction), so the test can fail...
    assert raw["avx2"][0] != raw["sse42"][0] and raw["avx2"][1] != raw["sse42"][1]
    # ...and the pin makes them agree bit for bit: model file and prediction.
    assert pinned["avx2"] == pinned["sse42"] and len(pinned["avx2"]) == 2
