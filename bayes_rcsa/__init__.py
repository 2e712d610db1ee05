"""bayes_rcsa: Bayesian receptance coupling substructure analysis for machine-tool dynamics.

Layout (each sub-package one room of the pipeline):

- :mod:`bayes_rcsa.model`     materials, sections, Timoshenko beams, coupling, RCSA assembly
- :mod:`bayes_rcsa.io`        measurement, receptance and setup files (CSV, UFF58, TOML)
- :mod:`bayes_rcsa.synthetic` an independent, richer finite-element bench with hidden effects
- :mod:`bayes_rcsa.inference` priors, likelihood, emcee sampling, deterministic fits
- :mod:`bayes_rcsa.posterior` predictions, credible intervals, identifiability
- :mod:`bayes_rcsa.stability` milling stability lobes (ZOA, SDM), probabilistic lobes
- :mod:`bayes_rcsa.cli`       the ``bayes-rcsa`` command line
"""

from .errors import BayesRCSAError, ConvergenceError, DataError, ModelError, SetupError

__version__ = "0.1.0"

__all__ = ["BayesRCSAError", "ConvergenceError", "DataError", "ModelError", "SetupError", "__version__"]
