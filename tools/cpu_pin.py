"""One arithmetic across CPUs, for builds and benchmarks (never for users' Blender).

The same Python code computes different last bits on different CPUs, through three libraries
that pick code by the CPU they run on:

* **OpenBLAS** (NumPy's BLAS/LAPACK) picks its kernels (SSE2 ... AVX-512) by CPU model; the
  kernels sum the products of a matrix product in different orders. ``OPENBLAS_CORETYPE``
  forces one kernel set (it must be one the CPU can run). Its blocking along the shared
  dimension (GEMM_Q) is a constant of the kernel set; only the row blocking (GEMM_P) of the
  oldest sets follows the L2 cache size, which leaves every element's sum in the same order.
* **NumPy** dispatches its own loops (exp, log, sin, cos, power, arctan2, tanh, ...; AVX2/FMA3,
  AVX-512 through SVML) by the features the CPU has. ``NPY_DISABLE_CPU_FEATURES`` turns
  dispatched features off; NumPy (2.x and 1.26) refuses to disable a *baseline* feature (an
  error: SSE/SSE2/SSE3 for these wheels), warns about a name it does not dispatch, and
  silently accepts a feature the CPU lacks; it cannot turn on a feature the CPU lacks. The
  features to disable are read from this NumPy (``__cpu_dispatch__``).
* **glibc's libm** (what NumPy calls for float64 exp/log/sin/cos/pow without its own SIMD, and
  Python's ``math``) picks FMA variants on a CPU with FMA and AVX2 (``ifunc``; no AVX-512
  variants). ``GLIBC_TUNABLES`` ``glibc.cpu.hwcaps=-AVX2,-FMA,-FMA4`` turns them off (glibc
  2.33 and later; 2.26-2.32 spelled them ``AVX2_Usable``, ...: both are given, glibc ignores
  names it does not know). Tunables are read when a process starts, hence the re-execution.

Two pins (``PINS``):

* ``x86-64-v3`` (the default): what an AVX2/FMA machine without AVX-512 computes — OpenBLAS's
  Haswell kernels (which OpenBLAS also runs on AMD Zen), NumPy's loops up to AVX2/FMA3, libm's
  FMA variants. The same bits on every CPU with AVX2 and FMA (Intel since 2013, AMD since
  2017); on an older CPU it refuses, by name. The shipped stock library was built on such a
  machine, and this pin rebuilds it bit for bit on an AVX-512 Xeon.
* ``x86-64-baseline``: the same bits on every x86-64 CPU — OpenBLAS's oldest kernels
  (``Prescott``, reported as Katmai: SSE2/SSE3), NumPy's baseline loops, libm's SSE2 variants.
  It learns another stock library (learning's refinement lands elsewhere along a nearly flat
  direction: Stop 46 in docs/gait.md), so it is not the default; ``make test-portability`` runs
  the core tests under it.

Bit-identical results also need the same software: the venv's NumPy (and its OpenBLAS) and the
same glibc. ``reexec_pinned()`` re-executes the running script under a pinned environment (the
same interpreter and argv) unless it already runs under it; ``tools/build_stock_gaits.py`` and
``benchmarks/bench_gait.py`` call it first thing (``--pin none``: this CPU's own kernels).
"""

import argparse
import json
import os
import sys

PIN_VAR = "TRACK_AND_STRIDE_CPU_PIN"
SAVED_VAR = "TRACK_AND_STRIDE_UNPINNED"  # the pinned variables' values before the pin (JSON)
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
CHANGED_VARS = (*THREAD_VARS, "OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES",
                "NPY_ENABLE_CPU_FEATURES", "GLIBC_TUNABLES")
