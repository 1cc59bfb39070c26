"""One arithmetic on every x86-64 CPU, for builds and benchmarks (never for users' Blender).

The same Python code computes different last bits on different CPUs, through three libraries
that pick code by the CPU they run on:

* **OpenBLAS** (NumPy's BLAS/LAPACK) picks its kernels (SSE2 ... AVX-512) by CPU model; the
  kernels sum the products of a matrix product in different orders. ``OPENBLAS_CORETYPE``
  forces one kernel set; ``Prescott`` is the oldest that this OpenBLAS holds (it reports itself
  as ``Katmai``): SSE2/SSE3 only, which every x86-64 CPU runs. Its blocking along the shared
  dimension (GEMM_Q) is a constant of the kernel set; only the row blocking (GEMM_P) follows the
  CPU's L2 cache size, and that does not change the order of any element's sum.
* **NumPy** dispatches its own loops (exp, log, sin, cos, power, arctan2, tanh, ...; AVX2/FMA3,
  AVX-512 through SVML) by the features the CPU has. ``NPY_DISABLE_CPU_FEATURES`` turns
  dispatched features off; NumPy (2.x and 1.26) refuses to disable a *baseline* feature (an
  error: the x86-64 baseline SSE/SSE2/SSE3 of these wheels), warns about a name it does not
  dispatch, and silently accepts a feature the CPU lacks. So the pin disables exactly the
  features this NumPy dispatches (``__cpu_dispatch__``): every CPU then runs the baseline
  loops.
* **glibc's libm** (what NumPy calls for float64 exp/log/sin/cos/pow without its own SIMD, and
  Python's ``math``) picks FMA/AVX2 variants by the CPU (``ifunc``). ``GLIBC_TUNABLES``
  ``glibc.cpu.hwcaps=-AVX2,-FMA,-FMA4`` turns them off (glibc 2.33 and later; glibc 2.26-2.32
  spelled them ``AVX2_Usable``, ... and both spellings are given: glibc ignores names it does
  not know). Tunables are read once when a process starts, hence the re-execution below.

Measured on an AVX-512 Xeon (Stop 46, docs/gait.md): each layer alone changes the last bits of
2 million float64 results (NumPy dispatch: exp 92 452 differ, tanh 392 338; libm FMA: exp 1 448,
sin 1 382; OpenBLAS kernels: 181 654 of 200 000 matrix-product elements), and the pinned
environment gives the same bits whichever CPU is emulated. Bit-identical results also need the
same software: the same Python packages (the venv's pinned NumPy) and the same glibc.

``reexec_pinned()`` re-executes the running script under the pinned environment (the same
interpreter and argv) unless it already runs under it; ``tools/build_stock_gaits.py`` and
``benchmarks/bench_gait.py`` call it first thing. Predict Gait's runtime in Blender never does:
the pin makes NumPy and BLAS slower and only buys the same bits everywhere.
"""

import argparse
import json
import os
import sys

