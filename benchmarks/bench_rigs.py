"""Track Keyframes and Fit Body on the rigs animators animate (issue 18; gait rows: issue 19).

    python benchmarks/bench_rigs.py --extension build/track_and_stride-<v>.zip \
        --output build/bench/rigs.json

Rigs (``sample_scenes/rig_scenes.py``, built from what ``bpy`` bundles): ``cmu`` (the
reference, *Import › Acclaim*), ``metarig``, ``rigify_fk``, ``rigify_ik``, ``mixamo_fbx`` (FBX
round trip: object scale 0.01, centimetres) and ``ik_legs``. Each is skinned to the same body and
walks the same CMU walk (35_01, 61 frames at 30 fps) keyed on its own controls, rendered with
Workbench from one camera at 640x360 (``sample_scenes/rig_footage.py``, cached under
``build/rig_footage``; see ``docs/bench_rigs.md``).

For each rig and keys every 10 / 15 / 20 frames, a fresh ``bpy`` process installs the built
extension, opens the rig's scene, keeps the walk's keys on the rig's controls only at frames
1, 1 + k, … 61 (what the animator keyed), sets the Track panel to the footage (image sequence,
the scene camera, Processes 1) and runs ``bpy.ops.track_and_stride.track_keyframes()``:

* ``interpolation_cm``: mean distance of the rig's **deforming joints** (per body part the head
  of its first deforming bone, and the tails of head, hands and toes: 26 joints; metres → cm) to
  the truth over the in-between frames, as Blender evaluates the kept keys (its own
  interpolation of them), before tracking;
* ``tracker_cm``: the same after Track Keyframes (``null`` when it refused or failed; ``status``
  and ``message`` say what it reported);
* ``keys_on_unmapped_bones``: F-curves of pose bones that are not the rig's controls (face,
  finger, tweak, ``MCH-``/``DEF-``/``ORG-`` bones, the other IK/FK set …) that tracking created
  or changed, with a count per kind of bone;
* ``user_keys_bit_for_bit``: every key the animator had is still there with the same value,
  handles, interpolation and handle types.

``fit_body_peak_mb``: Fit Body to Footage on the same scene at 1920x1080 (keys every 15) in a
fresh process: the peak of the memory Python and NumPy allocate during the operator
(``tracemalloc``), beside the process's peak RSS growth. Every worker runs under a memory
limit (``--memory-limit-gb``, address space) and a time limit, so that an operator that would
need more is recorded as such instead of taking the machine down.

Gait rows (``gait``, ``track_then_predict``; issue 19) are ``benchmarks/rig_gait.py``'s: Predict
Gait on each rig against the CMU skeleton's prediction, the round trip through the model's joint
space, foot slide, and a walk tracked from the footage continued by Predict Gait.
"""

import argparse
import contextlib
import json
import os
import platform
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from sample_scenes.rig_footage import (ensure_rig_footage, load_rig_footage,  # noqa: E402
                                       open_rig_scene, part_joints)

RIGS = ("cmu", "metarig", "rigify_fk", "rigify_ik", "mixamo_fbx", "ik_legs")
KEYS_EVERY = (10, 15, 20)
N_FRAMES = 61
TRACK_SIZE = (640, 360)
FIT_SIZE = (1920, 1080)
FIT_KEYS_EVERY = 15
MODULE = "bl_ext.user_default.track_and_stride"

#: Kinds of bones that must never get keys from tracking (name patterns, checked in order).
BONE_KINDS = (
    ("MCH", re.compile(r"^MCH-")), ("DEF", re.compile(r"^DEF-")), ("ORG", re.compile(r"^ORG-")),
    ("tweak", re.compile(r"tweak", re.I)),
    ("finger", re.compile(r"f_(index|middle|ring|pinky)|thumb|palm|fingers|Hand(Index|Middle|"
                          r"Ring|Pinky|Thumb)", re.I)),
    ("face", re.compile(r"lip|nose|brow|lid|ear|jaw|chin|cheek|forehead|temple|tongue|teeth|"
                        r"eye|face|HeadTop", re.I)),
)


def bone_kind(name):
    """The kind of a bone that is not a control (``BONE_KINDS``; else ``'other'``)."""
    return next((kind for kind, pattern in BONE_KINDS if pattern.search(name)), "other")


