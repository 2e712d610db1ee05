"""Posterior predictions: quantities derived from identified contact parameters.

* :mod:`.draws` -- :class:`PosteriorDraws` (a parameter model plus its draws), read from posterior.nc through
  :mod:`bayes_rcsa.store`;
* :mod:`.predict`, :mod:`.prediction_outputs` -- credible intervals of tool-point FRFs and natural frequencies at
  any clamping length, and their files;
* :mod:`.identifiability`, :mod:`.study` -- single- vs multi-length fits: contraction, ridges, Fisher information,
  transfer errors;
* :mod:`.setup_match` -- a posterior used with another setup (changed geometry or material) says so;
* :mod:`.growth_prior`, :mod:`.plots`, :mod:`.report`.
"""

from ..model.natural_frequencies import NATURAL_FREQUENCY_RULE, natural_frequency

__all__ = ["natural_frequency", "NATURAL_FREQUENCY_RULE"]

# Posterior predictions, credible intervals and identifiability diagnostics.
from .draws import CONTACT_NAMES, PosteriorDraws, draws_from_result, load_posterior  # noqa: E402
from .identifiability import (  # noqa: E402
    VERDICT_RULE,
    contraction,
    fisher_information,
    parameter_identifiability,
    ridge_analysis,
    transfer_errors,
    verdict,
)
from .predict import (  # noqa: E402
    FRFBands,
    ModePrediction,
    Prediction,
    PredictionTarget,
    find_modes,
    mode_statistics,
    parameter_influence,
    predict,
    prediction_targets,
    predictive_frf,
)
from .prediction_outputs import run_prediction, write_prediction_outputs  # noqa: E402
from .study import plan_fits, run_study, write_study  # noqa: E402

__all__ += [
    "CONTACT_NAMES", "PosteriorDraws", "draws_from_result", "load_posterior",
    "VERDICT_RULE", "contraction", "verdict", "parameter_identifiability", "ridge_analysis", "fisher_information",
    "transfer_errors",
    "PredictionTarget", "FRFBands", "ModePrediction", "Prediction", "prediction_targets", "predictive_frf",
    "find_modes", "mode_statistics", "predict", "parameter_influence",
    "run_prediction", "write_prediction_outputs", "plan_fits", "run_study", "write_study",
]
