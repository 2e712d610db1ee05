"""The update's files: ``DIR/posterior.nc`` (draws with K_t/K_r) and ``DIR/update.json``.

``posterior.nc`` is an ordinary posterior (``predict``, ``lobes``, ``report``
read it): the parameter model of the draws (with growth factors drawn from
the growth law's prior when a single-length fit was carried to another
length), the resampled physical draws as one chain, the hammer posterior's
``constant_data`` (fit lengths, bands) and attributes, plus

- ``cutting_kt_pa``, ``cutting_kr_pa`` (Pa): the cutting coefficients of every draw, which ``lobes`` uses unless
  ``--kt``/``--kr`` are given;
- ``cut_boundary_width``: the boundary width of every draw;
- attributes ``created_by = "bayes_rcsa update"``, ``hammer_posterior``, ``cuts_file``, ``n_cuts``.

The hammer posterior's pointwise log-likelihood and sampler statistics are
not copied: they describe the hammer chains, not the resampled draws.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write_text
from ..io.jsonable import dumps_strict
from ..stability.coefficients import COEFFICIENT_VARIABLES

__all__ = ["COEFFICIENT_VARIABLES", "write_updated_posterior", "write_update_json"]


def write_updated_posterior(path, hammer_posterior, draws, result, attrs: dict) -> Path:
    """Write the resampled draws of ``result`` as ``path``.

    Parameters
    ----------
    path : output path (posterior.nc)
    hammer_posterior : path of the hammer posterior.nc (its constant_data and attributes are kept)
    draws : PosteriorDraws the particles refer to (after the length transfer)
    result : UpdateResult
    attrs : dict, extra attributes (JSON-able values are stored as text)
    """
    import xarray as xr

    from ..params.model import PARAMETER_MODEL_ATTR
    from ..store import posterior_attributes, read_posterior, write_posterior

    idata = read_posterior(hammer_posterior, option=None)
    pm = draws.parameters
    n = int(result.draw.size)
    dims = ("chain", "draw")
    data = {name: (dims, np.asarray(draws.values[name])[result.draw][None, :]) for name in pm.names
            if name in draws.values}
    data[COEFFICIENT_VARIABLES[0]] = (dims, result.kt[None, :])
    data[COEFFICIENT_VARIABLES[1]] = (dims, result.kr[None, :])
    data["cut_boundary_width"] = (dims, result.width[None, :])
    base = {k: v for k, v in posterior_attributes(idata).items()}
    base.update({PARAMETER_MODEL_ATTR: json.dumps(pm.to_dict()), "created_by": "bayes_rcsa update",
                 "hammer_posterior": str(hammer_posterior)})
    base.update({k: (v if isinstance(v, (int, float, str)) else json.dumps(v)) for k, v in attrs.items()})
    base = {k: (int(v) if isinstance(v, bool) else v) for k, v in base.items()}
    post = xr.Dataset(data, coords={"chain": [0], "draw": np.arange(n)}, attrs=base)
    groups = {"posterior": post}
    const = getattr(idata, "constant_data", None)
    if const is not None:
        groups["constant_data"] = const.assign_attrs(base)
    return write_posterior(type(idata)(**groups), Path(path))


def write_update_json(path, document: dict) -> Path:
    """``update.json`` (strict JSON: non-finite numbers as null), atomically."""
    atomic_write_text(Path(path), dumps_strict(document, indent=2) + "\n")
    return Path(path)
