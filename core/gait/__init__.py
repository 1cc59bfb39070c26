"""Stylistic gait model (Matsubara, Hyon & Morimoto): learn from a few walkers, adapt to a new one
online, predict where the body goes next, retime and restyle. Pure NumPy.

Method and API: ``docs/gait.md``; equations by number: DESIGN.md §2.

Learning        :func:`learn_model` → :class:`GaitModel` (save/load/to_bytes/from_bytes)
Observations    :func:`observations_from_dofs`, :class:`ObservationStream`
Adaptation      :func:`adapt` (batch EM), :class:`OnlineEM` (online EM, ``step(y)``)
Prediction      :func:`predict`, :func:`predict_dofs`, :func:`mix_styles`,
                :func:`interpolate_styles`
Root travel     :func:`root_features`, :func:`integrate_root`, :class:`RootFrame`
Building blocks alignment, factorisation, MAP refinement, GP, EKF, grid initialisation, L-BFGS
"""

from .alignment import AlignmentResult, align_sequences, cycle_profile, estimate_period, \
    phase_shift
from .factorization import choose_n_styles, factorize
from .gp import PhaseGP, build_phase_gp, fit_phase_gp
from .map_refinement import MapResult, map_objective, refine_map
from .optimize import minimize_lbfgs

__all__ = [
    "AlignmentResult",
    "MapResult",
    "PhaseGP",
    "align_sequences",
    "build_phase_gp",
    "choose_n_styles",
    "cycle_profile",
    "estimate_period",
    "factorize",
    "fit_phase_gp",
    "map_objective",
    "minimize_lbfgs",
    "phase_shift",
    "refine_map",
]
