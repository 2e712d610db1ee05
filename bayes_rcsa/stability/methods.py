"""The registry of stability methods: every method turns FRF draws into per-draw depth limits.

A method is an object with

- ``name`` (str) and ``summary`` (one line, for ``--help``);
- ``depth_limits(frf_x, frf_y, frequency_hz, cutting, speeds_rpm, options, progress) -> MethodResult``
  with the limit a_lim,d(n) of every draw d at every speed (m; +inf = no
  chatter found in the analysed range);
- ``estimate_seconds(n_draws, n_speeds, n_freq) -> float``, a run-time
  estimate on the reference machine (2 shared cores), printed before the job;
- ``check(options)`` raising :class:`~bayes_rcsa.errors.SetupError` for
  options the method cannot use.

Adding a method is one file defining it plus ``STABILITY_METHODS.register(...)``
(see :mod:`.zoa` and :mod:`.sdm_draws`); ``bayes-rcsa lobes --method`` takes
its choices from this registry.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..registry import Registry

__all__ = ["STABILITY_METHODS", "MethodOptions", "MethodResult", "method_names"]

STABILITY_METHODS: Registry = Registry("stability method")


@dataclass(frozen=True)
class MethodOptions:
    """Options a method may use.

    Attributes
    ----------
    intervals : int or None, SDM intervals per tooth period (None: the method's rule)
    max_modes : int, largest mode count of modal fits (SDM)
    exact : bool, compute every draw with the method itself, never a surrogate (SDM: see
        :mod:`bayes_rcsa.stability.sdm_draws`)
    """

    intervals: int | None = None
    max_modes: int = 4
    exact: bool = False


@dataclass(frozen=True)
class MethodResult:
    """Per-draw depth limits of a method.

    Attributes
    ----------
    depth_limit_m : (n_draws, n_speed) m, +inf where no limit was found
    modal_fits : list of (ModalFit x, ModalFit y) per draw (methods on modal models), else empty
    info : dict, JSON-able details for the output file
    limits_at : callable (speeds (k,) rpm) -> (n_draws, k) m, or None
        The same limits at other speeds, reusing the method's per-draw work
        (used to verify the recommendation between grid speeds).
    """

    depth_limit_m: np.ndarray
    modal_fits: list = field(default_factory=list)
    info: dict = field(default_factory=dict)
    limits_at: object = None


def method_names() -> tuple[str, ...]:
    """Registered method names (imports the built-in methods first)."""
    from . import sdm_draws, zoa  # noqa: F401  (registration happens on import)

    return STABILITY_METHODS.names()
