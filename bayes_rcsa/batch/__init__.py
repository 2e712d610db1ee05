"""Scale-out to a tool library: many setups, identify + predict + lobes each, on any executor.

:func:`load_manifest` reads the library's manifest (TOML) into
:class:`SetupJob` s; :func:`run_batch` runs the unfinished ones, one task per
setup, on a :class:`concurrent.futures.Executor` (local processes by default,
a Dask cluster's executor for many machines) and :func:`write_summary` writes
the library's table.  See docs/scaling-out.md.
"""

from .manifest import SetupJob, load_manifest
from .run import BatchResult, limit_threads, run_batch, run_setup
from .table import write_summary

__all__ = ["SetupJob", "load_manifest", "BatchResult", "run_batch", "run_setup", "limit_threads", "write_summary"]
