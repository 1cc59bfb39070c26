"""Track & Stride core: pure NumPy (no bpy, no SciPy, no mathutils).

Plain-array interfaces only; conventions (frames, Euler orders, units, frame rates) are written
once in ``docs/conventions.md``. Subpackages:

``kinematics``  rotations, articulated skeletons, batched forward kinematics
``mocap``       Acclaim ASF/AMC reading and writing, frame-rate resampling
``armature``    core skeleton <-> Blender-style armature (bone Y along head->tail) layout
``gait``        stylistic gait model: learning, adaptation (EKF/EM), prediction (docs/gait.md)
``tracking``    drift-corrected video tracking (Yamamoto; docs/tracking.md)
"""

__all__ = ["kinematics", "mocap", "armature", "gait", "tracking"]
