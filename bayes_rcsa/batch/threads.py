"""One BLAS/OpenMP thread per batch worker (no numpy import here: it must run before numpy loads its BLAS)."""

import os

__all__ = ["THREAD_VARIABLES", "limit_threads"]

#: Environment variables that cap the BLAS/OpenMP thread pools of a worker at one thread: N workers on N cores
#: otherwise start N x cores threads that fight for the cores (numpy's BLAS reads them when it is first imported).
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                    "NUMEXPR_NUM_THREADS", "NUMBA_NUM_THREADS")


def limit_threads() -> None:
    """Cap every thread pool variable at 1 (effective for libraries loaded after the call)."""
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"
