"""bayes_rcsa: Bayesian receptance coupling substructure analysis for machine-tool dynamics.

The workflows are functions of this package that return result objects
(docs/api.md)::

    import bayes_rcsa as br
    setup = br.load_setup("setup.toml")
    post = br.identify(setup, lengths=[0.025, 0.040], seed=1)
    pred = post.predict([0.030])
    lob = br.lobes(posterior=post, setup=setup, clamping_length=0.030, flutes=4, kt=790e6, kr=230e6,
                   radial_immersion=0.7, speeds_rpm=np.linspace(5000, 30000, 400))
    check = br.check_model(setup, lengths=[0.025, 0.040])

Each result has ``save(folder)`` (the files of the matching ``bayes-rcsa``
command), ``load(folder)``, ``to_dict()``, ``figures()`` and a notebook
view.  The packages below hold the physics and the methods; docs/architecture.md
draws how they stack.
"""

from __future__ import annotations

from .errors import BayesRCSAError, ConvergenceError, DataError, ModelError, SetupError

__version__ = "0.1.0"

_LAZY = {"load_setup": ("bayes_rcsa.io.setup", "load_setup"), "example_setup": ("bayes_rcsa.data", "example_setup")}


def __getattr__(name: str):
    # the workflows import numpy, scipy, emcee, ...: only when first used, so that `bayes-rcsa --help` and
    # `import bayes_rcsa` stay light.  importlib, not `from . import`, which would ask this function again.
    import importlib

    if name.startswith("_"):
        raise AttributeError(f"module 'bayes_rcsa' has no attribute {name!r}")
    workflows = importlib.import_module(f"{__name__}.workflows")
    if name in workflows.EXPORTS:
        return getattr(importlib.import_module(f"{workflows.__name__}.{workflows.EXPORTS[name]}"), name)
    if name in _LAZY:
        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'bayes_rcsa' has no attribute {name!r}")


def __dir__():
    import importlib

    workflows = importlib.import_module(f"{__name__}.workflows")
    return sorted(set(globals()) | set(workflows.EXPORTS) | set(_LAZY))


__all__ = ["BayesRCSAError", "ConvergenceError", "DataError", "ModelError", "SetupError", "__version__",
           "load_setup", "example_setup", "Result", "identify", "Posterior", "predict", "Prediction", "lobes", "Lobes",
           "check_model", "ModelCheck", "design_test", "Design", "update", "CutUpdate", "build_library",
           "Population", "run_batch", "BatchRun", "make_report", "Report", "identifiability", "Identifiability", "identify_spindle",
           "SpindleInterface", "synthesize", "Campaign", "simulate", "SimulatedFRF", "demo", "Demo"]
