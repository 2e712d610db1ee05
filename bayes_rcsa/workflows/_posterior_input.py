"""Inputs shared by the workflows that use a posterior (predict, lobes, design): a path or a loaded ``Posterior``.

A workflow accepts the posterior as the path of a ``posterior.nc`` or as the
:class:`~bayes_rcsa.workflows.identification.Posterior` an identification returned
(or :meth:`Posterior.load` read); with the latter it uses the draws and the
file content it holds and never reads the file again.  The setup likewise is
a path of the setup TOML or a loaded :class:`~bayes_rcsa.io.setup.Setup`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from ..errors import SetupError

__all__ = ["PosteriorParts", "posterior_parts", "is_path", "setup_of"]


def is_path(value) -> bool:
    """True for a str or path-like (a file to read), False for an object already loaded."""
    return isinstance(value, (str, os.PathLike))


def setup_of(setup, load_data: bool = True, load_spindle: bool | None = None):
    """(``setup`` loaded, what messages call it): a path is read once, a Setup is used as it is."""
    if is_path(setup):
        from ..io.setup import load_setup

        return load_setup(setup, load_data=load_data, load_spindle=load_spindle), setup
    return setup, getattr(setup, "path", "the setup")


@dataclass(frozen=True)
class PosteriorParts:
    """What a workflow takes from a loaded posterior (all None for a path: the callee reads the file once).

    Attributes
    ----------
    path : str, path-like or None, the posterior.nc as given (None for a posterior held in memory only)
    draws : PosteriorDraws or None
    inference_data : arviz.InferenceData, :class:`bayes_rcsa.store.netcdf.ArrayData` or None, the file's content
    summary : dict or None, the fit's summary.json document, passed on only when there is no file beside it
    """

    path: object
    draws: object = None
    inference_data: object = None
    summary: dict | None = None


def posterior_parts(posterior) -> PosteriorParts:
    """Split ``posterior`` (a path, or a ``Posterior`` result) into what the stability and posterior layers take.

    Raises
    ------
    SetupError
        A ``Posterior`` without draws (identified with method "deterministic").
    """
    if is_path(posterior):
        return PosteriorParts(posterior)
    draws = getattr(posterior, "draws", None)
    if draws is None:
        raise SetupError("the posterior holds no draws (identified with method 'deterministic'); predictions and "
                         "lobes need posterior draws")
    path = getattr(posterior, "path", None)
    # the numbers of the file as h5py read them (what the callee would read itself), so that no ArviZ decode is
    # forced; an InferenceData already decoded, or set by a script, is passed on as it is
    from .identification import Posterior, _numbers

    idata = _numbers(posterior) if isinstance(posterior, Posterior) else getattr(posterior, "inference_data", None)
    return PosteriorParts(None if path is None else Path(path), draws, idata,
                          None if path is not None else getattr(posterior, "summary", None))
