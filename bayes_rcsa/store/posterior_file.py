"""``posterior.nc``: its schema version, its one writer and its one reader.

A ``posterior.nc`` is an ArviZ InferenceData netCDF file (:mod:`.netcdf`)
holding the draws of a fit (``posterior``: the parameters in physical units
and derived quantities, shape (chain, draw, ...)), ``sample_stats``,
``log_likelihood``, ``observed_data`` and ``constant_data`` (fit lengths,
bands), with the fit's attributes (method, tempering, the JSON parameter
model) on ``constant_data`` and ``observed_data`` (where ArviZ puts them)
and on the root group.

Schema versions (root attribute :data:`SCHEMA_ATTRIBUTE`):

1. no attribute: every file written before the version was recorded; read as
   it always was;
2. the same layout with the attribute.

A file of a newer version (written by a newer bayes_rcsa) or with a version
that is not a positive integer is refused with one line naming the file and
the version, rather than misread.

Every read of a ``posterior.nc`` in the package goes through
:func:`_open_posterior` (through :func:`read_posterior`), every write through
:func:`write_posterior` or :func:`append_to_posterior`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import DataError, SetupError
from .netcdf import _groups, _inference_data, _write_groups, read_netcdf, read_netcdf_arrays

__all__ = ["SCHEMA_VERSION", "SCHEMA_ATTRIBUTE", "write_posterior", "read_posterior", "append_to_posterior",
           "posterior_attributes"]

#: Version of the posterior.nc layout this bayes_rcsa writes (and the newest it reads).
SCHEMA_VERSION = 2

#: Root attribute of posterior.nc holding its schema version (absent: version 1).
SCHEMA_ATTRIBUTE = "bayes_rcsa_schema_version"

#: Groups whose attributes :func:`posterior_attributes` merges, later ones winning.
_ATTRIBUTE_GROUPS = ("posterior", "sample_stats", "constant_data", "observed_data", "log_likelihood")


def posterior_attributes(idata) -> dict:
    """Attributes of every group of a posterior's InferenceData, merged (method, tempering, parameter_model, ...).

    Parameters
    ----------
    idata : arviz.InferenceData

    Returns
    -------
    dict, the attributes of the groups ``posterior``, ``sample_stats``, ``constant_data``, ``observed_data``
    and ``log_likelihood`` (those present), a later group's value winning.
    """
    out: dict = {}
    for group in _ATTRIBUTE_GROUPS:
        ds = getattr(idata, group, None)
        if ds is not None:
            out.update(dict(ds.attrs))
    return out


def _open_posterior(path: Path, arrays: bool = False):
    """Open ``path`` as an InferenceData (or, with ``arrays``, an :class:`~.netcdf.ArrayData`): the one place a
    posterior.nc is read (tests count calls of it)."""
    return read_netcdf_arrays(path) if arrays else read_netcdf(path)


def _schema_version(idata, path: Path) -> int:
    """The schema version of an opened posterior.nc; :class:`DataError` for one this version cannot read."""
    v = idata.attrs.get(SCHEMA_ATTRIBUTE)
    if v is None:
        return 1
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        shown = repr(v) if isinstance(v, str) else str(v)
        raise DataError(f"{path}: posterior.nc schema version {shown} is not an integer (attribute "
                        f"{SCHEMA_ATTRIBUTE}); the file was not written by bayes_rcsa")
    v = int(v)
    if v > SCHEMA_VERSION:
        raise DataError(f"{path}: posterior.nc schema version {v} is newer than this bayes_rcsa reads "
                        f"({SCHEMA_VERSION}); update bayes_rcsa")
    if v < 1:
        raise DataError(f"{path}: posterior.nc schema version {v} is not a version of bayes_rcsa's (1 to "
                        f"{SCHEMA_VERSION})")
    return v


def read_posterior(path, option: str | None = "--posterior", arrays: bool = False):
    """The InferenceData of a ``posterior.nc``, checked.

    Parameters
    ----------
    path : path-like
    option : str or None
        The command-line option that named the file.  A missing file is then
        the command's ``SetupError`` ``"{option} {path}: no such file
        (posterior.nc written by 'bayes-rcsa identify')"``; with ``None`` it
        is the library's ``DataError`` ``"{path}: posterior file not found
        (...)"``.
    arrays : bool
        Read the numbers only, with h5py (:func:`~.netcdf.read_netcdf_arrays`: no ArviZ, xarray or scipy
        import), for a reader that needs the draws and attributes and not an ``arviz.InferenceData``.

    Returns
    -------
    arviz.InferenceData, or :class:`~.netcdf.ArrayData` with ``arrays``

    Raises
    ------
    SetupError
        Missing file, with ``option``.
    DataError
        Missing file (``option=None``), a file netCDF cannot read, a file
        without a ``posterior`` group, or a schema version newer than
        :data:`SCHEMA_VERSION` (or not a positive integer).
    """
    path = Path(path)
    if not path.is_file():
        if option:
            raise SetupError(f"{option} {path}: no such file (posterior.nc written by 'bayes-rcsa identify')")
        raise DataError(f"{path}: posterior file not found (expected DIR/posterior.nc written by 'bayes-rcsa identify')")
    try:
        idata = _open_posterior(path, arrays)
    except Exception as exc:  # netCDF/HDF5 readers raise many unrelated types
        raise DataError(f"{path}: cannot read as an ArviZ InferenceData netCDF file ({exc})") from None
    _schema_version(idata, path)
    if getattr(idata, "posterior", None) is None:
        raise DataError(f"{path}: no 'posterior' group")
    return idata


def _with_schema(attrs: Mapping) -> dict:
    out = dict(attrs)
    out[SCHEMA_ATTRIBUTE] = SCHEMA_VERSION
    return out


def write_posterior(idata, path) -> Path:
    """Write ``idata`` as the ``posterior.nc`` ``path`` and return ``path``.

    Atomic (no partial file on failure) and compressed as
    :func:`bayes_rcsa.store.write_netcdf` (zlib + shuffle, the pointwise
    log-likelihood as float32).  ``idata`` (an arviz.InferenceData) is not
    modified; the file's root attributes are ``idata.attrs`` plus
    :data:`SCHEMA_ATTRIBUTE` = :data:`SCHEMA_VERSION`.
    """
    return _write_groups(_groups(idata), _with_schema(idata.attrs), Path(path))


def _attribute_value(v):
    # netCDF attributes are numbers or text: booleans as 0/1, anything else (lists, dicts) as JSON
    if isinstance(v, bool):
        return int(v)
    return v if isinstance(v, (int, float, str)) else json.dumps(v)


def append_to_posterior(path, *, posterior_vars: Mapping[str, np.ndarray] | None = None,
                        groups: Mapping[str, object] | None = None,
                        attrs: Mapping[str, object] | None = None) -> Path:
    """Add variables, groups and attributes to an existing ``posterior.nc``; everything else is kept.

    The file is rewritten atomically (no partial file on failure) with the
    current :data:`SCHEMA_VERSION`.

    Parameters
    ----------
    path : path-like, an existing posterior.nc
    posterior_vars : {name: array}, optional
        New (or replaced) variables of the ``posterior`` group, one value per
        draw: either (n_chain * n_draw,) in the chain-flattened order of
        :func:`bayes_rcsa.posterior.load_posterior` or (n_chain, n_draw).
    groups : {name: xarray.Dataset}, optional
        Groups added to the file (a group of the same name is replaced).
    attrs : dict, optional
        Attributes added to the ``posterior`` group (read back by
        :func:`posterior_attributes`); booleans are stored as 0/1, values
        other than numbers and text as JSON text.

    Returns
    -------
    Path, ``path``

    Raises
    ------
    DataError
        As :func:`read_posterior`, or an array whose size is not the
        posterior's number of draws.
    """
    path = Path(path)
    idata = read_posterior(path, option=None)
    post = idata.posterior
    shape = (int(post.sizes["chain"]), int(post.sizes["draw"]))
    new = {}
    for name, values in (posterior_vars or {}).items():
        a = np.asarray(values)
        if a.shape not in (shape, (shape[0] * shape[1],)):
            raise DataError(f"{path}: {name} has shape {a.shape}; expected {shape[0] * shape[1]} draws as "
                            f"(chain, draw) = {shape} or flattened")
        new[name] = (("chain", "draw"), a.reshape(shape))
    post = post.assign(new)
    if attrs:
        post = post.assign_attrs({k: _attribute_value(v) for k, v in attrs.items()})
    out = _groups(idata)
    out["posterior"] = post
    out.update(dict(groups or {}))
    return write_posterior(_inference_data(out, idata.attrs), path)
