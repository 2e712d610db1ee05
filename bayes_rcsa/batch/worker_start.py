"""Start-up of the local worker processes: one BLAS thread, then the heavy imports, once.

The batch's local pool forks its workers from a fork server that imports this
module first (``multiprocessing`` forkserver preload): the thread caps are in
the environment before numpy loads its BLAS, and numpy, the model, the
sampler and the plotting stack are imported once in the server instead of
once per worker process.  Nothing here may import numpy before the caps are
set.
"""

from bayes_rcsa.threads import limit_threads

limit_threads()

import bayes_rcsa.batch.run  # noqa: E402,F401  (numpy, the I/O layer)
import bayes_rcsa.inference.identify  # noqa: E402,F401  (emcee, the likelihood)
import bayes_rcsa.posterior.prediction_outputs  # noqa: E402,F401  (predict)
import bayes_rcsa.stability.probabilistic  # noqa: E402,F401  (lobes)
# what every step imports lazily, measured on a worker's identify (chain), predict and lobes: ArviZ used to bring
# most of it along; without it each worker would pay ~2 s of imports
import emcee  # noqa: E402,F401  (with scipy.stats)
import h5py  # noqa: E402,F401  (posterior.nc, the checkpoint; h5netcdf stays the store's own import)
import numba  # noqa: E402,F401  (the compiled kernels' runtime)
import matplotlib  # noqa: E402  (the figures of every step: matplotlib's own start-up, once)
import matplotlib.backends.backend_agg  # noqa: E402,F401
import matplotlib.figure  # noqa: E402,F401
import scipy.signal  # noqa: E402,F401  (predict's peak finding)


def _numba_target() -> None:
    """Build numba's CPU target (its typing and lowering registries) in the server.

    A process builds it at its first kernel call, even when the machine code then comes from numba's on-disk
    cache: ~0.3 s of imports (``numba.cpython.*``, the typed containers) per worker otherwise.  Nothing is
    compiled here, so the workers' kernels and numbers are those of a cold process.  numba's registry is not a
    documented API: if it moves, the workers build the target themselves, as before.
    """
    try:
        from numba.core.registry import cpu_target
    except ImportError:
        return
    for context in ("typing_context", "target_context"):
        ctx = getattr(cpu_target, context, None)
        refresh = getattr(ctx, "refresh", None)
        if callable(refresh):
            refresh()


_numba_target()
