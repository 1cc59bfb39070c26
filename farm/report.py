"""Gather the per-shot JSON summaries of a Track & Stride farm job into one report.

Run by the job's last step, with Blender's own Python (nothing but the standard library)::

    blender --background --factory-startup --python-exit-code 1 --python report.py -- \
        --output-dir OUT --track SHOT.blend ... --motions MOTION.amc ...

(or any Python 3.11+: ``python report.py --output-dir OUT ...``). Every task of the job wrote
``OUT/<name>.<step>.json`` (the command line's ``--summary``) beside its output
``OUT/<name>.<step>.blend``, where ``<name>`` is the input's file name without its extension;
this script reads them for the shots and motions the job was given, in their order, and writes

* ``OUT/report.csv``: one row per task: ``shot``, ``step``, ``status`` (the summary's: ok,
  warning, failed, bad_arguments, error; ``missing`` when the task wrote no summary: it has not
  run, or Blender stopped before the end -- see the task's log), ``exit_code``,
  ``intervals_tracked`` (track: intervals whose keys follow the footage / all), ``share_tracked``
  (track: the share of the tracked motion kept, over body parts and intervals weighted by their
  length in frames; 1 = every part follows the footage everywhere, 0 = the keys' in-between
  everywhere), ``warnings`` (how many), ``warning_lines`` (the summary's plain lines: one per
  interval where a body part kept the keys' in-between), ``seconds`` (the task's time),
  ``message``, ``output`` (the saved .blend; empty when nothing was saved) and ``summary``;
* ``OUT/report.html``: the same as a small table, one colour per status;

and prints one line per task (the task log) and an ``openjd_status:`` line with the counts.
Exit status 0 once both files are written, whatever the shots' status (the shots' own tasks
carry that); 1 when they cannot be written.

This file is the single source of the report: ``farm/openjd/track_and_stride.yaml`` embeds it
verbatim (a test checks that), and a Flamenco manager runs it from the shared storage.
"""

import argparse
import csv
import html
import json
import sys
from pathlib import Path

STEPS = ("import-acclaim", "predict", "track")
COLUMNS = ("shot", "step", "status", "exit_code", "intervals_tracked", "share_tracked",
           "warnings", "warning_lines", "seconds", "message", "output", "summary")
#: The page's style sheet (no double braces anywhere in this file: the OpenJD template that
#: embeds it would read them as its own format-string expressions).
STYLE = ("body { font-family: sans-serif } table { border-collapse: collapse } "
         "td, th { border: 1px solid #999; padding: 3px 6px; vertical-align: top; "
         "text-align: left }")
COLOURS = {"ok": "#d7f0d2", "warning": "#fbefc4", "failed": "#f6d0cb",
           "bad_arguments": "#f6d0cb", "error": "#e9b5ae", "missing": "#dddddd"}


def shot_name(path):
    """The name outputs are saved under: the file name without its extension."""
    return Path(path).stem


def share_tracked(intervals):
    """Share of the tracked motion kept over a track run (0..1; None without intervals).

    Each interval weighs its length in frames; within an interval, the body parts' mean
    ``share_tracked`` (an interval without part verdicts counts 1 when 'tracked', else 0).
    """
    total = weight = 0.0
    for interval in intervals:
        first, last = interval["frames"]
        parts = interval.get("parts") or {}
        if parts:
            share = sum(p.get("share_tracked", 1.0 if p.get("result") == "tracked" else 0.0)
                        for p in parts.values()) / len(parts)
        else:
            share = 1.0 if interval.get("status") == "tracked" else 0.0
        total += (last - first) * share
        weight += last - first
    return round(total / weight, 3) if weight > 0 else None


def row_of(name, step, summary_path):
    """One report row from a task's summary file (status 'missing' when there is none)."""
    row = dict.fromkeys(COLUMNS, "")
    row.update(shot=name, step=step, summary=str(summary_path))
    try:
        summary = json.loads(Path(summary_path).read_text(encoding="utf-8").splitlines()[-1])
    except (OSError, ValueError, IndexError) as exc:
        missing = isinstance(exc, FileNotFoundError)
        row.update(status="missing", message="No summary: the task has not run, or Blender "
                   "stopped before the end (see the task's log)" if missing else
                   f"Unreadable summary: {exc}")
        return row
    warnings = summary.get("warnings") or []
    row.update(status=summary.get("status", ""), exit_code=summary.get("exit_code", ""),
               warnings=len(warnings), warning_lines="\n".join(warnings),
               seconds=summary.get("seconds_total", ""), message=summary.get("message", ""),
               output=summary.get("output", "") if summary.get("saved") else "")
    intervals = summary.get("intervals")
    if step == "track" and intervals:
        tracked = sum(1 for i in intervals if i.get("status") == "tracked")
        row.update(intervals_tracked=f"{tracked}/{len(intervals)}",
                   share_tracked=share_tracked(intervals))
    return row


