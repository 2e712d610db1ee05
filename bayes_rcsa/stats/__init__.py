"""Layer-0 statistics shared across the package: importance weights and the model-free noise estimate.

* :mod:`.weights` -- normalised importance weights from log weights, their effective sample size, the
  Pareto-smoothed weights and shape ``k`` (PSIS), and the thresholds that judge them (one constant per meaning);
* :mod:`.convergence` -- rank-normalised split R-hat and bulk/tail effective sample size of Markov chains;
* :mod:`.noise` -- the relative noise level of a measured FRF, estimated from the FRF alone, and the per-line
  noise standard deviation of the relative-plus-floor noise model.

Imports numpy (scipy.special lazily, for the normal quantile) and :mod:`bayes_rcsa.errors` only.
"""

from .convergence import convergence_diagnostics, ess_bulk, ess_tail, rank_rhat
from .noise import noise_sigma, relative_noise_scale
from .weights import (MIN_ESS, MIN_ESS_COVARIANCE, MIN_ESS_INTERVAL_END, MIN_ESS_PER_DIMENSION, MIN_ESS_UPDATE,
                      PARETO_K_MAX, effective_sample_size, importance_reliable, normalise_log_weights, pareto_k,
                      pareto_smoothed_log_weights)

__all__ = ["normalise_log_weights", "effective_sample_size", "pareto_smoothed_log_weights", "pareto_k",
           "importance_reliable", "PARETO_K_MAX", "MIN_ESS", "MIN_ESS_INTERVAL_END", "MIN_ESS_UPDATE",
           "MIN_ESS_COVARIANCE", "MIN_ESS_PER_DIMENSION", "relative_noise_scale", "noise_sigma", "rank_rhat", "ess_bulk",
           "ess_tail", "convergence_diagnostics"]
