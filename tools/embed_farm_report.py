"""Copy ``farm/report.py`` into the OpenJD template's embedded file (the template's last block).

The job template ``farm/openjd/track_and_stride.yaml`` carries the report script verbatim so
that it is self-contained (one file to put in a job bundle). Run this after editing the
script; ``tests/blender/test_farm.py`` checks the two are the same::

    python tools/embed_farm_report.py
"""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "farm" / "report.py"
TEMPLATE = ROOT / "farm" / "openjd" / "track_and_stride.yaml"
MARKER = "      data: |\n"
INDENT = " " * 8


def embedded_template(template_text, script_text):
    """The template's text with everything after its last ``data: |`` line replaced by the
    script, indented into the YAML literal block."""
    if "{{" in script_text or "}}" in script_text:
        raise ValueError(f"{SCRIPT}: double braces would be read as the template's format-string "
                         "expressions: write them otherwise")
    head, found, _ = template_text.rpartition(MARKER)
    if not found:
        raise ValueError(f"{TEMPLATE}: no '{MARKER.strip()}' line to embed the script under")
    lines = [INDENT + line if line.strip() else "" for line in script_text.splitlines()]
    return head + MARKER + "\n".join(lines) + "\n"


def main():
    text = embedded_template(TEMPLATE.read_text(encoding="utf-8"),
                             SCRIPT.read_text(encoding="utf-8"))
    TEMPLATE.write_text(text, encoding="utf-8")
    print(f"embedded {SCRIPT.relative_to(ROOT)} into {TEMPLATE.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
