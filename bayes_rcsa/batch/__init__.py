"""Scale-out to a tool library: many setups, identify + predict + lobes each, on any executor.

:func:`load_manifest` reads the library's manifest (TOML) into
:class:`SetupJob` s; :func:`run_batch` runs the unfinished ones, one task per
setup, on a :class:`concurrent.futures.Executor` (local processes by default,
a Dask cluster's executor for many machines) and :func:`write_summary` writes
the library's table.  See docs/scaling-out.md.

The names are imported on first use, so that a worker's start-up module
(:mod:`bayes_rcsa.batch.worker_start`) can cap the BLAS threads before numpy
is imported.
"""

import importlib

__all__ = ["SetupJob", "load_manifest", "BatchResult", "run_batch", "run_setup", "limit_threads", "write_summary"]

_WHERE = {"SetupJob": "manifest", "load_manifest": "manifest", "BatchResult": "run", "run_batch": "run",
          "run_setup": "run", "limit_threads": "run", "write_summary": "table"}


def __getattr__(name):
    if name in _WHERE:
        return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
