"""Load what a lobes job will need in a background thread while the job starts.

A probabilistic lobes run spends about a second on loading code it will certainly use: numba and the cached
machine code of the compiled envelope and map (:mod:`._zoa_kernel`), and matplotlib for the figure.  That loading
is Python work holding the interpreter lock, but the job's own first steps (reading the FRF files, drawing
the realisations, the eigenvalues of 750,000 2 x 2 matrices, sorting) run mostly inside numpy, which releases the
lock; on a machine with a second core the two overlap.  :func:`start` returns at once; whatever the thread has
not finished is loaded by the job when it gets there (Python's per-module import locks make that safe), so the
results are the same with or without it.

The thread must never enter :class:`warnings.catch_warnings`.  Before Python 3.14 that context manager saves
and restores the process's global filter list and ``showwarning``; entered on two threads at once, the one that
leaves last restores a state the other has already left, so the job (or the next one in the same process) can
lose its warnings for good: a filter saved inside a short ``simplefilter("ignore")`` block stays in force, and
``showwarning`` points at a finished :func:`bayes_rcsa.messages.warning_log`.  Importing scipy and matplotlib
runs such blocks at module level, so :func:`start` imports those two packages on the calling thread first
(about 0.2 s each when not yet loaded); what is left for the thread (numba, the kernels' cached code,
``matplotlib.figure`` and the Agg backend) enters none.  Compiling does: numba enters such a block hundreds
of times while it compiles a kernel, so the thread loads a kernel only when numba's on-disk cache holds its
machine code for this source and this processor, and otherwise leaves it to the job, which compiles it on its
own thread (the first run after an installation or an edit of the kernels, e.g. a fresh CI checkout).  Both
cases are watched by tests/test_stability_warmup.py.
"""

from __future__ import annotations

import threading

__all__ = ["start"]

#: Modules whose import enters :class:`warnings.catch_warnings` (module-level code of scipy's ``_lib._util`` and
#: of matplotlib's ``__init__``): imported on the calling thread before the warm-up thread starts.
_CALLER_IMPORTS = {"kernels": ("scipy._lib._util",), "figure": ("matplotlib",)}


def _cached(kernel) -> bool:
    """Whether numba's on-disk cache holds machine code of ``kernel`` for this source file and this processor.

    Numba has no public call for this; its cache index is read the way numba reads it (an index whose source
    stamp differs from the file's is empty).  Any surprise in numba's internals counts as "not cached": the
    warm-up is then skipped, which costs time, never correctness.
    """
    try:
        magic = kernel.targetctx.codegen().magic_tuple()
        index = kernel._cache._cache_file._load_index()
        return any(key[1] == magic for key in index)
    except Exception:  # numba's private layout changed: do not warm up rather than risk compiling here
        return False


def _load(kernels: bool, figure: bool) -> None:
    if kernels:
        from . import _zoa_kernel

        kernels = all(_cached(k) for k in (_zoa_kernel.stable_fractions, _zoa_kernel.lower_envelope))
    if kernels:
        import numpy as np

        # calling each kernel once on tiny inputs loads its cached machine code (numba compiles nothing here:
        # the signatures are those of the real call, float64/int64 arrays, and _cached found them on disk)
        one = np.zeros((1, 1))
        _zoa_kernel.stable_fractions(np.ones((1, 1)), np.ones(1), np.zeros((1, 1)))
        _zoa_kernel.lower_envelope(np.full((1, 2, 2), np.inf), np.zeros((1, 2, 2)), np.ones(2), np.ones(2), 1, 1,
                                   np.ones(2), True, np.full((1, 2), np.inf), one.copy(),
                                   np.zeros((1, 1), dtype=np.int64), False)
    if figure:
        import matplotlib.backends.backend_agg  # noqa: F401
        import matplotlib.figure  # noqa: F401


def start(kernels: bool = True, figure: bool = True) -> threading.Thread:
    """Start loading the compiled kernels (``kernels``) and matplotlib (``figure``) in a daemon thread.

    The packages in ``_CALLER_IMPORTS`` are imported first, on the calling thread (see the module's docstring).
    """
    import importlib

    for part, wanted in (("kernels", kernels), ("figure", figure)):
        if wanted:
            for name in _CALLER_IMPORTS[part]:
                importlib.import_module(name)

    def run():
        try:
            _load(kernels, figure)
        except Exception:  # a warm-up only: the job itself loads (and reports) whatever failed here
            pass

    thread = threading.Thread(target=run, name="bayes_rcsa-warmup", daemon=True)
    thread.start()
    return thread
