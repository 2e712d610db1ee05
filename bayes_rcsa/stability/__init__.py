"""Milling chatter stability: deterministic and probabilistic stability lobes.

- :mod:`.cutting`        CuttingConditions, directional matrices (axis convention documented there)
- :mod:`.zoa`            zero-order approximation directly on complex FRFs (fast, vectorised over draws)
- :mod:`.modal_fit`      real passive modal models and their fit to FRFs (mode count by BIC)
- :mod:`.sdm`            first-order semi-discretisation on modal x/y models (vectorised over the grid)
- :mod:`.timedomain`     time-domain milling simulation (independent check)
- :mod:`.methods`        the registry of stability methods (ZOA in :mod:`.zoa`, SDM in :mod:`.sdm_draws`)
- :mod:`.probabilistic`  P(stable) maps, depth quantiles and lobes from FRF draws
- :mod:`.recommend`      robust operating point (speed tolerance, depth margin, force tolerance), pockets
- :mod:`.plausibility`   plausibility of cutting coefficients (unit slips)
- :mod:`.posterior_frf`, :mod:`.tests_io`, :mod:`.outputs`, :mod:`.plots`: the ``lobes`` job's inputs and outputs
- :mod:`.compare`        the paper's comparison metrics (Tables 8 and 9)

See docs/stability.md for the theory, conventions and the verification.

The names of :mod:`.modal_fit` (scipy.optimize) and :mod:`.sdm` (the compiled
kernel) are imported on first use, so that a ZOA run does not pay for them.
"""

import importlib as _importlib

from .compare import disagreement, limits_disagreement, stable_at, test_error
from .cutting import CuttingConditions, directional_matrix, interval_directional_matrices, mean_directional_matrix
from .methods import STABILITY_METHODS, MethodOptions, MethodResult, method_names
from .probabilistic import (
    ProbabilisticLobes,
    depth_grid,
    depth_quantiles,
    lobes_from_frf_draws,
    probability_map,
    recommend_operating_point,
)
from .recommend import Recommendation, Tolerances, level_limit, recommend
from . import sdm_draws as _sdm_draws  # noqa: F401  (registers the "sdm" method)
from .timedomain import TimeDomainResult, simulate_milling
from .zoa import ZOAResult, oriented_eigenvalues, zoa_lobes, zoa_minimum_depth

__all__ = [
    "CuttingConditions",
    "directional_matrix",
    "mean_directional_matrix",
    "interval_directional_matrices",
    "ZOAResult",
    "zoa_lobes",
    "zoa_minimum_depth",
    "oriented_eigenvalues",
    "ModalModel",
    "ModalFit",
    "fit_modal_model",
    "SDMResult",
    "sdm_stability_map",
    "sdm_depth_limit",
    "spectral_radius",
    "default_intervals",
    "TimeDomainResult",
    "simulate_milling",
    "ProbabilisticLobes",
    "Recommendation",
    "Tolerances",
    "recommend",
    "level_limit",
    "depth_grid",
    "STABILITY_METHODS",
    "MethodOptions",
    "MethodResult",
    "method_names",
    "periodic_dde_radius",
    "lobes_from_frf_draws",
    "probability_map",
    "depth_quantiles",
    "recommend_operating_point",
    "disagreement",
    "limits_disagreement",
    "stable_at",
    "test_error",
]

_LAZY = {
    "ModalFit": "modal_fit", "ModalModel": "modal_fit", "fit_modal_model": "modal_fit",
    "SDMResult": "sdm", "default_intervals": "sdm", "periodic_dde_radius": "sdm", "sdm_depth_limit": "sdm",
    "sdm_stability_map": "sdm", "spectral_radius": "sdm",
}


def __getattr__(name):
    """Import the names of :mod:`.modal_fit` and :mod:`.sdm` on first use (PEP 562)."""
    if name in _LAZY:
        value = getattr(_importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
