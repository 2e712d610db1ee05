"""Stage-2 defaults that the command line shows in its help, importable without the sampler and its numerics.

Building the ``bayes-rcsa`` parser registers every sub-command; importing :mod:`.hierarchy` there only to print a
default took 0.6 s of every start of the command (``--help`` and a refused argument included).
"""

from __future__ import annotations

__all__ = ["STAGE2_MAX_STEPS"]

#: Steps of stage 2 after its burn-in at most (:class:`~bayes_rcsa.library.hierarchy.Stage2Settings`); stopping
#: there unconverged is a warning.
STAGE2_MAX_STEPS = 10000