# --------------------------------------------------------------------------------------------
# Workers (each in a fresh bpy process)
# --------------------------------------------------------------------------------------------

def _install(extension):
    import bpy
    result = bpy.ops.extensions.package_install_files(
        filepath=str(Path(extension).resolve()), repo="user_default", enable_on_install=True)
    if result != {"FINISHED"} or MODULE not in bpy.context.preferences.addons:
        raise RuntimeError(f"installing {extension} failed: {result}")


@contextlib.contextmanager
def captured_output(sink):
    """Capture this process's stdout and stderr at the file-descriptor level (Blender prints
    operator reports there in background mode); the text is appended to ``sink``."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            tmp.seek(0)
            sink.append(tmp.read().decode(errors="replace"))


def _reports(text):
    """Operator report lines (``Info: …``, ``Warning: …``, ``Error: …``) in printed output."""
    return [line.strip() for line in text.splitlines()
            if re.match(r"^\s*(Info|Warning|Error)\b", line)]


def _key_state(obj):
    """{(data_path, index): {prop: array}} of every F-curve of the object's action."""
    anim = obj.animation_data
    if anim is None or anim.action is None:
        return {}
    out = {}
    for layer in anim.action.layers:
        for strip in layer.strips:
            bag = strip.channelbag(anim.action_slot)
            if bag is None:
                continue
            for fcurve in bag.fcurves:
                points = fcurve.keyframe_points
                n = len(points)
                state = {}
                for prop, width, dtype in (("co", 2, np.float32), ("handle_left", 2, np.float32),
                                           ("handle_right", 2, np.float32),
                                           ("interpolation", 1, np.int32),
                                           ("handle_left_type", 1, np.int32),
                                           ("handle_right_type", 1, np.int32)):
                    a = np.empty(n * width, dtype=dtype)
                    points.foreach_get(prop, a)
                    state[prop] = a.reshape(n, width) if width > 1 else a
                out[(fcurve.data_path, fcurve.array_index)] = state
    return out


def _bone_of(path):
    m = re.match(r'pose\.bones\["(.*)"\]\.', path)
    return m.group(1) if m else None


def user_keys_kept(before, after):
    """Whether every key of ``before`` is in ``after`` (same frame) bit for bit."""
    for key, old in before.items():
        new = after.get(key)
        if new is None:
            return False
        frames_new = new["co"][:, 0]
        for i, frame in enumerate(old["co"][:, 0]):
            j = np.nonzero(frames_new == frame)[0]
            if len(j) != 1:
                return False
            if any(old[p][i].tobytes() != new[p][j[0]].tobytes() for p in old):
                return False
    return True


def keys_on_unmapped(before, after, controls):
    """F-curves of bones outside ``controls`` that are new or changed: (count, per kind,
    bone names)."""
    changed = set()
    for key, new in after.items():
        bone = _bone_of(key[0])
        if bone is None or bone in controls:
            continue
        old = before.get(key)
        if old is None or any(old[p].tobytes() != new[p].tobytes() for p in new):
            changed.add((bone, key))
    per_kind = {}
    for bone, _ in changed:
        per_kind[bone_kind(bone)] = per_kind.get(bone_kind(bone), 0) + 1
    return len(changed), per_kind, sorted({b for b, _ in changed})


def joint_names():
    """Names of the 26 deforming joints of :func:`part_joints`, in its order."""
    from sample_scenes.rig_footage import END_PARTS
    from sample_scenes.rig_specs import PARTS
    return list(PARTS) + [f"{p} tip" for p in END_PARTS]


#: Body regions of the error breakdown: the joints (:func:`joint_names`) whose part starts so.
REGIONS = (("trunk", ("hips", "spine", "chest", "neck")), ("head", ("head",)),
           ("arms", ("clavicle", "upper_arm", "forearm", "hand")), ("legs", ("thigh", "shin")),
           ("feet", ("foot", "toe")))


def region_of(joint):
    """The region (:data:`REGIONS`) of a joint name such as ``'toe.L tip'``."""
    part = joint.split(" ")[0].split(".")[0]
    return next(region for region, parts in REGIONS if part in parts)


