"""tools/cpu_pin.py: the same bytes from a learning run whatever the CPU (issue 21 §3, stop 46).

A CPU is emulated by the variables that make NumPy, OpenBLAS and glibc's libm behave as on an
older one (features turned off, kernels forced): an AVX-512 machine, an AVX2/FMA machine
without AVX-512 and an SSE4.2 machine without AVX. Each emulated CPU is pinned as
``pinned_env`` pins a real one: x86-64-v3 (the default) on the AVX-512 and the AVX2 machine,
x86-64-baseline on the AVX2 and the SSE4.2 machine.
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
    "avx512": {"OPENBLAS_CORETYPE": "SkylakeX"},
    "avx2": {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": " ".join(AVX512)},
    "sse42": {"OPENBLAS_CORETYPE": "Nehalem",
              "NPY_DISABLE_CPU_FEATURES": " ".join(["AVX", "F16C", "FMA3", "AVX2"] + AVX512),
              "GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-FMA4,-AVX"},
}
# pin: (two emulated CPUs, the features this CPU needs to emulate both)
CASES = {"x86-64-v3": (("avx512", "avx2"), ("AVX2", "FMA3", "AVX512_SKX")),
         "x86-64-baseline": (("avx2", "sse42"), ("AVX2", "FMA3"))}


def _cpu_has(*features):
    """Whether this CPU has ``features`` (asked of NumPy in a process without the switches:
    this one may run under the pin, `make test-portability`, which hides them)."""
    script = ("import sys\ntry:\n from numpy._core._multiarray_umath import __cpu_features__ "
              "as f\nexcept ImportError:\n from numpy.core._multiarray_umath import "
              "__cpu_features__ as f\nprint(all(f.get(x) for x in sys.argv[1:]))")
    out = subprocess.run([sys.executable, "-c", script, *features], env=_clean_env(),
                         capture_output=True, text=True, timeout=60, check=True)
    return out.stdout.strip() == "True"


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
    env = {"HOME": "/h", "GLIBC_TUNABLES": "glibc.malloc.check=1:glibc.cpu.hwcaps=-AVX512F",
           "NPY_DISABLE_CPU_FEATURES": "AVX512F,FOO", "NPY_ENABLE_CPU_FEATURES": "AVX2",
           "OPENBLAS_CORETYPE": "Nehalem"}
    features = ["SSSE3", "AVX2", "AVX512F", "AVX512_SKX"]
    base = cpu_pin.pinned_env(env, "x86-64-baseline", features=features)
    assert base["HOME"] == "/h" and base["OPENBLAS_CORETYPE"] == "Prescott"
    assert base["NPY_DISABLE_CPU_FEATURES"].split() == ["AVX512F", "FOO", "SSSE3", "AVX2",
                                                        "AVX512_SKX"]
    assert "NPY_ENABLE_CPU_FEATURES" not in base
    assert all(base[v] == "1" for v in cpu_pin.THREAD_VARS)
    malloc, hwcaps = base["GLIBC_TUNABLES"].split(":")
    assert malloc == "glibc.malloc.check=1"
    assert hwcaps.startswith("glibc.cpu.hwcaps=-AVX2,-FMA,")
    # x86-64-v3 keeps the AVX2/FMA machine's NumPy loops and libm (the CPU's own hwcaps).
    v3 = cpu_pin.pinned_env(env, features=features)
    assert v3["OPENBLAS_CORETYPE"] == "Haswell" and v3[cpu_pin.PIN_VAR] == "x86-64-v3"
    assert v3["NPY_DISABLE_CPU_FEATURES"].split() == ["AVX512F", "FOO", "AVX512_SKX"]
    assert v3["GLIBC_TUNABLES"] == "glibc.malloc.check=1"
    assert cpu_pin.is_pinned(v3) and not cpu_pin.is_pinned(base) and not cpu_pin.is_pinned(env)
    assert cpu_pin.is_pinned(base, "x86-64-baseline")
    # Pinning a pinned environment starts from the variables as they were.
    assert cpu_pin.pinned_env(base, features=features) == v3
    assert cpu_pin.unpinned_env(base) == env and cpu_pin.unpinned_env(v3) == env
    assert cpu_pin.describe(env) == {} and cpu_pin.describe(base)["OPENBLAS_CORETYPE"]


def test_a_script_reexecutes_itself_under_the_pin_unless_told_none():
    script = ("import os, sys; sys.path.insert(0, '.'); from tools import cpu_pin; "
              "cpu_pin.pin_from_command_line(); import numpy as np; "
              "print(os.environ.get(cpu_pin.PIN_VAR), np.exp(np.arange(3.0)).sum() > 0)")
    env = _clean_env()
    v3 = "x86-64-v3 True" if _cpu_has("AVX2", "FMA3", "F16C") else None
    for args, expect in (([], v3), (["--pin", "x86-64-baseline"], "x86-64-baseline True"),
                         (["--pin", "none"], "None True")):
        out = subprocess.run([sys.executable, "-c", script, *args], env=env, cwd=ROOT,
                             capture_output=True, text=True, timeout=120)
        if expect is None:    # a CPU without AVX2/FMA: the default pin refuses, by name
            assert out.returncode != 0 and "x86-64-baseline" in out.stderr
            continue
        assert out.returncode == 0, out.stderr[-2000:]
        assert out.stdout.strip() == expect
        assert "Warning" not in out.stderr   # NumPy knows every feature the pin names


@pytest.mark.slow
@pytest.mark.parametrize("pin", list(CASES))
def test_a_learning_run_gives_the_same_bytes_on_emulated_cpus_under_the_pin(pin):
    cpus, needs = CASES[pin]
    if not _cpu_has(*needs):
        pytest.skip(f"emulating {' and '.join(cpus)} needs a CPU with {' '.join(needs)}")
    raw = {name: _probe(_clean_env(**EMULATED[name])) for name in cpus}
    pinned = {name: _probe(cpu_pin.pinned_env(_clean_env(**EMULATED[name]), pin))
              for name in cpus}
    a, b = cpus
    # The emulated CPUs round differently (model file and prediction), so the test can fail...
    assert raw[a][0] != raw[b][0] and raw[a][1] != raw[b][1]
    # ...and the pin makes them agree bit for bit: model file and prediction.
    assert pinned[a] == pinned[b] and len(pinned[a]) == 2
