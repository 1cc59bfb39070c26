// SPDX-License-Identifier: GPL-3.0-or-later
//
// Track & Stride on a Flamenco 3 render farm: a custom job type. Put this file in the
// `scripts/` folder beside the flamenco-manager executable (job type "track-and-stride"),
// and farm/report.py where every worker can read it (the `report_script` setting).
//
// The same job as farm/openjd/track_and_stride.yaml, with the same command lines: one task
// per shot, each running the extension's own command line
//   blender --background --command track_and_stride <step> INPUT ... --output OUT --summary JSON
// and a report task that gathers every summary into OUT/report.csv and OUT/report.html.
// Outputs in output_dir, for an input /any/where/NAME.ext: NAME.import-acclaim.blend/.json,
// NAME.predict.blend/.json, NAME.track.blend/.json (names must be unique within a list).
// A shot's task fails when its command exits non-zero (1: refused or failed, nothing saved;
// the summary's message says why); the other shots' tasks go on. Each predict task waits only
// for the import of its own motion; the report waits for every task.
// tests/blender/test_farm.py runs compileJob() with Node against a recording `author` and
// checks that the command lines equal the ones `openjd run` ran. docs/pipeline.md: submitting.

const JOB_TYPE = {
  label: "Track & Stride shot list",
  description: "Import Acclaim motions and predict their walks on, track shots through their " +
               "footage: one task per shot, and a report of every shot at the end",
  settings: [
    { key: "blender", type: "string", default: "{blender}",
      description: "The Blender executable on the workers (4.5 LTS or newer) with the " +
                   "Track & Stride extension installed and enabled for the worker's user" },
    { key: "track_shots", type: "string", default: "",
      description: "Shots to track: absolute paths of .blend files, one per line (or " +
                   "separated by ';'), each an armature posed at a few keyframes over its " +
                   "footage, set up in the Track panel. One task per shot" },
    { key: "motions", type: "string", default: "",
      description: "Acclaim motions (.amc, absolute paths; the .asf beside each), one per " +
                   "line (or separated by ';'), to import and continue with Predict Gait" },
    { key: "output_dir", type: "string", subtype: "dir_path", required: true,
      description: "The folder that receives every output, summary and the report " +
                   "(created when missing)" },
    { key: "report_script", type: "string", subtype: "file_path", required: true,
      description: "farm/report.py of Track & Stride, where every worker can read it" },
    { key: "processes", type: "int32", default: 0,
      description: "Worker processes per track task (0 = one per CPU of the worker)" },
    { key: "import_fps", type: "float", default: 24,
      description: "Frames per second of the imported scene" },
    { key: "predict_model", type: "string", default: "Stock Gaits",
      description: "The gait model: 'Stock Gaits' (built in) or a model file (.npz) every " +
                   "worker can read" },
    { key: "predict_length", type: "float", default: 2,
      description: "Seconds of walk to predict after each imported motion" },
  ],
};

const COMMAND_ID = "track_and_stride";

function compileJob(job) {
  const s = job.settings;
  const out = s.output_dir;
  const tracks = pathList(s.track_shots);
  const motions = pathList(s.motions);
  checkUniqueNames("track_shots", tracks);
  checkUniqueNames("motions", motions);

  // The command line saves only into an existing folder: make it first (as the OpenJD
  // template's job environment does, with the same command).
  const folder = blenderTask(s, "make output folder", [
    "--background", "--factory-startup", "--python-exit-code", "1", "--python-expr",
    "import os, sys; os.makedirs(sys.argv[-1], exist_ok=True)", "--", out]);
  const all = [];

  for (const motion of motions) {
    const name = stem(motion);
    const imported = blenderTask(s, `import-acclaim ${name}`, trackAndStride(
      "import-acclaim", motion,
      ["--fps", number(s.import_fps)], outputs(out, name, "import-acclaim")), [folder]);
    const predicted = blenderTask(s, `predict ${name}`, trackAndStride(
      "predict", join(out, `${name}.import-acclaim.blend`),
      ["--model", s.predict_model, "--length", number(s.predict_length)],
      outputs(out, name, "predict")), [imported]);
    all.push(imported, predicted);
  }
  for (const shot of tracks) {
    const name = stem(shot);
    all.push(blenderTask(s, `track ${name}`, trackAndStride(
      "track", shot, ["--processes", String(s.processes)], outputs(out, name, "track")),
      [folder]));
  }
  blenderTask(s, "report", [
    "--background", "--factory-startup", "--python-exit-code", "1", "--python",
    s.report_script, "--", "--output-dir", out, "--track", ...tracks, "--motions",
    ...motions, "--title", job.name || JOB_TYPE.label], all.length ? all : [folder]);

  function blenderTask(settings, name, args, dependsOn) {
    const task = author.Task(name, "blender");
    task.addCommand(author.Command("exec", { exe: settings.blender, args: args }));
    for (const other of dependsOn || []) task.addDependency(other);
    job.addTask(task);
    return task;
  }
}

// `blender --background --command track_and_stride <step> INPUT [options] --output --summary`
function trackAndStride(step, input, options, output) {
  return ["--background", "--command", COMMAND_ID, step, input, ...options, ...output];
}

function outputs(folder, name, step) {
  return ["--output", join(folder, `${name}.${step}.blend`),
          "--summary", join(folder, `${name}.${step}.json`)];
}

// Paths one per line or separated by ';', blanks dropped.
function pathList(text) {
  return String(text || "").split(/[\n;]/).map((p) => p.trim()).filter((p) => p.length > 0);
}

// The file name without its extension (either slash separates folders).
function stem(path) {
  const base = path.split(/[\\/]/).pop();
  const dot = base.lastIndexOf(".");
  return dot > 0 ? base.slice(0, dot) : base;
}

function join(folder, name) {
  const sep = folder.includes("\\") && !folder.includes("/") ? "\\" : "/";
  return folder.replace(/[\\/]+$/, "") + sep + name;
}

// Numbers as the OpenJD template writes them: integers without a decimal point.
function number(value) {
  return String(Number(value));
}

function checkUniqueNames(setting, paths) {
  const seen = {};
  for (const p of paths) {
    const name = stem(p);
    if (seen[name]) {
      throw `${setting}: ${seen[name]} and ${p} share the name '${name}': their outputs ` +
            "would overwrite each other; give every shot a file name of its own";
    }
    seen[name] = p;
  }
}
