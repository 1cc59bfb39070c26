# Track & Stride — two commands on a fresh machine (Python 3.11 + make):
#   make demo    the main job end to end (imports CMU mocap, writes build/demo/)
#   make test    the whole test suite (core tests + headless Blender tests)
# Each target creates the virtualenv with the pinned dependencies when it is missing.
#
# Blender 4.5 LTS: `make test BPY=4.5.15` runs the same suite against bpy 4.5 in its own venv.

PYTHON ?= python3.11
BPY ?= 5.0.1
ifeq ($(BPY),5.0.1)
VENV ?= .venv
else
VENV ?= .venv-bpy$(BPY)
endif
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-$(BPY)
VERSION := $(shell sed -n 's/^version = "\(.*\)"/\1/p' blender_manifest.toml)
ZIP := build/track_and_stride-$(VERSION).zip
PYTEST_ARGS ?=

.PHONY: venv demo test test-core test-blender extension bench bench-import bench-gait bench-gait-blender bench-tracking bench-track-blender stock-gaits clean

venv: $(STAMP)

$(STAMP): requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check bpy==$(BPY) -r requirements.txt
	touch $(STAMP)

extension: $(STAMP)
	$(PY) tools/build_extension.py --output $(ZIP)

demo: extension
	$(PY) sample_scenes/demo.py --extension $(ZIP) --output build/demo

test: extension
	$(PY) -m pytest $(PYTEST_ARGS) tests

test-core: $(STAMP)
	$(PY) -m pytest $(PYTEST_ARGS) tests/core

test-blender: extension
	$(PY) -m pytest $(PYTEST_ARGS) tests/blender

bench: bench-import bench-gait bench-gait-blender bench-tracking bench-track-blender

bench-import: extension
	$(PY) benchmarks/bench_import.py --extension $(ZIP) --output build/bench/import.json

bench-gait: $(STAMP)
	$(PY) benchmarks/bench_gait.py --output build/bench/gait.json

# Rebuild the stock gait library shipped in core/gait/data (about 10 s; docs/gait.md).
stock-gaits: $(STAMP)
	$(PY) tools/build_stock_gaits.py --output core/gait/data/stock_gaits.npz

bench-gait-blender: extension
	$(PY) benchmarks/bench_gait_blender.py --extension $(ZIP) --output build/bench/gait_blender.json

# Renders its footage once (cached under build/footage), then accuracy, speed, throughput.
bench-tracking: $(STAMP)
	$(PY) benchmarks/bench_tracking.py --output build/bench/tracking.json

# Track Keyframes through the installed extension: serial vs parallel, phases, accuracy.
bench-track-blender: extension
	$(PY) benchmarks/bench_track_blender.py --extension $(ZIP) --output build/bench/track_blender.json

clean:
	rm -rf build .pytest_cache
