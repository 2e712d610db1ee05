"""Cutting-test outcomes update the posterior (issue #23).

- :mod:`.coefficients`  CoefficientPrior: cutting-force level and K_r/K_t ratio (``--kt 560e6±30%``)
- :mod:`.likelihood`    the probit stability likelihood P(chatter | θ, K_t, K_r) on the registered methods' limits
- :mod:`.data`          cut files with their setups (clamping length, immersion, feed, tool) and their checks
- :mod:`.update`        importance re-weighting of a posterior's draws, ESS check, resampling
- :mod:`.mcmc`          the MCMC fallback (emcee) when the re-weighting collapses
- :mod:`.compare`       hammer only vs hammer + cuts lobes and recommendations, each cut's move
- :mod:`.workflow`      ``bayes-rcsa update`` as one call (:func:`~.workflow.run_update`)
- :mod:`.next_cut`      which cut next (the expected reduction of a target's uncertainty)
- :mod:`.outputs`       the updated ``posterior.nc`` (with K_t/K_r draws) and ``update.json``

See docs/stability.md, "Cutting tests update the posterior".
"""

from .coefficients import DEFAULT_RATIO_NODES, CoefficientPrior
from .likelihood import (DEFAULT_BOUNDARY_WIDTH, DEFAULT_LABEL_ERROR, BoundaryWidth, CutGroup, CutLikelihood,
                         chatter_probability, inverse_limits_at_cuts, outcome_log_likelihood)

__all__ = [
    "CoefficientPrior", "DEFAULT_RATIO_NODES",
    "DEFAULT_BOUNDARY_WIDTH", "DEFAULT_LABEL_ERROR", "BoundaryWidth", "CutGroup", "CutLikelihood",
    "chatter_probability", "inverse_limits_at_cuts", "outcome_log_likelihood",
]
