"""Build the installable extension zip with Blender's own extension builder.

The builder (``blender_ext.py build``) ships inside the ``bpy`` wheel; using it means the zip is
validated exactly as ``blender --command extension build`` would validate it. The manifest's
``[build] paths_exclude_pattern`` keeps tests, benchmarks, sample scenes and caches out.

Usage: ``python tools/build_extension.py --output build/track_and_stride-<version>.zip``
"""

import argparse
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def find_blender_ext() -> Path:
    """Locate ``bl_pkg/cli/blender_ext.py`` inside the installed ``bpy`` package (without importing bpy)."""
    import importlib.util

    spec = importlib.util.find_spec("bpy")
    if spec is None or spec.origin is None:
        raise SystemExit("bpy is not installed in this Python; run `make extension` (it creates .venv).")
    package_dir = Path(spec.origin).parent
    hits = sorted(package_dir.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    if not hits:
        raise SystemExit(f"blender_ext.py not found under {package_dir}")
    return hits[-1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", required=True, help="path of the zip to write")
    args = parser.parse_args()
    output = Path(args.output).resolve()
    output.parent.mkdir(parents=True, exist_ok=True)
    if output.exists():
        output.unlink()
    cmd = [sys.executable, str(find_blender_ext()), "build",
           "--source-dir", str(ROOT), "--output-filepath", str(output)]
    result = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True,
                            env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    if result.returncode != 0 or not output.exists():
        sys.stderr.write(result.stdout + result.stderr)
        return result.returncode or 1
    print(f"built {output.relative_to(ROOT) if output.is_relative_to(ROOT) else output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
