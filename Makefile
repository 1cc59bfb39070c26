# Track & Stride — two commands on a fresh machine (make + Python 3.13; 3.11 for Blender 4.5/5.0):
#   make demo    the main job end to end (imports CMU mocap, writes build/demo/)
#   make test    the whole test suite (core tests + headless Blender tests)
# Each target creates the virtualenv with the pinned dependencies when it is missing.
#
# Supported Blender: 4.5 LTS, 5.0 and 5.2. The default is the newest release (bpy 5.2.3, Python
# 3.13, NumPy 2), in .venv; `make test BPY=4.5.15` (or BPY=5.0.1) runs the same suite against
# that bpy (Python 3.11, NumPy 1.26) in its own .venv-bpy<version>. Each bpy release supports
# exactly one Python; tools/find_python.sh finds it (PATH, then pyenv, then uv) unless
# PYTHON=/path/to/pythonX.Y is given. requirements.txt pins per Python (environment markers).

SUPPORTED_BPY := 4.5.15 5.0.1 5.2.3
BPY ?= 5.2.3
ifneq ($(filter 4.5.% 5.0.%,$(BPY)),)
PYTHON_VERSION := 3.11
else ifneq ($(filter 5.1.% 5.2.%,$(BPY)),)
PYTHON_VERSION := 3.13
else
$(error BPY=$(BPY) is not a supported Blender (supported: $(SUPPORTED_BPY)))
endif
PYTHON ?=
ifeq ($(BPY),5.2.3)
VENV ?= .venv
else
VENV ?= .venv-bpy$(BPY)
endif
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-$(BPY)
VERSION := $(shell sed -n 's/^version = "\(.*\)"/\1/p' blender_manifest.toml)
ZIP := build/track_and_stride-$(VERSION).zip
PYTEST_ARGS ?=

.PHONY: venv demo test test-core test-blender extension bench bench-import bench-gait bench-gait-blender bench-tracking bench-track-blender bench-real bench-rigs bench-memory mutate test-portability stock-gaits check-stock-gaits clean

venv: $(STAMP)

# A venv of another Python or bpy (e.g. .venv made for an earlier default) is recreated.
$(STAMP): requirements.txt
	@interpreter="$(PYTHON)"; \
	if [ -z "$$interpreter" ]; then interpreter="$$(sh tools/find_python.sh $(PYTHON_VERSION))" || exit 1; fi; \
	echo "$(VENV): bpy $(BPY) on $$interpreter"; \
	"$$interpreter" -m venv --clear $(VENV)
	$(PY) -m pip install --quiet --disable-pip-version-check bpy==$(BPY) -r requirements.txt
	touch $(STAMP)

extension: $(STAMP)
	$(PY) tools/build_extension.py --output $(ZIP)

demo: extension
	$(PY) sample_scenes/demo.py --extension $(ZIP) --output build/demo

# One BLAS thread: on a loaded machine OpenBLAS's threads wait for cores other processes hold
# (a test tracking in-process took 127 s with the default threads and 40 s with one,
# docs/tracking.md, *Robust estimation: its cost*); the tracker's pool workers do the same.
TEST_ENV := OPENBLAS_NUM_THREADS=1

test: extension
	$(TEST_ENV) $(PY) -m pytest $(PYTEST_ARGS) tests

test-core: $(STAMP)
	$(TEST_ENV) $(PY) -m pytest $(PYTEST_ARGS) tests/core

test-blender: extension
	$(TEST_ENV) $(PY) -m pytest $(PYTEST_ARGS) tests/blender

bench: bench-import bench-gait bench-gait-blender bench-tracking bench-track-blender

bench-import: extension
	$(PY) benchmarks/bench_import.py --extension $(ZIP) --output build/bench/import.json

# ONLY=restyle (or offline,online,lowo,restyle,acceptance,acceptance_rig): a quick run of some
# parts while iterating (acceptance_rig: the acceptance table read through a rig too, ~5 min).
# Runs under the CPU pin of tools/cpu_pin.py (x86-64-v3: the same figures on every CPU with
# AVX2/FMA; its speed block on this CPU's own kernels); PIN=none: all on this CPU's own kernels.
bench-gait: $(STAMP)
	$(PY) benchmarks/bench_gait.py --output build/bench/gait.json $(if $(ONLY),--only $(ONLY)) $(if $(PIN),--pin $(PIN))

