"""Diagnostics and the InferenceData of a fit: R-hat/ESS of a chain, :func:`build_inference_data`.

Together with :mod:`bayes_rcsa.store.netcdf` (which writes and reads the
netCDF files) this is the only module of the package that imports
:mod:`arviz` (its import is slow and its API moves between versions), and
only where an :class:`arviz.InferenceData` is asked for.  R-hat and ESS are
the package's own implementation of the same estimators
(:mod:`bayes_rcsa.stats.convergence`), so that sampling and judging a chain
never loads ArviZ.

Walkers of the ensemble are treated as *chains*.  They are not
independent chains, but after the burn-in they are exchangeable draws of
the posterior, and the rank-normalised split R-hat across walkers detects
walkers that have not mixed (e.g. stuck in a second mode).
"""

from __future__ import annotations

import contextlib
import warnings
from typing import Mapping, Sequence

import numpy as np

from ..stats.convergence import convergence_diagnostics

__all__ = ["chain_diagnostics", "build_inference_data", "inference_data_from_dict", "InferenceGroups"]


def _az():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)  # arviz announces its 1.0 refactor on import
        import arviz

    return arviz


@contextlib.contextmanager
def _walkers_as_chains():
    """Silence ArviZ's "More chains than draws" for the one call it wraps.

    Every emcee walker is a chain of ArviZ's (chain, draw) layout, so a short run (or a thinned one) can
    have more walkers than kept draws on purpose; the shape is right and the warning would reach the
    user's terminal without reaching the JSON outputs.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="More chains", category=UserWarning)
        yield


def chain_diagnostics(chain: np.ndarray) -> dict[str, np.ndarray]:
    """Rank-normalised split R-hat, bulk and tail ESS of each coordinate (walkers as chains).

    :func:`bayes_rcsa.stats.convergence.convergence_diagnostics` (the estimators of ArviZ's ``rhat`` and ``ess``,
    without importing it).

    Parameters
    ----------
    chain : (n_steps, n_walkers, ndim)

    Returns
    -------
    dict with ``"rhat"``, ``"ess_bulk"``, ``"ess_tail"``, each (ndim,); NaN for fewer than 4 steps
    """
    chain = np.asarray(chain, dtype=float)
    return convergence_diagnostics(np.transpose(chain, (2, 1, 0)))


class InferenceGroups:
    """The groups of an InferenceData as plain arrays, built without importing ArviZ or xarray.

    What :func:`bayes_rcsa.store.write_posterior` needs (``groups()``, ``contents``: group name ->
    :class:`bayes_rcsa.store.netcdf.GroupContent`, ``attrs``) in ArviZ's layout; a group read as an attribute is
    an ``xarray.Dataset``, and :meth:`to_inference_data` makes the :class:`arviz.InferenceData`.  Importing
    ArviZ costs 2-4 s of start-up (matplotlib, scipy.stats, a numba compilation) and xarray another second
    (pandas, dask.array), more than an importance-sampled identification; writing ``posterior.nc`` needs neither.
    """

    def __init__(self, contents: Mapping[str, object], attrs: Mapping[str, object]):
        self.contents = dict(contents)
        self.attrs = dict(attrs)

    def groups(self) -> list[str]:
        return list(self.contents)

    def __getattr__(self, name: str):
        contents = self.__dict__.get("contents", {})
        if name in contents:
            return contents[name].to_dataset()
        raise AttributeError(name)

    def to_inference_data(self):
        """The :class:`arviz.InferenceData` of these groups (imports ArviZ)."""
        return _az().InferenceData(attrs=dict(self.attrs), **{g: c.to_dataset() for g, c in self.contents.items()})


def _group(data: Mapping[str, np.ndarray], dims: Mapping[str, Sequence[str]], coords: Mapping[str, object],
             sampled: bool, attrs: Mapping[str, object]):
    """One group as ArviZ's ``from_dict`` lays it out (a :class:`~bayes_rcsa.store.netcdf.GroupContent`):
    ``(chain, draw, ...)`` for sampled groups, named dims or ``<var>_dim_<i>``, integer coordinates where none
    is given, each variable after the coordinates it brings, ``created_at`` and ``arviz_version`` first."""
    import datetime
    from importlib.metadata import PackageNotFoundError, version

    from ..store.netcdf import GroupContent

    try:
        az_version = version("arviz")
    except PackageNotFoundError:  # pragma: no cover - arviz is a dependency
        az_version = ""
    variables = {}
    for name, values in data.items():
        values = np.asarray(values)
        base = ["chain", "draw"] if sampled else []
        named = list(dims.get(name, ()))
        names = base + named + [f"{name}_dim_{i}" for i in range(len(named), values.ndim - len(base))]
        for axis, dim in enumerate(names):
            if dim not in variables:
                variables[dim] = ((dim,), np.asarray(coords[dim]) if dim in coords else np.arange(values.shape[axis]),
                                  {})
        variables[name] = (tuple(names), values, {})
    head = {"created_at": datetime.datetime.now(datetime.timezone.utc).isoformat(), "arviz_version": az_version}
    return GroupContent(variables, {**head, **attrs})


def build_inference_data(
    posterior: Mapping[str, np.ndarray],
    log_prob: np.ndarray,
    log_likelihood: np.ndarray,
    observed: np.ndarray,
    constant: Mapping[str, np.ndarray],
    dims: Mapping[str, Sequence[str]],
    coords: Mapping[str, np.ndarray],
    attrs: Mapping[str, object],
) -> InferenceGroups:
    """The InferenceData groups of a fit, in ArviZ's ``from_dict`` layout (:class:`InferenceGroups`).

    Parameters
    ----------
    posterior : {name: (n_walkers, n_draws, ...)}
        Physical parameter values and derived quantities.
    log_prob : (n_walkers, n_draws) log posterior (as sampled)
    log_likelihood : (n_walkers, n_draws, n_lines) pointwise log-likelihood
    observed : (n_lines,) complex measured FRF on the band lines
    constant : {name: array} e.g. frequencies, clamping lengths
    dims, coords : ArviZ dims and coords of the named variables
    attrs : attributes of the data groups and of the file (method, seed, ...), as ``from_dict`` places them
    """
    observed = np.asarray(observed)
    dims = {**dict(dims), "frf": ["line"], "frf_real": ["line"], "frf_imag": ["line"]}
    coords = dict(coords)
    attrs = {k: _attr(v) for k, v in attrs.items()}
    groups = {
        "posterior": _group(posterior, dims, coords, True, {}),
        "log_likelihood": _group({"frf": np.asarray(log_likelihood)}, dims, coords, True, {}),
        "sample_stats": _group({"lp": np.asarray(log_prob)}, dims, coords, True, {}),
        "observed_data": _group({"frf_real": observed.real, "frf_imag": observed.imag}, dims, coords, False, attrs),
        "constant_data": _group(dict(constant), dims, coords, False, attrs),
    }
    return InferenceGroups(groups, attrs)


def inference_data_from_dict(**groups):
    """:func:`arviz.from_dict` for the other packages' netCDF files (the population of a tool library, ...).

    Keeps the ArviZ import in this module, and walkers or hyperparameter chains laid out as ArviZ chains
    without its "More chains than draws" warning.
    """
    az = _az()
    with _walkers_as_chains():
        return az.from_dict(**groups)


def _attr(v):
    # netCDF attributes must be strings, numbers or 1-D arrays of them
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, (int, float, str)):
        return v
    if v is None:
        return ""
    return str(v)
