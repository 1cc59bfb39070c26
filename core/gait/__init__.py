"""Stylistic gait model (Matsubara, Hyon & Morimoto): learn from a few walkers, adapt to a new one
online, predict where the body goes next, retime and restyle. Pure NumPy.

Method and API: ``docs/gait.md``; equations by number: DESIGN.md §2.

Learning        :func:`learn_model` → :class:`GaitModel` (save/load/to_bytes/from_bytes)
Observations    :func:`observations_from_dofs`, :class:`ObservationStream`
Adaptation      :func:`adapt` (batch EM), :class:`OnlineEM` (online EM, ``step(y)``)
Prediction      :func:`predict`, :func:`predict_dofs`, :func:`mix_styles`,
                :func:`interpolate_styles`
Root travel     :func:`root_features`, :func:`integrate_root`, :class:`RootFrame`,
                :func:`foot_slide` (stance-foot sliding metric)
Live preview    :class:`LookaheadPredictor` (online EM kept in step with the timeline)
Stock library   :func:`load_stock_library` (named styles, shipped; :func:`restyle`)
Long captures   :func:`steady_segments` (what learning keeps of a trial with stops and turns)
Building blocks alignment, factorisation, MAP refinement, GP, EKF, grid initialisation, L-BFGS
"""

from .alignment import AlignmentResult, align_sequences, cycle_profile, estimate_period, \
    phase_shift
from .ekf import FilterContext, ekf_filter, ekf_predict, ekf_update, make_context, \
    observation_jacobian
from .em import AdaptResult, adapt, m_step
from .factorization import choose_n_styles, factorize
from .features import ObservationStream, observations_from_dofs
from .foot_slide import foot_slide, stance_speeds
from .gp import PhaseGP, build_phase_gp, fit_phase_gp
from .initial_phase import GridResult, grid_search
from .learning import learn_model
from .lookahead import LookaheadPredictor
from .map_refinement import MapResult, map_objective, refine_map
from .model import FORMAT_VERSION, GaitModel, GaitModelFileError
from .online import OnlineConfig, OnlineEM, OnlineState, online_forecast, online_init, \
    online_step
from .optimize import minimize_lbfgs
from .prediction import interpolate_styles, mix_styles, predict, predict_dofs, restyle
from .root_travel import ROOT_DOF_NAMES, ROOT_FEATURE_NAMES, RootFrame, integrate_root, \
    root_features
from .alignment import periodicity
from .segments import split_segments, steady_segments
from .stock import STOCK_NAME, STOCK_RECIPE, load_stock_library

__all__ = [
    "AdaptResult",
    "AlignmentResult",
    "FORMAT_VERSION",
    "FilterContext",
    "GaitModel",
    "GaitModelFileError",
    "GridResult",
    "LookaheadPredictor",
    "MapResult",
    "ObservationStream",
    "OnlineConfig",
    "OnlineEM",
    "OnlineState",
    "PhaseGP",
    "ROOT_DOF_NAMES",
    "ROOT_FEATURE_NAMES",
    "RootFrame",
    "adapt",
    "align_sequences",
    "build_phase_gp",
    "choose_n_styles",
    "cycle_profile",
    "ekf_filter",
    "ekf_predict",
    "ekf_update",
    "estimate_period",
    "factorize",
    "fit_phase_gp",
    "foot_slide",
    "grid_search",
    "integrate_root",
    "interpolate_styles",
    "learn_model",
    "m_step",
    "make_context",
    "map_objective",
    "minimize_lbfgs",
    "mix_styles",
    "observation_jacobian",
    "observations_from_dofs",
    "online_forecast",
    "online_init",
    "online_step",
    "phase_shift",
    "periodicity",
    "predict",
    "predict_dofs",
    "refine_map",
    "restyle",
    "root_features",
    "split_segments",
    "stance_speeds",
    "steady_segments",
    "load_stock_library",
    "STOCK_NAME",
    "STOCK_RECIPE",
]