# libm's FMA/AVX2 variants off: glibc >= 2.33's names, then 2.26-2.32's (unknown ones ignored).
GLIBC_HWCAPS_OFF = ("AVX2", "FMA", "FMA4", "AVX2_Usable", "FMA_Usable", "FMA4_Usable")
V3_FEATURES = ("SSSE3", "SSE41", "POPCNT", "SSE42", "AVX", "F16C", "FMA3", "AVX2")
# name: (OpenBLAS kernels, NumPy features kept (the CPU must have them), libm hwcaps off)
PINS = {
    # x86-64-v3 (Intel Haswell 2013 on, AMD Zen on): what an AVX2/FMA machine without AVX-512
    # computes (the shipped library was built on one: an AMD EPYC). The default.
    "x86-64-v3": ("Haswell", V3_FEATURES, ()),
    # Every x86-64 CPU: OpenBLAS's oldest kernels (it reports them as Katmai), NumPy's baseline
    # loops, libm's SSE2 variants. Slower; learns a different library (Stop 46, docs/gait.md).
    "x86-64-baseline": ("Prescott", (), GLIBC_HWCAPS_OFF),
}
DEFAULT_PIN = "x86-64-v3"


def numpy_dispatched_features():
    """The CPU features this NumPy dispatches at run time (tuple of str; empty off x86)."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__  # NumPy 2
    except ImportError:
        from numpy.core._multiarray_umath import __cpu_dispatch__  # NumPy 1.26
    return tuple(__cpu_dispatch__)


def missing_features(pin=DEFAULT_PIN):
    """The NumPy features ``pin`` keeps that this process's CPU lacks (or has turned off)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__  # NumPy 2
    except ImportError:
        from numpy.core._multiarray_umath import __cpu_features__  # NumPy 1.26
    return [f for f in PINS[pin][1] if not __cpu_features__.get(f)]


def _set_hwcaps(tunables, off):
    """``GLIBC_TUNABLES`` (``name=value`` joined by ``:``) with ``glibc.cpu.hwcaps`` set to
    ``-name`` for each of ``off`` (left out when ``off`` is empty: the CPU's own); other
    tunables kept."""
    items = [item for item in (tunables or "").split(":")
             if item and item.partition("=")[0] != "glibc.cpu.hwcaps"]
    if off:
        items.append("glibc.cpu.hwcaps=" + ",".join(f"-{name}" for name in off))
    return ":".join(items)


def pinned_env(env=None, pin=DEFAULT_PIN, features=None):
    """The environment ``env`` (default ``os.environ``) with the CPU pin ``pin`` applied.

    Parameters
    ----------
    env : mapping of str to str, optional
        The environment to pin; its other variables are kept, NumPy features it already turns
        off stay off.
    pin : str
        A key of ``PINS``.
    features : sequence of str, optional
        NumPy's dispatched features (default: ``numpy_dispatched_features()``, which imports
        NumPy).

    Returns
    -------
    dict
        A new environment: one BLAS thread, the pin's OpenBLAS kernels, every dispatched
        NumPy feature off but the pin's, libm's hwcaps as the pin says, the marker
        ``PIN_VAR`` (and ``SAVED_VAR``: the variables as they were, for :func:`unpinned_env`).
    """
    out = unpinned_env(env)
    core, keep, hwcaps_off = PINS[pin]
    features = numpy_dispatched_features() if features is None else tuple(features)
    out[SAVED_VAR] = json.dumps({var: out.get(var) for var in CHANGED_VARS})
    for var in THREAD_VARS:
        out[var] = "1"
    out["OPENBLAS_CORETYPE"] = core
    disabled = out.get("NPY_DISABLE_CPU_FEATURES", "").replace(",", " ").split()
    off = [f for f in features if f not in keep]
    out["NPY_DISABLE_CPU_FEATURES"] = " ".join(dict.fromkeys(disabled + off))
    out.pop("NPY_ENABLE_CPU_FEATURES", None)  # NumPy 2 refuses both at once
    tunables = _set_hwcaps(out.get("GLIBC_TUNABLES"), hwcaps_off)
    if tunables:
        out["GLIBC_TUNABLES"] = tunables
    else:
        out.pop("GLIBC_TUNABLES", None)
    out[PIN_VAR] = pin
    return out