def _joint_errors_cm(obj, spec, fp, frames):
    """Distance (cm) of each deforming joint of Blender's evaluation of ``obj`` to the truth:
    (len(frames), 26)."""
    from sample_scenes.rig_walk import read_truth
    got = read_truth(obj, spec, frames)
    rows = np.asarray(frames) - 1
    truth = part_joints(fp.heads[rows], fp.tails[rows], fp.names, fp.parts)
    mine = part_joints(got.heads, got.tails, got.names, got.parts)
    return 100 * np.linalg.norm(mine - truth, axis=-1)


def error_breakdown(errors, frames, keys):
    """Where the error is: per region, per joint and per frame (cm), the in-between frames'
    mean per region/joint and the keys' own error (should be ~0: the keys are the truth).

    ``errors``: (F, 26) of :func:`_joint_errors_cm` at ``frames`` (every frame of the clip).
    """
    frames = np.asarray(frames)
    at_keys = np.isin(frames, keys)
    inner = errors[~at_keys]
    names = joint_names()
    regions = {region: float(inner[:, [region_of(n) == region for n in names]].mean())
               for region, _ in REGIONS}
    return {"in_between_by_region_cm": regions,
            "in_between_by_joint_cm": {n: float(e) for n, e in zip(names, inner.mean(axis=0))},
            "per_frame_cm": [float(e) for e in errors.mean(axis=1)],
            "at_keys_cm": float(errors[at_keys].mean()),
            "at_keys_max_cm": float(errors[at_keys].max())}


def worker_track(kind, every, render, extension, keep_feet_planted=True):
    """One Track Keyframes run (module docstring); returns its result dict.
    ``keep_feet_planted``: the Track panel's *Keep Feet Planted* (on by default, as the
    panel's)."""
    import bpy

    from sample_scenes.rig_specs import RIG_SPECS
    _install(extension)
    spec = RIG_SPECS[kind]
    n = len(load_rig_footage(render, images=False).scene_frames)
    keys = list(range(1, n + 1, every))
    interior = [f for f in range(1, n + 1) if f not in keys]
    obj, fp = open_rig_scene(render, keys)
    bpy.context.scene.track_and_stride_track.processes = 1
    bpy.context.scene.track_and_stride_track.keep_feet_planted = bool(keep_feet_planted)
    controls = set(spec.controls) or set(spec.deform_bones)
    every_frame = list(range(1, n + 1))
    interpolated = _joint_errors_cm(obj, spec, fp, every_frame)
    out = {"keys": keys, "interpolation_cm": float(interpolated[np.asarray(interior) - 1].mean()),
           "interpolation_breakdown": error_breakdown(interpolated, every_frame, keys)}
    before = _key_state(obj)
    printed = []
    tic = time.perf_counter()
    with captured_output(printed):
        try:
            result = bpy.ops.track_and_stride.track_keyframes()
            error = None
        except RuntimeError as exc:
            result, error = {"CANCELLED"}, str(exc)
    out["seconds"] = time.perf_counter() - tic
    out["reports"] = _reports(printed[0])
    after = _key_state(obj)
    count, per_kind, bones = keys_on_unmapped(before, after, controls)
    out.update(keys_on_unmapped_bones=count, unmapped_by_kind=per_kind,
               unmapped_bones=bones[:40], unmapped_bones_total=len(bones),
               user_keys_bit_for_bit=user_keys_kept(before, after),
               fcurves_before=len(before), fcurves_after=len(after))
    if result == {"FINISHED"}:
        out["status"] = "tracked"
        tracked = _joint_errors_cm(obj, spec, fp, every_frame)
        out["tracker_cm"] = float(tracked[np.asarray(interior) - 1].mean())
        out["tracker_breakdown"] = error_breakdown(tracked, every_frame, keys)
        # The share of the tracked motion each body part kept per interval ('Tracked: <part>'
        # curves: 1 = the footage's, 0 = the keys' in-between).
        out["tracked_share"] = {path[len('["Tracked: '):-2]: [float(v) for v in st["co"][:, 1]]
                                for (path, _), st in after.items()
                                if path.startswith('["Tracked: ')}
        out["ratio"] = out["tracker_cm"] / out["interpolation_cm"]
    else:
        out["status"] = "refused"
        out["message"] = (error or "").strip()
        out["tracker_cm"] = None
    return out


