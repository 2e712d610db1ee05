"""ArviZ InferenceData netCDF files: the one writer and reader of the package's ``.nc`` files.

The layout is ArviZ's (one netCDF group per InferenceData group, the
InferenceData's own attributes on the root group), written with h5netcdf
and read by :func:`arviz.from_netcdf`.  Every numeric variable is
zlib-compressed after the byte shuffle (lossless), and the pointwise
log-likelihood is stored in single precision (:data:`LOG_LIKELIHOOD_DTYPE`).

``posterior.nc`` has its own schema on top of this (:mod:`.posterior_file`);
other InferenceData files (a tool library's ``population.nc``) use
:func:`write_netcdf` and :func:`read_netcdf` directly.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Mapping

from ..io.atomic import atomic_path

__all__ = ["COMPRESSION", "LOG_LIKELIHOOD_DTYPE", "write_netcdf", "read_netcdf"]

#: Compression of every numeric variable: zlib (lossless) after the byte shuffle, which groups the slowly
#: varying exponent bytes of neighbouring floats and gains ~16 % over zlib alone on the draws.
COMPRESSION = {"zlib": True, "complevel": 4, "shuffle": True}

#: The pointwise log-likelihood (walkers x draws x lines, ~90 % of a posterior.nc) is stored in single precision:
#: relative error 6e-8, i.e. < 2e-6 nats per line for |log p| < 30 and < 2e-3 nats summed over 1000 lines,
#: far below the differences of order 1 nat that LOO/WAIC comparisons read.  Everything else stays float64.
LOG_LIKELIHOOD_DTYPE = "float32"


def _az():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # arviz announces its 1.0 refactor on import
        import arviz

    return arviz


def _encoding(group: str, dataset) -> dict:
    enc = {}
    for name, var in dataset.variables.items():
        kind = var.dtype.kind
        if kind not in "fiub":
            continue  # strings and objects (coordinate labels) are stored as they are
        e = dict(COMPRESSION)
        if group == "log_likelihood" and kind == "f" and name not in dataset.coords:
            e["dtype"] = LOG_LIKELIHOOD_DTYPE
        enc[name] = e
    return enc


def _write_groups(groups: Mapping[str, object], root_attrs: Mapping[str, object], path: Path) -> Path:
    """Write ``groups`` (name -> xarray.Dataset, in file order) and the root attributes atomically."""
    import xarray as xr

    with atomic_path(path) as tmp:
        xr.Dataset(attrs=dict(root_attrs)).to_netcdf(str(tmp), mode="w", engine="h5netcdf")
        for group, ds in groups.items():
            if group == "log_likelihood":
                ds = ds.assign_attrs(stored_dtype=LOG_LIKELIHOOD_DTYPE)
            ds.to_netcdf(str(tmp), mode="a", group=group, engine="h5netcdf", encoding=_encoding(group, ds))
    return path


def _groups(idata) -> dict:
    """``{group name: xarray.Dataset}`` of an InferenceData, in its order."""
    return {g: getattr(idata, g) for g in idata.groups()}


def write_netcdf(idata, path) -> Path:
    """Write ``idata`` to ``path`` atomically (no partial file on failure), compressed.

    Parameters
    ----------
    idata : arviz.InferenceData
    path : path-like

    Returns
    -------
    Path, ``path``

    Notes
    -----
    The pointwise log-likelihood is stored as ``float32`` (recorded in its
    group's ``stored_dtype`` attribute); see :data:`LOG_LIKELIHOOD_DTYPE`.
    A ``posterior.nc`` is written by :func:`bayes_rcsa.store.write_posterior`
    instead, which adds the schema version.
    """
    return _write_groups(_groups(idata), idata.attrs, Path(path))


def read_netcdf(path):
    """Read an InferenceData file written by :func:`write_netcdf` (no checks; see :func:`bayes_rcsa.store.read_posterior`).

    Parameters
    ----------
    path : path-like

    Returns
    -------
    arviz.InferenceData
    """
    return _az().from_netcdf(str(path))


def _inference_data(groups: Mapping[str, object], attrs: Mapping[str, object]):
    """An :class:`arviz.InferenceData` of ``groups`` (name -> xarray.Dataset) with root attributes ``attrs``."""
    return _az().InferenceData(attrs=dict(attrs), **dict(groups))
