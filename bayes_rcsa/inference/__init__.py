"""Bayesian identification of the tool-holder contact (Methods I and II) with emcee.

Separate, small objects in the spirit of bilby:

* :mod:`bayes_rcsa.params` (upstream) -- priors, the growth law, the parameter model and model terms;
* :mod:`.band` -- the likelihood band (default rule, overrides);
* :mod:`.likelihood` -- the vectorised complex-FRF likelihood and its tempering;
* :mod:`.posterior` -- log prior + log likelihood + a problem's extra likelihood terms;
* :mod:`.search` -- global optimum (likelihood grid + polish);
* :mod:`.sampler` -- walker start, the package's one emcee driver (convergence, fixed steps, checkpoint/resume);
* :mod:`.deterministic` -- the reference paper's deterministic fit;
* :mod:`.diagnostics` -- R-hat and ESS of a chain (:mod:`bayes_rcsa.stats.convergence`) and the InferenceData (the
  only module that imports ArviZ, and only for an InferenceData);
* :mod:`.results`, :mod:`.plots` -- summary.json and figures;
* :mod:`.problem`, :mod:`.identify` -- assembling a problem and running it;
* :mod:`.fingerprint` -- what a resumed run must share with its checkpoint;
* :mod:`.outputs` -- posterior.nc, summary.json and the plots of a run.

See docs/identification.md.  Importing this package does not import ArviZ or
matplotlib; they are loaded when diagnostics or plots are made.
"""

from .band import Band, default_band
from .identify import IdentificationResult, identify, posterior_stiffness, predict_frf
from .outputs import write_outputs
from ..params.growth import GrowthLaw
from ..params.model import ParameterModel
from ..params.priors import LogNormal, LogUniform, Normal, PriorSet, Uniform  # re-exported for API continuity
from .problem import IdentificationOptions, Problem, build_problem, build_problem_from_setup
from .sampler import SamplerSettings

__all__ = [
    "Band", "default_band",
    "IdentificationResult", "identify", "posterior_stiffness", "predict_frf", "write_outputs",
    "GrowthLaw", "ParameterModel",
    "LogNormal", "LogUniform", "Normal", "PriorSet", "Uniform",
    "IdentificationOptions", "Problem", "build_problem", "build_problem_from_setup",
    "SamplerSettings",
]