def gather(output_dir, track, motions):
    """Rows of the report: every motion's import-acclaim and predict, every shot's track."""
    jobs = [(m, step) for m in motions for step in ("import-acclaim", "predict")]
    jobs += [(s, "track") for s in track]
    rows = []
    for path, step in jobs:
        name = shot_name(path)
        rows.append(row_of(name, step, Path(output_dir) / f"{name}.{step}.json"))
    return rows


def duplicates(paths):
    """Names that two inputs of one list share (their outputs overwrite each other)."""
    names = [shot_name(p) for p in paths]
    return sorted({n for n in names if names.count(n) > 1})


def write_csv(rows, path):
    with open(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows(rows)


def write_html(rows, path, title, problems):
    """A small self-contained HTML table of the rows."""
    def cell(row, key):
        text = html.escape(str(row[key]))
        return text.replace("\n", "<br>") if key == "warning_lines" else text
    shown = [c for c in COLUMNS if c not in ("summary",)]
    head = "".join(f"<th>{html.escape(c.replace('_', ' '))}</th>" for c in shown)
    body = "\n".join(
        f'<tr class="{html.escape(r["status"])}" style="background:'
        f'{COLOURS.get(r["status"], "#ffffff")}">'
        + "".join(f"<td>{cell(r, c)}</td>" for c in shown) + "</tr>" for r in rows)
    notes = "".join(f"<p><strong>{html.escape(p)}</strong></p>" for p in problems)
    counts = ", ".join(f"{n} {s}" for s, n in status_counts(rows).items())
    Path(path).write_text(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
        f"<title>{html.escape(title)}</title>\n<style>{STYLE}</style></head>\n<body>"
        f"<h1>{html.escape(title)}</h1>\n<p>{html.escape(counts)}</p>{notes}\n"
        f"<table>\n<tr>{head}</tr>\n{body}\n</table>\n</body></html>\n", encoding="utf-8")


def status_counts(rows):
    counts = {}
    for row in rows:
        counts[row["status"]] = counts.get(row["status"], 0) + 1
    return counts


def parse_args(argv):
    if "--" in argv:                     # run by Blender: the script's arguments follow '--'
        argv = argv[argv.index("--") + 1:]
    parser = argparse.ArgumentParser(prog="report.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--output-dir", required=True, help="the job's output folder")
    parser.add_argument("--track", nargs="*", default=[], metavar="SHOT.blend",
                        help="the shots of the track step, in the job's order")
    parser.add_argument("--motions", nargs="*", default=[], metavar="MOTION.amc",
                        help="the motions of the import-acclaim and predict steps")
    parser.add_argument("--title", default="Track & Stride farm report")
    return parser.parse_args(argv)


def main(argv):
    args = parse_args(argv)
    out = Path(args.output_dir)
    rows = gather(out, args.track, args.motions)
    problems = [f"Two inputs share the name {name!r}: their outputs and summaries overwrite "
                "each other; give every shot a file name of its own"
                for name in duplicates(args.track) + duplicates(args.motions)]
    try:
        write_csv(rows, out / "report.csv")
        write_html(rows, out / "report.html", args.title, problems)
    except OSError as exc:
        print(f"Cannot write the report into {out}: {exc}", file=sys.stderr)
        return 1
    for row in rows:
        print(f"{row['step']:>14}  {row['shot']:<24} {row['status']:<13} "
              f"{row['share_tracked'] if row['share_tracked'] != '' else '':>5}  "
              f"{row['message']}")
    for problem in problems:
        print(problem)
    counts = ", ".join(f"{n} {s}" for s, n in status_counts(rows).items())
    print(f"openjd_status: {counts or 'no tasks'}")
    print(f"Report: {out / 'report.csv'} and {out / 'report.html'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