def _rss_mb():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def worker_fit_body(kind, render, extension):
    """Fit Body to Footage at the render's size with its peak memory (module docstring)."""
    import resource
    import tracemalloc

    import bpy
    _install(extension)
    n = len(load_rig_footage(render, images=False).scene_frames)
    obj, fp = open_rig_scene(render, list(range(1, n + 1, FIT_KEYS_EVERY)))
    radii_before = np.array([[b.head_radius, b.tail_radius] for b in obj.data.bones])
    out = {"size": f"{fp.width}x{fp.height}", "keys_every": FIT_KEYS_EVERY}
    rss0 = _rss_mb()
    maxrss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    printed = []
    tracemalloc.start()
    tic = time.perf_counter()
    with captured_output(printed):
        try:
            result = bpy.ops.track_and_stride.fit_body_to_footage()
            error = None
        except RuntimeError as exc:
            result, error = {"CANCELLED"}, str(exc)
        except MemoryError as exc:
            result, error = {"CANCELLED"}, f"MemoryError: {exc}"
    out["seconds"] = time.perf_counter() - tic
    out["tracemalloc_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    maxrss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out["rss_before_mb"] = rss0
    out["rss_peak_growth_mb"] = max(0.0, maxrss1 - rss0) if maxrss1 > maxrss0 else None
    out["reports"] = _reports(printed[0])
    radii_after = np.array([[b.head_radius, b.tail_radius] for b in obj.data.bones])
    out["bones_changed"] = int(np.any(radii_after != radii_before, axis=1).sum())
    if result == {"FINISHED"}:
        out["status"] = "fitted"
    else:
        out["status"] = "out of memory" if "MemoryError" in (error or "") else "refused"
        out["message"] = (error or "").strip()[-600:]
    return out


def worker_main(args):
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="ts-bench-rigs-"))
    from benchmarks import rig_gait
    if args.worker == "track":
        result = worker_track(args.kind, args.every, args.render, args.extension,
                              not args.no_keep_feet_planted)
    elif args.worker == "gait_predict":
        result = rig_gait.worker_predict(args.kind, args.render, args.extension, args.mode,
                                         args.arrays)
    elif args.worker == "gait_round_trip":
        result = rig_gait.worker_round_trip(args.kind, args.render, args.extension, args.arrays,
                                            args.mode)
    elif args.worker == "gait_drive":
        result = rig_gait.worker_drive(args.kind, args.render, args.extension, args.cmu_arrays,
                                       args.arrays)
    else:
        result = worker_fit_body(args.kind, args.render, args.extension)
    Path(args.result).write_text(json.dumps(result, indent=1))
    return 0


# --------------------------------------------------------------------------------------------
# The benchmark (parent process)
# --------------------------------------------------------------------------------------------

def _limit_memory(gigabytes):
    def apply():
        import resource
        limit = int(gigabytes * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    return apply


def run_worker(kind, task, render, extension, timeout, memory_gb, every=None, extra=()):
    """Run one worker in a fresh process under the limits; its result dict (or why none)."""
    with tempfile.TemporaryDirectory(prefix="ts-bench-rigs-") as tmp:
        result_path = Path(tmp) / "result.json"
        cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", task, "--kind", kind,
               "--render", str(render), "--extension", str(extension), "--result",
               str(result_path)] + [str(x) for x in extra]
        if every is not None:
            cmd += ["--every", str(every)]
        env = dict(os.environ, BLENDER_USER_RESOURCES=str(Path(tmp) / "blender"))
        tic = time.perf_counter()
        try:
            proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                                  timeout=timeout, preexec_fn=_limit_memory(memory_gb))
        except subprocess.TimeoutExpired:
            return {"status": "timeout", "message": f"no result within {timeout:.0f} s",
                    "tracker_cm": None}
        if proc.returncode != 0 or not result_path.exists():
            tail = (proc.stdout[-1500:] + proc.stderr[-1500:]).strip()
            oom = "MemoryError" in tail or proc.returncode in (-9, 137)
            return {"status": "out of memory" if oom else "failed",
                    "message": f"exit {proc.returncode}: {tail[-800:]}", "tracker_cm": None,
                    "seconds": time.perf_counter() - tic}
        return json.loads(result_path.read_text())