def unpinned_env(env=None):
    """The environment before :func:`pinned_env` (a new dict): the pinned variables as they
    were (for a child process that should run on this CPU's own kernels)."""
    out = dict(os.environ if env is None else env)
    if PIN_VAR not in out:
        return out
    for var, value in json.loads(out.pop(SAVED_VAR, "{}")).items():
        if value is None:
            out.pop(var, None)
        else:
            out[var] = value
    out.pop(PIN_VAR, None)
    return out


def is_pinned(env=None, pin=DEFAULT_PIN):
    """Whether ``env`` (default ``os.environ``) is already pinned by :func:`pinned_env`."""
    env = os.environ if env is None else env
    return (env.get(PIN_VAR) == pin and env.get("OPENBLAS_CORETYPE") == PINS[pin][0]
            and all(env.get(var) == "1" for var in THREAD_VARS))


def reexec_pinned(pin=DEFAULT_PIN, argv=None):
    """Re-execute this Python script under :func:`pinned_env` unless already pinned.

    Call it before any computation (the process is replaced: nothing computed so far
    survives). ``argv`` defaults to the interpreter's own command line (``sys.orig_argv``:
    its options, the script, the script's arguments). Returns only when already pinned; exits
    with a message on a CPU that lacks what the pin keeps (x86-64-v3 on a CPU without AVX2).
    """
    if is_pinned(pin=pin):
        return
    missing = missing_features(pin)
    if missing:
        sys.exit(f"CPU pin {pin}: this CPU lacks {' '.join(missing)}; run with --pin "
                 "x86-64-baseline (every x86-64 CPU, other bytes) or --pin none")
    argv = list(sys.orig_argv[1:] if argv is None else argv)
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, *argv], pinned_env(pin=pin))


def add_pin_argument(parser):
    """Add ``--pin {x86-64-v3,x86-64-baseline,none}`` to an ``argparse`` parser."""
    parser.add_argument("--pin", choices=(*PINS, "none"), default=DEFAULT_PIN,
                        help=f"run under a CPU pin of tools/cpu_pin.py (default {DEFAULT_PIN}: "
                             "the same bits on every CPU with AVX2/FMA; x86-64-baseline: on "
                             "every x86-64 CPU) or on this CPU's own kernels (none)")


def pin_from_command_line(argv=None):
    """Re-execute under the pin the command line (default ``sys.argv[1:]``) names with
    ``--pin`` (:func:`reexec_pinned`; the default pin when not given; nothing for ``none``).
    Call it before NumPy computes anything."""
    parser = argparse.ArgumentParser(add_help=False)
    add_pin_argument(parser)
    known, _ = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    if known.pin != "none":
        reexec_pinned(known.pin)


def describe(env=None):
    """The pin's settings as recorded in reports (dict of str; empty when not pinned)."""
    env = os.environ if env is None else env
    if env.get(PIN_VAR) not in PINS:
        return {}
    keys = (PIN_VAR, "OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "GLIBC_TUNABLES")
    return {key: env.get(key, "") for key in keys}


def main(argv=None):
    """``python tools/cpu_pin.py [--pin NAME] COMMAND [ARG ...]``: run COMMAND under a pin
    (default x86-64-v3; ``make test-portability`` runs the core tests under x86-64-baseline)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    pin = DEFAULT_PIN
    if argv[:1] == ["--pin"] and len(argv) >= 2:
        pin, argv = argv[1], argv[2:]
    if not argv or argv[0] in ("-h", "--help") or pin not in PINS:
        print(main.__doc__.strip())
        return 0 if argv[:1] in (["-h"], ["--help"]) else 2
    missing = missing_features(pin)
    if missing:
        sys.exit(f"CPU pin {pin}: this CPU lacks {' '.join(missing)}")
    os.execvpe(argv[0], argv, pinned_env(pin=pin))


if __name__ == "__main__":
    sys.exit(main())