PIN_VAR = "TRACK_AND_STRIDE_CPU_PIN"
SAVED_VAR = "TRACK_AND_STRIDE_UNPINNED"  # the pinned variables' values before the pin (JSON)
PIN_NAME = "x86-64-baseline"
OPENBLAS_CORE = "Prescott"
GLIBC_HWCAPS_OFF = ("AVX2", "FMA", "FMA4", "AVX2_Usable", "FMA_Usable", "FMA4_Usable")
THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def numpy_dispatched_features():
    """The CPU features this NumPy dispatches at run time (tuple of str; empty off x86)."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__  # NumPy 2
    except ImportError:
        from numpy.core._multiarray_umath import __cpu_dispatch__  # NumPy 1.26
    return tuple(__cpu_dispatch__)


def _merge_hwcaps(tunables, off):
    """``GLIBC_TUNABLES`` (``name=value`` joined by ``:``) with ``-name`` entries of ``off``
    added to ``glibc.cpu.hwcaps`` (other tunables kept)."""
    items = [item for item in (tunables or "").split(":") if item]
    minus = ",".join(f"-{name}" for name in off)
    for i, item in enumerate(items):
        key, _, value = item.partition("=")
        if key == "glibc.cpu.hwcaps":
            items[i] = f"{key}={value + ',' if value else ''}{minus}"
            break
    else:
        items.append(f"glibc.cpu.hwcaps={minus}")
    return ":".join(items)


def pinned_env(env=None, features=None):
    """The environment ``env`` (default ``os.environ``) with the CPU pin applied (a new dict).

    Parameters
    ----------
    env : mapping of str to str, optional
        The environment to pin; its other variables are kept, CPU features it already turns
        off stay off.
    features : sequence of str, optional
        NumPy's dispatched features (default: ``numpy_dispatched_features()``, which imports
        NumPy).

    Returns
    -------
    dict
        ``env`` plus one BLAS thread, ``OPENBLAS_CORETYPE=Prescott``, every dispatched NumPy
        feature disabled, libm's FMA/AVX2 variants off, and the marker ``PIN_VAR``.
    """
    out = dict(os.environ if env is None else env)
    if is_pinned(out):
        return out
    features = numpy_dispatched_features() if features is None else tuple(features)
    changed = (*THREAD_VARS, "OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES",
               "NPY_ENABLE_CPU_FEATURES", "GLIBC_TUNABLES")
    out[SAVED_VAR] = json.dumps({var: out.get(var) for var in changed})
    for var in THREAD_VARS:
        out[var] = "1"
    out["OPENBLAS_CORETYPE"] = OPENBLAS_CORE
    disabled = out.get("NPY_DISABLE_CPU_FEATURES", "").replace(",", " ").split()
    out["NPY_DISABLE_CPU_FEATURES"] = " ".join(dict.fromkeys(disabled + list(features)))
    out.pop("NPY_ENABLE_CPU_FEATURES", None)  # NumPy 2 refuses both at once
    out["GLIBC_TUNABLES"] = _merge_hwcaps(out.get("GLIBC_TUNABLES"), GLIBC_HWCAPS_OFF)
    out[PIN_VAR] = PIN_NAME
    return out


def unpinned_env(env=None):
    """The environment before :func:`pinned_env` (a new dict): the pinned variables as they
    were (for a child process that should run on this CPU's own kernels)."""
    out = dict(os.environ if env is None else env)
    if not is_pinned(out):
        return out
    for var, value in json.loads(out.pop(SAVED_VAR, "{}")).items():
        if value is None:
            out.pop(var, None)
        else:
            out[var] = value
    out.pop(PIN_VAR, None)
    return out


def is_pinned(env=None):
    """Whether ``env`` (default ``os.environ``) is already pinned by :func:`pinned_env`."""
    env = os.environ if env is None else env
    return (env.get(PIN_VAR) == PIN_NAME and env.get("OPENBLAS_CORETYPE") == OPENBLAS_CORE
            and all(env.get(var) == "1" for var in THREAD_VARS))


def reexec_pinned(argv=None):
    """Re-execute this Python script under :func:`pinned_env` unless already pinned.

    Call it before any computation (the process is replaced: nothing computed so far
    survives). ``argv`` defaults to the interpreter's own command line (``sys.orig_argv``:
    its options, the script, the script's arguments). Returns only when already pinned.
    """
    if is_pinned():
        return
    argv = list(sys.orig_argv[1:] if argv is None else argv)
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, *argv], pinned_env())


def add_pin_argument(parser):
    """Add ``--pin {x86-64-baseline,none}`` to an ``argparse`` parser (default: the pin)."""
    parser.add_argument("--pin", choices=(PIN_NAME, "none"), default=PIN_NAME,
                        help="run under the CPU pin of tools/cpu_pin.py (default: the same "
                             "bits on every x86-64 CPU) or on this CPU's own kernels (none)")


def pin_from_command_line(argv=None):
    """Re-execute under the pin (:func:`reexec_pinned`) unless the command line (default
    ``sys.argv[1:]``) says ``--pin none``. Call it before NumPy computes anything."""
    parser = argparse.ArgumentParser(add_help=False)
    add_pin_argument(parser)
    known, _ = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    if known.pin != "none":
        reexec_pinned()


def describe(env=None):
    """The pin's settings as recorded in reports (dict of str; empty when not pinned)."""
    env = os.environ if env is None else env
    if not is_pinned(env):
        return {}
    keys = ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "GLIBC_TUNABLES", PIN_VAR)
    return {key: env.get(key, "") for key in keys}


def main(argv=None):
    """``python tools/cpu_pin.py COMMAND [ARG ...]``: run COMMAND under the pin (``make
    test-portability`` runs the core tests so)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        print(main.__doc__.strip())
        return 0 if argv else 2
    os.execvpe(argv[0], argv, pinned_env())


if __name__ == "__main__":
    sys.exit(main())
