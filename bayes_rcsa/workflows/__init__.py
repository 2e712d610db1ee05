"""The public workflows: one function per job, each returning a result object.

This is the layer a script, a notebook and the command line share (the
``bayes-rcsa`` commands only parse their arguments, call one function here
and print).  Every function takes typed arguments (SI units: metres, Pa,
Hz, rpm for spindle speeds) and returns a :class:`~bayes_rcsa.workflows.result.Result`
subclass with ``save``/``load``, ``to_dict``, ``figures`` and a notebook view.

The names are imported lazily (``import bayes_rcsa`` stays light); they are
also available from the top level: ``bayes_rcsa.identify(...)``.
"""

from __future__ import annotations

import importlib

#: public name -> module of this package that defines it
EXPORTS: dict[str, str] = {
    "Result": "result",
    "identify": "identify", "Posterior": "identify",
    "predict": "predict", "Prediction": "predict",
    "lobes": "lobes", "Lobes": "lobes",
    "discrepancy": "discrepancy", "ModelCheck": "discrepancy",
    "design": "design", "Design": "design",
    "update": "update", "CutUpdate": "update",
    "build_library": "library", "Population": "library",
    "batch": "batch", "BatchRun": "batch",
    "report": "report", "Report": "report",
    "identifiability": "identifiability", "Identifiability": "identifiability",
    "identify_spindle": "spindle", "SpindleInterface": "spindle",
    "synthesize": "synthesize", "Campaign": "synthesize",
    "simulate": "simulate", "SimulatedFRF": "simulate",
    "demo": "demo", "Demo": "demo",
}

__all__ = sorted(EXPORTS)


def __getattr__(name: str):
    if name in EXPORTS:
        module = importlib.import_module(f"{__name__}.{EXPORTS[name]}")
        return getattr(module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(EXPORTS))
