"""core/ must import and run with NumPy only: bpy, mathutils and SciPy are blocked."""

import subprocess
import sys
import textwrap

from tests.data import ROOT

SCRIPT = textwrap.dedent("""
    import importlib, pkgutil, sys

    class Blocker:
        BLOCKED = ("bpy", "mathutils", "scipy", "bmesh", "cv2")
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in self.BLOCKED:
                raise ImportError(f"blocked import of {name}")
            return None

    sys.meta_path.insert(0, Blocker())
    import core
    names = [m.name for m in pkgutil.walk_packages(core.__path__, "core.")]
    for name in names:
        importlib.import_module(name)
    from core.mocap import read_asf, read_amc, asf_to_skeleton
    from core.kinematics import forward_kinematics, local_rotations_from_dofs
    asf = read_asf(sys.argv[1])
    sk = asf_to_skeleton(asf)
    values = read_amc(sys.argv[2], asf).values
    forward_kinematics(sk, *local_rotations_from_dofs(sk, values)[::-1])
    blocked = [m for m in sys.modules if m.split(".")[0] in Blocker.BLOCKED]
    assert not blocked, blocked
    print("imported", len(names), "modules")
""")


def test_core_imports_without_bpy_mathutils_scipy():
    result = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(ROOT / "sample_scenes/data/cmu/08.asf"),
         str(ROOT / "sample_scenes/data/cmu/08_01.amc")],
        cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert "imported" in result.stdout


def test_blocker_really_blocks():
    script = SCRIPT.replace("import core\n", "import core\nimport scipy\n", 1)
    result = subprocess.run([sys.executable, "-c", script, "x", "y"], cwd=ROOT,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode != 0 and "blocked import of scipy" in result.stderr