def bench_gait(kind, args):
    """Issue 19's rows for one rig (``benchmarks/rig_gait.py``)."""
    from benchmarks import rig_gait

    def run(k, task, render, extra):
        return run_worker(k, task, render, args.extension, args.timeout, args.memory_limit_gb,
                          extra=extra)

    workdir = Path(args.output).parent / "rigs_gait"
    return rig_gait.bench_gait(kind, args.extension, run, workdir,
                               study=args.study_walk_template)


def _fmt(x, digits=1):
    return "—" if x is None else f"{x:.{digits}f}"


def table(results):
    """Markdown table of the results (docs/bench_rigs.md)."""
    lines = ["| rig | k10 tracker / interp. cm | k15 tracker / interp. cm | k20 tracker / "
             "interp. cm | keys on unmapped bones | user keys kept | Fit Body peak MB |",
             "|---|---|---|---|---|---|---|"]
    for kind, r in results["rigs"].items():
        cells = []
        for every in KEYS_EVERY:
            t = r["tracking"].get(f"keys_every_{every}", {})
            if t.get("status") == "tracked":
                cells.append(f"{_fmt(t['tracker_cm'])} / {_fmt(t['interpolation_cm'])}")
            else:
                cells.append(f"{t.get('status', '—')} / {_fmt(t.get('interpolation_cm'))}")
        fit = r.get("fit_body", {})
        peak = (_fmt(r.get("fit_body_peak_mb"), 0) if fit.get("status") == "fitted"
                else fit.get("status", "—"))
        kept = r.get("user_keys_bit_for_bit")
        lines.append(f"| {kind} | " + " | ".join(cells) +
                     f" | {r.get('keys_on_unmapped_bones', '—')} | "
                     f"{'yes' if kept else 'no' if kept is not None else '—'} | {peak} |")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--extension", required=True)
    parser.add_argument("--output", default=str(ROOT / "build" / "bench" / "rigs.json"))
    parser.add_argument("--rigs", default=",".join(RIGS), help="comma-separated rig kinds")
    parser.add_argument("--keys-every", default=",".join(map(str, KEYS_EVERY)))
    parser.add_argument("--no-fit-body", action="store_true")
    parser.add_argument("--no-tracking", action="store_true",
                        help="skip the tracking rows (keys every 10/15/20)")
    parser.add_argument("--no-gait", action="store_true", help="skip the gait rows (issue 19)")
    parser.add_argument("--no-keep-feet-planted", action="store_true",
                        help="track with Keep Feet Planted off (a study: on is the default)")
    parser.add_argument("--study-walk-template", action="store_true",
                        help="gait rows also read with the walk's own CMU template "
                             "(benchmarks/studies/rig_gait_template.py)")
    parser.add_argument("--timeout", type=float, default=1200.0,
                        help="seconds per worker (one tracking run, one fit)")
    parser.add_argument("--memory-limit-gb", type=float, default=6.0,
                        help="address-space limit of each worker")
    # Worker mode (internal).
    parser.add_argument("--worker", choices=("track", "fit_body", "gait_predict",
                                             "gait_round_trip", "gait_drive"))
    parser.add_argument("--kind")
    parser.add_argument("--every", type=int)
    parser.add_argument("--render")
    parser.add_argument("--result")
    parser.add_argument("--mode")
    parser.add_argument("--arrays")
    parser.add_argument("--cmu-arrays")
    args = parser.parse_args(argv)
    if args.worker:
        return worker_main(args)

    import bpy
    rigs = [r for r in args.rigs.split(",") if r]
    spacings = [] if args.no_tracking else [int(k) for k in args.keys_every.split(",") if k]
    results = {"machine": {"python": platform.python_version(), "bpy": bpy.app.version_string,
                           "cpu_count": os.cpu_count(), "numpy": np.__version__},
               "clip": {"motion": "CMU 35_01 walk", "frames": N_FRAMES, "fps": 30,
                        "track_size": "x".join(map(str, TRACK_SIZE)),
                        "fit_body_size": "x".join(map(str, FIT_SIZE)),
                        "keep_feet_planted": not args.no_keep_feet_planted},
               "timing_s": {}, "rigs": {}}
    for kind in rigs:
        row = {"tracking": {}}
        if not args.no_tracking:
            tic = time.perf_counter()
            render = ensure_rig_footage(kind, *TRACK_SIZE, frames=N_FRAMES,
                                        extension=args.extension)
            results["timing_s"][f"{kind}_footage"] = time.perf_counter() - tic
            fp = load_rig_footage(render, images=False)
            row.update(deforming_joints=int(part_joints(fp.heads[:1], fp.tails[:1], fp.names,
                                                        fp.parts).shape[1]),
                       drive_residual_deg=fp.drive_residual_deg,
                       drive_residual_cm=100 * fp.drive_residual_m, controls=len(fp.controls))
            print(f"{kind}: footage {render}", flush=True)
        else:
            print(f"{kind}:", flush=True)
        for every in spacings:
            t = run_worker(kind, "track", render, args.extension, args.timeout,
                           args.memory_limit_gb, every,
                           extra=["--no-keep-feet-planted"] * args.no_keep_feet_planted)
            row["tracking"][f"keys_every_{every}"] = t
            print(f"  keys every {every}: {t.get('status')} tracker {_fmt(t.get('tracker_cm'), 2)}"
                  f" cm, interpolation {_fmt(t.get('interpolation_cm'), 2)} cm, unmapped "
                  f"{t.get('keys_on_unmapped_bones')}, kept {t.get('user_keys_bit_for_bit')}"
                  f" ({_fmt(t.get('seconds'), 0)} s) {t.get('message', '')[:200]}", flush=True)
        runs = list(row["tracking"].values())
        counts = [t["keys_on_unmapped_bones"] for t in runs if "keys_on_unmapped_bones" in t]
        kept = [t["user_keys_bit_for_bit"] for t in runs if "user_keys_bit_for_bit" in t]
        row["keys_on_unmapped_bones"] = max(counts) if counts else None
        row["user_keys_bit_for_bit"] = all(kept) if kept else None
        if not args.no_fit_body and not args.no_tracking:
            tic = time.perf_counter()
            fit_render = ensure_rig_footage(kind, *FIT_SIZE, frames=N_FRAMES,
                                            extension=args.extension)
            results["timing_s"][f"{kind}_footage_{FIT_SIZE[0]}x{FIT_SIZE[1]}"] = (
                time.perf_counter() - tic)
            fit = run_worker(kind, "fit_body", fit_render, args.extension, args.timeout,
                             args.memory_limit_gb)
            row["fit_body"] = fit
            row["fit_body_peak_mb"] = fit.get("tracemalloc_peak_mb")
            print(f"  fit body {FIT_SIZE[0]}x{FIT_SIZE[1]}: {fit.get('status')} peak "
                  f"{_fmt(fit.get('tracemalloc_peak_mb'), 0)} MB {fit.get('message', '')[:200]}",
                  flush=True)
        # ---- Issue 19's rows (gait on the rig; track, then predict) ----
        if not args.no_gait:
            tic = time.perf_counter()
            row["gait"], row["track_then_predict"] = bench_gait(kind, args)
            results["timing_s"][f"{kind}_gait"] = time.perf_counter() - tic
            g, t = row["gait"], row["track_then_predict"]
            print(f"  gait: {g.get('status')} angle {_fmt(g.get('angle_diff_deg'), 2)}° root "
                  f"{_fmt(g.get('root_diff_cm'), 2)} cm round trip "
                  f"{_fmt(g.get('round_trip_deg'), 3)}° foot slide "
                  f"{_fmt(g.get('foot_slide_cm_s'), 3)} (CMU "
                  f"{_fmt(g.get('cmu_foot_slide_cm_s'), 3)}; every frame's lower foot "
                  f"{_fmt(g.get('foot_slide_lower_cm_s'), 3)}, CMU "
                  f"{_fmt(g.get('cmu_foot_slide_lower_cm_s'), 3)}) cm/s; tracked → predicted "
                  f"{_fmt(t.get('tracked_cm'), 1)} cm, true walk → "
                  f"{_fmt(t.get('true_walk_cm'), 1)} cm, keys only → "
                  f"{_fmt(t.get('keys_only_cm'), 1)} cm", flush=True)
        results["rigs"][kind] = row
        out = Path(args.output)
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(results, indent=2))
    print(table(results))
    if not args.no_gait:
        from benchmarks import rig_gait
        print(rig_gait.table(results))
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
