"""Model discrepancy: find where model and measurements disagree, name the missing effect, add it.

The loop (docs/discrepancy.md):

* :mod:`.detect` -- standardised residuals, resonance diagnosis, trends, adequacy test;
* :mod:`.screen` -- score test of every candidate model term at the baseline fit;
* :mod:`.fit` -- MAP + Laplace fits of model variants on the tempered likelihood;
* :mod:`.select` -- refits, the evidence criterion, winner / runner-up / confounded;
* the statistical discrepancy term used when nothing is named is a model term,
  :mod:`bayes_rcsa.params.terms.statistical_discrepancy` (so a posterior holding it reads back anywhere);
* :mod:`.workflow` -- the whole loop (the computation); :mod:`.evaluate` -- a fit at every measurement;
* :mod:`.document` -- discrepancy.json; :mod:`.render` -- summary.md and the closing line;
  :mod:`.files` -- setup.amended.toml and the writing of every file; :mod:`.plots` -- its figures.

The public entry point is :func:`bayes_rcsa.workflows.model_check.check_model` (``bayes_rcsa.check_model``), which returns a :class:`~bayes_rcsa.workflows.model_check.ModelCheck`.

Candidates are the registered model terms (:mod:`bayes_rcsa.params.terms`):
adding a candidate is adding a model term (one file, one registration).
"""

from .files import write_discrepancy
from .workflow import DiscrepancyOptions, DiscrepancyResult, run_discrepancy

__all__ = ["DiscrepancyOptions", "DiscrepancyResult", "run_discrepancy", "write_discrepancy"]
