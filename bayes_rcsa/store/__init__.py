"""The files of a fit: the one owner of ``posterior.nc`` and the package's other InferenceData netCDF files.

- :mod:`.posterior_file`: the ``posterior.nc`` schema (version attribute), :func:`write_posterior`,
  :func:`read_posterior` (every read of a posterior.nc in the package), :func:`append_to_posterior` and
  :func:`posterior_attributes`;
- :mod:`.netcdf`: the generic compressed InferenceData writer and reader (:func:`write_netcdf`,
  :func:`read_netcdf`; a tool library's ``population.nc``).

No other module of the package opens a ``.nc`` file (tests/test_store.py checks it).  ArviZ and xarray are
imported when a file is read or written, not with this package.
"""

from .netcdf import read_netcdf, write_netcdf
from .posterior_file import (
    SCHEMA_ATTRIBUTE,
    SCHEMA_VERSION,
    append_to_posterior,
    posterior_attributes,
    read_posterior,
    write_posterior,
)

__all__ = ["SCHEMA_VERSION", "SCHEMA_ATTRIBUTE", "write_posterior", "read_posterior", "append_to_posterior",
           "write_netcdf", "read_netcdf", "posterior_attributes"]
