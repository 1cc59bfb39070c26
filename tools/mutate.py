"""Mutation testing of core modules, each against its own tests (``make mutate``; mutmut 3).

For every module of :data:`MODULES` a scratch copy of the project is made under
``build/mutate/<name>/`` with a ``setup.cfg`` that tells mutmut to mutate that one module and to
run only that module's own test files; ``mutmut run`` mutates it and ``mutmut results`` reads
back what each mutant did. A mutant is *killed* when a test fails with it, *survived* when every
test still passes. The score is killed / (mutants - equivalent), the equivalent ones (changes no
test can see because the behaviour is the same) listed in :data:`EQUIVALENT` with the reason
in ``docs/testing.md``.

    .venv-mutate/bin/python tools/mutate.py [--only checks ekf] [--output build/mutate/scores.json]

mutmut lives in its own virtualenv (``.venv-mutate``, ``requirements-mutate.txt``): neither
the extension nor the main test venv gain it.
"""

import argparse
import json
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: module -> its own test files (the issue's six; more can be added).
MODULES = {
    "checks": ("core/gait/checks.py", ["tests/core/test_gait_checks.py"]),
    "amc": ("core/mocap/amc.py", ["tests/core/test_acclaim.py"]),
    "distortion": ("core/tracking/distortion.py", ["tests/core/test_tracking_distortion.py"]),
    "acceptance": ("core/tracking/acceptance.py", ["tests/core/test_tracking_acceptance.py",
                                                   "tests/core/test_tracking_acceptance_blend.py"]),
    "drift": ("core/tracking/drift.py", ["tests/core/test_tracking_drift.py"]),
    "ekf": ("core/gait/ekf.py", ["tests/core/test_gait_ekf.py"]),
}

#: Survivors that are equivalent mutants (same behaviour), by mutant name, with why
#: (docs/testing.md explains each). Names are mutmut's: module.x_function__mutmut_N.
EQUIVALENT = {}

COPY = ("core", "tests", "sample_scenes", "pytest.ini")


def _scratch(name, module, tests):
    """A copy of the project for one module's run, with its mutmut configuration."""
    folder = ROOT / "build" / "mutate" / name
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    for item in COPY:
        source = ROOT / item
        if source.is_dir():
            shutil.copytree(source, folder / item,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.blend1"))
        else:
            shutil.copy2(source, folder / item)
    (folder / "setup.cfg").write_text(
        "[mutmut]\n"
        "source_paths = core\n"
        f"only_mutate = {module}\n"
        f"tests_dir = {' '.join(tests)}\n"
        "also_copy =\n    tests\n    sample_scenes\n    pytest.ini\n"
        "pytest_add_cli_args = -p no:cacheprovider -q -x\n")
    return folder


def _results(folder):
    """{mutant name: status} from ``mutmut results --all true``."""
    done = subprocess.run([sys.executable, "-m", "mutmut", "results", "--all", "true"],
                          cwd=folder, capture_output=True, text=True)
    out = {}
    for line in done.stdout.splitlines():
        match = re.match(r"\s*([\w.]+__mutmut_\d+):\s*(.+?)\s*$", line)
        if match:
            out[match.group(1)] = match.group(2)
    return out


def run_module(name, module, tests, jobs):
    folder = _scratch(name, module, tests)
    tic = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mutmut", "run", "--max-children", str(jobs)],
                   cwd=folder, stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    statuses = _results(folder)
    survived = sorted(k for k, v in statuses.items() if v == "survived")
    equivalent = [k for k in survived if k in EQUIVALENT]
    counted = len(statuses) - len(equivalent)
    killed = sum(v == "killed" for v in statuses.values())
    return {"module": module, "tests": tests, "mutants": len(statuses), "killed": killed,
            "survived": [k for k in survived if k not in EQUIVALENT],
            "equivalent": equivalent,
            "other": {k: v for k, v in statuses.items() if v not in ("killed", "survived")},
            "score": round(killed / counted, 4) if counted else None,
            "seconds": round(time.perf_counter() - tic, 1)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=sorted(MODULES))
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--output", type=Path, default=ROOT / "build/mutate/scores.json")
    args = parser.parse_args(argv)
    rows = []
    for name in args.only or MODULES:
        module, tests = MODULES[name]
        row = run_module(name, module, tests, args.jobs)
        rows.append(row)
        print(f"{module}: {row['killed']}/{row['mutants']} killed, "
              f"{len(row['equivalent'])} equivalent, score {row['score']} "
              f"({row['seconds']} s); survived: {', '.join(row['survived']) or 'none'}",
              flush=True)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(rows, indent=1) + "\n")
    low = [r["module"] for r in rows if r["score"] is None or r["score"] < 0.9]
    if low:
        print(f"below 90 %: {', '.join(low)}")
    return 1 if low else 0


if __name__ == "__main__":
    sys.exit(main())
