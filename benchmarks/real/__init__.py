"""The real-footage benchmark's parts (``benchmarks/bench_real.py``, ``docs/bench_real.md``).

Benchmark code only: never imported by ``core/`` or ``addon/``. ``reference`` (triangulation),
``rig`` (the armature fitted to the reference) and ``score`` need NumPy and OpenCV;
``detect`` needs MediaPipe (the ``.venv-bench`` environment); ``blender_stage`` runs under
the test environment's ``bpy``.
"""
