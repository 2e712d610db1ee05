"""Milling chatter stability: deterministic and probabilistic stability lobes.

- :mod:`.cutting`        CuttingConditions, directional matrices (axis convention documented there)
- :mod:`.zoa`            zero-order approximation directly on complex FRFs (fast, vectorised over draws)
- :mod:`.modal_fit`      real passive modal models and their fit to FRFs (mode count by BIC)
- :mod:`.sdm`            first-order semi-discretisation on modal x/y models (vectorised over the grid)
- :mod:`.timedomain`     time-domain milling simulation (independent check)
- :mod:`.probabilistic`  P(stable) maps, depth quantiles and recommended operating point from FRF draws
- :mod:`.compare`        the paper's comparison metrics (Tables 8 and 9)

See docs/stability.md for the theory, conventions and the verification.
"""

from .compare import disagreement, limits_disagreement, stable_at, test_error
from .cutting import CuttingConditions, directional_matrix, interval_directional_matrices, mean_directional_matrix
from .modal_fit import ModalFit, ModalModel, fit_modal_model
from .probabilistic import (
    ProbabilisticLobes,
    Recommendation,
    depth_quantiles,
    lobes_from_frf_draws,
    probability_map,
    recommend_operating_point,
)
from .sdm import SDMResult, default_intervals, sdm_depth_limit, sdm_stability_map, spectral_radius
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
    "lobes_from_frf_draws",
    "probability_map",
    "depth_quantiles",
    "recommend_operating_point",
    "disagreement",
    "limits_disagreement",
    "stable_at",
    "test_error",
]
