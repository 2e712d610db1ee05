"""Thread pools of the numerical libraries: one thread per process (no numpy import here: it must run before
numpy loads its BLAS, which reads these variables once, when it is first imported).

The toolkit's linear algebra is many small problems batched over frequency lines and parameter sets (2 x 2
couplings, 4 x 4 segment stiffnesses, Jacobians of a few columns), where a multi-threaded BLAS gains nothing
and loses much when the other cores are busy: measured on the two-core development machine with another job
running, the SVD of a 1870 x 8 Jacobian (each step of the discrepancy workflow's fit) took 46 ms with
OpenBLAS's default threads against 0.3 ms with one, and ``bayes-rcsa demo`` 38.9 s against 25.4 s.
"""

import os

__all__ = ["THREAD_VARIABLES", "limit_threads", "single_threaded_by_default"]

#: Environment variables that cap the BLAS/OpenMP thread pools of a process at one thread: N worker processes on
#: N cores otherwise start N x cores threads that fight for the cores.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                    "NUMEXPR_NUM_THREADS", "NUMBA_NUM_THREADS")


def limit_threads() -> None:
    """Cap every thread pool variable at 1 (a worker process; effective for libraries loaded after the call)."""
    for name in THREAD_VARIABLES:
        os.environ[name] = "1"


def single_threaded_by_default() -> None:
    """Cap every thread pool variable at 1 unless the user has set it (the command line, before numpy loads)."""
    for name in THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
