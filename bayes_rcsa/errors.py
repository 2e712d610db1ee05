"""Exception hierarchy of bayes_rcsa.

Every error a user can trigger with a file, a setup key or a command-line
value derives from :class:`BayesRCSAError`; the command line turns these into
one line on stderr and exit status 2.  Anything else escaping is a bug.
"""

from __future__ import annotations

__all__ = [
    "BayesRCSAError",
    "DataError",
    "SetupError",
    "ModelError",
    "ConvergenceError",
    "OutputError",
    "DataWarning",
]


class BayesRCSAError(Exception):
    """Base class of all errors raised deliberately by bayes_rcsa."""


class DataError(BayesRCSAError, ValueError):
    """A measurement or receptance file is missing, malformed or unusable."""


class SetupError(BayesRCSAError, ValueError):
    """A setup file, geometry, material or option is inconsistent or invalid."""


class ModelError(BayesRCSAError, ValueError):
    """A model was asked for something outside its domain (e.g. extrapolation)."""


class ConvergenceError(BayesRCSAError, RuntimeError):
    """A sampler or optimiser did not reach the requested convergence."""


class OutputError(BayesRCSAError, RuntimeError):
    """An output folder or file cannot be written (full disk, read-only or vanished folder, no permission).

    Raised instead of a bare :class:`OSError` by the writers of :mod:`bayes_rcsa.io.atomic`, with the folder
    and the errno meaning named (``"DIR: cannot write: No space left on device (ENOSPC)"``).
    """


class DataWarning(UserWarning):
    """Input that is plausible enough to use but suspicious (the CLI prints it as one ``warning:`` line)."""
