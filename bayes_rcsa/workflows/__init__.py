"""The public workflows: one function per job, each returning a result object.

This is the layer a script, a notebook and the command line share (the
``bayes-rcsa`` commands only parse their arguments, call one function here
and print).  Every function takes typed arguments (SI units: metres, Pa,
Hz, rpm for spindle speeds) and returns a :class:`~bayes_rcsa.workflows.result.Result`
subclass with ``save``/``load``, ``to_dict``, ``figures`` and a notebook view.

The names are imported lazily (``import bayes_rcsa`` stays light); they are
also available from the top level: ``bayes_rcsa.identify(...)``.  Each lives
in a module whose name differs from every public name (``identification``
holds ``identify``), because importing a submodule makes it an attribute of
its package: a module ``identify`` would hide the function ``identify``.
For the same reason no public name equals a subpackage of ``bayes_rcsa``
(the model check is ``check_model``, not ``discrepancy``).
"""

from __future__ import annotations

import importlib

#: public name -> module of this package that defines it
EXPORTS: dict[str, str] = {
    "Result": "result",
    "identify": "identification", "Posterior": "identification",
    "predict": "prediction", "Prediction": "prediction",
    "lobes": "stability_lobes", "Lobes": "stability_lobes",
    "check_model": "model_check", "ModelCheck": "model_check",
    "design_test": "experiment_design", "Design": "experiment_design",
    "update": "cut_update", "CutUpdate": "cut_update",
    "build_library": "library", "Population": "library",
    "run_batch": "batch_run", "BatchRun": "batch_run",
    "make_report": "reporting", "Report": "reporting",
    "identifiability": "identifiability_study", "Identifiability": "identifiability_study",
    "identify_spindle": "spindle", "SpindleInterface": "spindle",
    "synthesize": "synthesis", "Campaign": "synthesis",
    "simulate": "simulation", "SimulatedFRF": "simulation",
    "demo": "demo_run", "Demo": "demo_run",
    "write_example_files": "example_files", "ExampleFiles": "example_files",
}

__all__ = sorted(EXPORTS)


def __getattr__(name: str):
    if name in EXPORTS:
        module = importlib.import_module(f"{__name__}.{EXPORTS[name]}")
        return getattr(module, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(EXPORTS))
