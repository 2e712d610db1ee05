"""Posterior draws in physical units, with the parameter model they belong to.

Predictions need, per draw, the physical value of every parameter of the
fit (contact stiffness and damping at the reference length, growth factors,
model-term parameters) plus the :class:`~bayes_rcsa.params.ParameterModel`
that carries them to other clamping lengths and into the forward model.
They come either from an identification run in memory
(:func:`draws_from_result`) or from the ``posterior.nc`` it wrote
(:func:`load_posterior`).

``posterior.nc`` stores the sampled parameters as variables and the whole
parameter model (priors, fixed values, growth law, model terms) as the JSON
attribute ``parameter_model``.  Fixed parameters (e.g. a fixed contact
damping) are taken from there, never from the setup: a setup edited after
the fit cannot change what the posterior means.  When a setup is passed,
:func:`load_posterior` compares it with the recorded model and lists the
differences as notes (the products write them into their JSON outputs).
Files without the attribute were written by an older version and are
refused with a :class:`DataError` (rerun ``identify``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import DataError, SetupError
from ..params.growth import GrowthLaw
from ..params.model import CONTACT_NAMES, PARAMETER_MODEL_ATTR, ParameterModel
from ..params.terms import Contact
from ..store import posterior_attributes, read_posterior

__all__ = ["CONTACT_NAMES", "PARAMETER_MODEL_ATTR", "PosteriorDraws", "draws_from_result", "load_posterior",
           "setup_differences"]


@dataclass(frozen=True)
class PosteriorDraws:
    """Flat posterior draws of a fit's parameters.

    Attributes
    ----------
    parameters : ParameterModel
        What was sampled and fixed, the growth law and the model terms.
    values : dict of str to (n_draws,) float
        Physical values of every non-noise parameter of ``parameters``
        (fixed ones repeated; filled in from the model when absent), plus
        the noise scales when available.
    method : str
        Identification method (``"multi"``, ``"single"``, ...).
    fit_lengths : tuple of float
        m, clamping lengths of the measurements used in the fit.
    source : str
        Where the draws came from (file name or ``"memory"``).
    parameter_model_source : str
        ``"posterior"`` when the parameter model was read from posterior.nc,
        ``"memory"`` for an in-memory fit.
    notes : tuple of str
        Fixed values taken from the posterior and differences between the
        setup and the recorded model (for the products' outputs).

    Notes
    -----
    Stable API: ``parameters``, ``values``, ``growth``, ``sampled``,
    ``n_draws``, :meth:`contact`, :meth:`take`, :meth:`subset`,
    :meth:`median_values`, :meth:`provenance`.
    """

    parameters: ParameterModel
    values: Mapping[str, np.ndarray]
    method: str = "multi"
    fit_lengths: tuple[float, ...] = ()
    source: str = "memory"
    parameter_model_source: str = "memory"
    notes: tuple[str, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        pm = self.parameters
        if not isinstance(pm, ParameterModel):
            raise SetupError(f"{self.source}: PosteriorDraws needs a ParameterModel, got {type(pm).__name__}")
        values = {n: np.asarray(v, dtype=float).reshape(-1) for n, v in self.values.items()}
        missing = [n for n in pm.names if n not in values and pm[n].role != "noise"]
        if missing:
            raise DataError(f"{self.source}: posterior draws lack the sampled parameter(s) {missing}")
        sizes = {v.shape for v in values.values()}
        if len(sizes) != 1 or next(iter(sizes))[0] == 0:
            raise DataError(f"{self.source}: posterior draws must be non-empty 1-D arrays of one length, got shapes {sizes}")
        n = next(iter(sizes))[0]
        for name, v in pm.fixed.items():
            values.setdefault(name, np.full(n, v))
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "notes", tuple(self.notes))

    @property
    def growth(self) -> GrowthLaw:
        return self.parameters.growth

    @property
    def sampled(self) -> tuple[str, ...]:
        """Sampled parameters other than noise scales (contact, growth, model terms), in vector order."""
        return self.parameters.physical_names

    @property
    def n_draws(self) -> int:
        return int(next(iter(self.values.values())).size)

    def contact(self, lengths) -> Contact:
        """Contact parameters of every draw at ``lengths`` (growth law and joint terms).

        Parameters
        ----------
        lengths : (n_len,) m

        Returns
        -------
        Contact
            ``k_xf``, ``k_thetaM``, ``c_xf``, ``c_thetaM``, each (n_draws, n_len); unpacks like a tuple.
        """
        return self.parameters.contact(self.values, lengths)

    def take(self, index) -> "PosteriorDraws":
        """The draws at ``index`` (an integer array or slice)."""
        values = {n: np.asarray(v)[index] for n, v in self.values.items()}
        return PosteriorDraws(self.parameters, values, self.method, self.fit_lengths, self.source,
                              self.parameter_model_source, self.notes)

    def subset(self, max_draws: int | None, rng: np.random.Generator | None) -> "PosteriorDraws":
        """At most ``max_draws`` draws chosen at random without replacement (all if fewer)."""
        if max_draws is None or self.n_draws <= max_draws:
            return self
        if max_draws < 1:
            raise SetupError(f"max_draws = {max_draws!r}: expected a positive integer")
        if rng is None:
            raise SetupError("a random subset of posterior draws needs an explicit numpy.random.Generator")
        return self.take(np.sort(rng.choice(self.n_draws, max_draws, replace=False)))

    def median_values(self) -> dict[str, float]:
        """Posterior median of every non-noise parameter (physical units)."""
        return {n: float(np.median(self.values[n])) for n in self.parameters.all_names
                if self.parameters[n].role != "noise" and n in self.values}

    def provenance(self) -> dict:
        """Where the parameter model came from, for the products' JSON outputs."""
        return {
            "parameter_model_source": self.parameter_model_source,
            "parameter_model_notes": list(self.notes),
            "fixed_parameters": dict(self.parameters.fixed),
            "model_terms": list(self.parameters.term_names),
        }


def draws_from_result(result) -> PosteriorDraws:
    """Draws of an :class:`bayes_rcsa.inference.identify.IdentificationResult` in memory."""
    problem = result.problem
    pm = problem.parameters
    values = pm.values(result.flat_theta)
    lengths = tuple(sorted({float(o.configuration.clamping_length) for o in problem.observations}))
    return PosteriorDraws(pm, values, problem.method, lengths, "memory", "memory")


def _fmt(v) -> str:
    return f"{v:.6g}" if isinstance(v, float) else repr(v)


def setup_differences(pm: ParameterModel, setup) -> list[str]:
    """Differences between a setup's ``[contact]``/``[model]`` and a recorded parameter model.

    One warning line per differing key, naming the key, both values and
    that the posterior's value is used.
    """
    out = []
    contact = getattr(setup, "contact", None)
    where = getattr(setup, "path", "the setup")
    if contact is not None:
        for key, name in (("translational_damping", "c_xf"), ("rotational_damping", "c_thetaM")):
            spec = getattr(contact, key, None)
            if spec is None or name not in pm:
                continue
            p = pm[name]
            if isinstance(spec, (list, tuple)):
                if not p.sampled:
                    out.append(f"warning: {where} [contact] {key} = {list(spec)} (sampled), but the fit held {name} fixed "
                               f"at {_fmt(p.value)}; using the posterior's value")
                elif p.prior.describe().get("lo") is not None and [p.prior.describe()["lo"], p.prior.describe()["hi"]] != [
                        float(v) for v in spec]:
                    out.append(f"warning: {where} [contact] {key} = {list(spec)} differs from the fit's prior of {name} "
                               f"{p.prior.describe()}; using the posterior")
            else:
                if p.sampled:
                    out.append(f"warning: {where} [contact] {key} = {_fmt(float(spec))} (fixed), but the fit sampled "
                               f"{name}; using the posterior's draws")
                elif float(spec) != p.value:
                    out.append(f"warning: {where} [contact] {key} = {_fmt(float(spec))} differs from the fit's fixed "
                               f"{name} = {_fmt(p.value)}; using the posterior's value")
        for key, name in (("translational_stiffness", "k_xf"), ("rotational_stiffness", "k_thetaM")):
            spec = getattr(contact, key, None)
            if spec is None or name not in pm or not pm[name].sampled:
                continue
            d = pm[name].prior.describe()
            if d.get("distribution") == "log-uniform" and [d["lo"], d["hi"]] != [float(v) for v in spec]:
                out.append(f"warning: {where} [contact] {key} = {list(spec)} differs from the fit's prior of {name} "
                           f"[{_fmt(d['lo'])}, {_fmt(d['hi'])}]; using the posterior")
        q = getattr(contact, "growth_bound", None)
        if q is not None and pm.growth.has_growth and float(q) != pm.growth.growth_bound:
            out.append(f"warning: {where} [contact] growth_bound = {_fmt(float(q))} differs from the fit's "
                       f"Q = {_fmt(pm.growth.growth_bound)}; using the posterior")
    extra = getattr(setup, "extra", None) or {}
    table = getattr(setup, "model_table", None) or extra.get("model") or {}
    terms = list(table.get("terms", [])) if isinstance(table, Mapping) else []
    if terms != list(pm.term_names) and (terms or pm.term_names):
        out.append(f"warning: {where} [model] terms = {terms} differ from the fit's terms {list(pm.term_names)}; "
                   f"using the posterior's")
    return out


def load_posterior(path, setup=None, inference_data=None) -> PosteriorDraws:
    """Read the draws and the parameter model of a ``posterior.nc`` written by ``bayes-rcsa identify``.

    Parameters
    ----------
    path : path-like
    setup : Setup, optional
        Only compared with the recorded model: differences (e.g. a
        ``[contact]`` damping edited after the fit) become warning notes;
        the posterior's values are always used.
    inference_data : arviz.InferenceData, optional
        The file's content when the caller has read it already (the file is then not opened again).

    Raises
    ------
    DataError
        The file is missing, unreadable, of a newer schema version
        (:func:`bayes_rcsa.store.read_posterior`) or not a bayes_rcsa
        posterior, or lacks the parameter model (an older version wrote it)
        or a sampled parameter.
    """
    path = Path(path)
    idata = read_posterior(path, option=None, arrays=True) if inference_data is None else inference_data
    post = getattr(idata, "posterior", None)
    if post is None:
        raise DataError(f"{path}: no 'posterior' group")
    attrs = posterior_attributes(idata)
    if PARAMETER_MODEL_ATTR not in attrs:
        raise DataError(f"{path}: attribute {PARAMETER_MODEL_ATTR!r} (the fit's parameter model) missing; the file was "
                        f"written by an older bayes_rcsa or another program; rerun 'bayes-rcsa identify'")
    try:
        d = json.loads(str(attrs[PARAMETER_MODEL_ATTR]))
    except ValueError as exc:
        raise DataError(f"{path}: attribute {PARAMETER_MODEL_ATTR!r} is not valid JSON ({exc})") from None
    pm = ParameterModel.from_dict(d, f"{path}: {PARAMETER_MODEL_ATTR}")
    values: dict[str, np.ndarray] = {}
    for name in pm.names:
        if name not in post.data_vars:
            if pm[name].role == "noise":
                continue
            raise DataError(f"{path}: sampled parameter {name!r} of the parameter model has no draws in the posterior")
        values[name] = np.asarray(post[name].values, dtype=float).reshape(-1)
    for name in ("k_xf", "k_thetaM"):
        if name in values and not np.all(np.isfinite(values[name]) & (values[name] > 0)):
            raise DataError(f"{path}: {name} draws must be finite and positive")
    fit_lengths: tuple[float, ...] = ()
    const = getattr(idata, "constant_data", None)
    if const is not None and "fit_clamping_length" in const.data_vars:
        fit_lengths = tuple(sorted({float(v) for v in np.asarray(const["fit_clamping_length"].values).ravel()}))
    notes = [f"{n} = {_fmt(v)} {pm.unit(n)} (fixed in the fit; value taken from {path.name})"
             for n, v in pm.fixed.items()]
    if setup is not None:
        notes += setup_differences(pm, setup)
    return PosteriorDraws(pm, values, str(attrs.get("method", "multi")), fit_lengths, str(path), "posterior",
                          tuple(notes))
