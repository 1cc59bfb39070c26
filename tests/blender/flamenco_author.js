// Run a Flamenco 3 job type's compileJob() outside a Flamenco Manager, against a stand-in of
// the Manager's `author` API that records what the script creates (tests/blender/test_farm.py).
//
//   node flamenco_author.js JOB_TYPE.js JOB.json
//
// JOB.json: {"name": ..., "settings": {...}}. Settings left out take the JOB_TYPE's defaults
// (as the Blender add-on fills them in before submitting). Prints one JSON object on stdout:
// {"label", "settings": [keys], "tasks": [{"name", "type", "commands": [{"name",
// "parameters"}], "dependencies": [task names]}]}. A script that throws (as compileJob does to
// refuse a job) prints the error on stderr and exits 1.
"use strict";

const fs = require("fs");
const vm = require("vm");

function main(argv) {
  const [jobTypePath, jobPath] = argv;
  const submitted = JSON.parse(fs.readFileSync(jobPath, "utf8"));
  const tasks = [];

  function Task(name, type) {
    const task = {
      name: name, type: type, commands: [], dependencies: [],
      addCommand(command) { this.commands.push(command); },
      addDependency(other) {
        if (!tasks.includes(other)) throw new Error(`${name}: depends on a task not in the job`);
        this.dependencies.push(other.name);
      },
    };
    return task;
  }
  function Command(name, parameters) {
    return { name: name, parameters: parameters };
  }

  const sandbox = vm.createContext({ author: { Task, Command }, print: console.error });
  vm.runInContext(fs.readFileSync(jobTypePath, "utf8") +
                  "\n;globalThis.__jobType = JOB_TYPE; globalThis.__compileJob = compileJob;",
                  sandbox, { filename: jobTypePath });
  const jobType = sandbox.__jobType;
  const settings = {};
  for (const s of jobType.settings) {
    if (s.default !== undefined) settings[s.key] = s.default;
  }
  Object.assign(settings, submitted.settings || {});
  for (const s of jobType.settings) {
    if (s.required && (settings[s.key] === undefined || settings[s.key] === "")) {
      throw new Error(`setting ${s.key} is required`);
    }
  }
  const job = {
    name: submitted.name, settings: settings, metadata: {},
    addTask(task) { tasks.push(task); },
  };
  sandbox.__compileJob(job);
  const recorded = tasks.map((t) => ({
    name: t.name, type: t.type, commands: t.commands, dependencies: t.dependencies,
  }));
  process.stdout.write(JSON.stringify({
    label: jobType.label, settings: jobType.settings.map((s) => s.key), tasks: recorded,
  }) + "\n");
}

try {
  main(process.argv.slice(2));
} catch (err) {
  process.stderr.write(`${err && err.stack ? err.stack : err}\n`);
  process.exit(1);
}