# Rebuild the stock gait library shipped in core/gait/data (1-2 min; under the CPU pin of
# tools/cpu_pin.py: the same file, bit for bit, on every CPU with AVX2/FMA: docs/gait.md).
stock-gaits: $(STAMP)
	$(PY) tools/build_stock_gaits.py --output core/gait/data/stock_gaits.npz

# Rebuild it into build/ and compare with the shipped file (fails naming the first byte that
# differs).
check-stock-gaits: $(STAMP)
	$(PY) tools/build_stock_gaits.py --output build/stock_gaits_check.npz
	cmp build/stock_gaits_check.npz core/gait/data/stock_gaits.npz && \
	echo "build/stock_gaits_check.npz: the shipped stock library, bit for bit"

bench-gait-blender: extension
	$(PY) benchmarks/bench_gait_blender.py --extension $(ZIP) --output build/bench/gait_blender.json

# Renders its footage once (cached under build/footage), then accuracy, speed, throughput.
bench-tracking: $(STAMP)
	$(PY) benchmarks/bench_tracking.py --output build/bench/tracking.json

# Track Keyframes through the installed extension: serial vs parallel, phases, accuracy.
bench-track-blender: extension
	$(PY) benchmarks/bench_track_blender.py --extension $(ZIP) --output build/bench/track_blender.json

# Rigs animators animate (docs/bench_rigs.md): test rigs built from Blender's bundled data
# (CMU import, metarig, Rigify FK/IK, Mixamo through the FBX exporter and importer, IK legs),
# the same walk keyed on each, rendered once (cached under build/rigs and build/rig_footage),
# Track Keyframes and Fit Body through the installed extension, each run in a fresh process.
bench-rigs: extension
	$(PY) benchmarks/bench_rigs.py --extension $(ZIP) --output build/bench/rigs.json

# Real footage (docs/bench_real.md): MediaPipe reference over the Pose2Sim demo's 4 cameras,
# Track Keyframes through the operator per camera; its own venv (MediaPipe, never in .venv).
BENCH_VENV := .venv-bench
BENCH_STAMP := $(BENCH_VENV)/.installed

# MediaPipe 0.10.21 has wheels for Python 3.11 (whatever Blender the tests use).
$(BENCH_STAMP): requirements-bench.txt
	@interpreter="$$(sh tools/find_python.sh 3.11)" || exit 1; "$$interpreter" -m venv --clear $(BENCH_VENV)
	$(BENCH_VENV)/bin/python -m pip install --quiet --disable-pip-version-check --no-deps -r requirements-bench.txt
	touch $(BENCH_STAMP)

bench-real: extension $(BENCH_STAMP)
	$(BENCH_VENV)/bin/python benchmarks/bench_real.py --extension $(ZIP) --blender-python $(PY) --output build/bench/real.json

# Peak memory of Track and Fit Body at 1920x1080 on the largest rig (docs/testing.md).
bench-memory: $(STAMP)
	$(PY) benchmarks/bench_memory.py --output build/bench/memory.json

# Mutation testing of six core modules, each against its own tests (docs/testing.md); mutmut
# in its own venv (.venv-mutate), never in .venv or the extension. MUTATE_ARGS="--only ekf".
MUTATE_VENV := .venv-mutate
MUTATE_STAMP := $(MUTATE_VENV)/.installed
MUTATE_ARGS ?=

$(MUTATE_STAMP): requirements-mutate.txt requirements.txt
	@interpreter="$$(sh tools/find_python.sh 3.13)" || exit 1; "$$interpreter" -m venv --clear $(MUTATE_VENV)
	$(MUTATE_VENV)/bin/python -m pip install --quiet --disable-pip-version-check -r requirements-mutate.txt
	touch $(MUTATE_STAMP)

mutate: $(MUTATE_STAMP)
	$(MUTATE_VENV)/bin/python tools/mutate.py $(MUTATE_ARGS)

# The core tests on other CPU paths (docs/testing.md): NumPy's SIMD dispatch off, OpenBLAS's
# oldest x86-64 kernels, one thread -- exact comparisons that hold only by luck fail here.
# The core tests under the x86-64-baseline pin of tools/cpu_pin.py: every SIMD feature NumPy
# dispatches off (AVX-512 included), OpenBLAS's oldest kernels, libm's FMA variants off.
test-portability: $(STAMP)
	$(PY) tools/cpu_pin.py --pin x86-64-baseline $(PY) -m pytest $(PYTEST_ARGS) tests/core

clean:
	rm -rf build .pytest_cache
