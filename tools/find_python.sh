#!/bin/sh
# Print the path of a working Python interpreter of version $1 (e.g. 3.13), or fail with a
# message that says how to get one.  Used by the Makefile to create the virtualenv of a
# Blender version (each bpy release supports exactly one Python).
#
# Tried in order:
#   1. `python<version>` on PATH, if it really runs (a pyenv shim for a version that is
#      installed but not active exists on PATH yet fails);
#   2. pyenv: the newest installed `<version>.*` under `pyenv root`;
#   3. uv: `uv python find <version>`.
set -u
want="${1:?usage: find_python.sh <major.minor>}"

works() {  # works <interpreter>: it runs and is the wanted major.minor
    [ -n "$1" ] && "$1" -c "import sys; sys.exit(0 if '%d.%d' % sys.version_info[:2] == '$want' else 1)" \
        >/dev/null 2>&1
}

candidate="$(command -v "python$want" 2>/dev/null || true)"
if works "$candidate"; then
    echo "$candidate"
    exit 0
fi

if command -v pyenv >/dev/null 2>&1; then
    root="$(pyenv root 2>/dev/null || true)"
    version="$(pyenv versions --bare 2>/dev/null | grep -E "^$want\.[0-9]+$" | sort -t. -k3,3n | tail -n 1)"
    candidate="$root/versions/$version/bin/python$want"
    if [ -n "$version" ] && works "$candidate"; then
        echo "$candidate"
        exit 0
    fi
fi

if command -v uv >/dev/null 2>&1; then
    candidate="$(uv python find "$want" 2>/dev/null || true)"
    if works "$candidate"; then
        echo "$candidate"
        exit 0
    fi
fi

echo "error: Python $want is needed (bpy of this Blender version supports no other) but none was" \
     "found: no working python$want on PATH, none installed by pyenv or uv." \
     "Install it (e.g. \`pyenv install $want\`) or pass PYTHON=/path/to/python$want." >&2
exit 1
