"""Assemble an identification problem: which measurements, bands, priors, likelihood.

Methods
-------
``multi`` (default)
    All selected measurements at once.  With two or more distinct clamping
    lengths this is the paper's Method II: ``k(l)`` follows the bounded
    linear growth law over the feasible range ``[l_a, l_b]`` and the
    sampled stiffness is ``k(l_a)``.  With a single clamping length (several
    tools, or one tool) it is Method I: one contact stiffness shared by all
    measurements, no growth parameters.
``single``
    The literature method: exactly one clamping length, one constant
    contact stiffness, which predictions then transfer unchanged to other
    lengths.
``deterministic``
    The paper's deterministic baseline (:mod:`.deterministic`) with the
    same parameterisation as ``multi`` (so one length gives the classical
    single-length fit).

Setup tables read here (all optional)
-------------------------------------
``[likelihood]``: ``band = [lo, hi]`` (Hz, replaces the default rule),
``band_ratio`` (1.25), ``band_rel_height`` (0.5), ``noise_floor`` (0.01),
``min_coherence`` (0.05), ``tempering`` (``"auto"`` or a number in (0, 1]),
``noise_scale = [lo, hi]`` (log-uniform bounds of the relative noise
scales, default ``[1e-4, 10]``).

``[priors]``: replaces the prior of ``k_xf``, ``k_thetaM``, ``g_xf``,
``g_thetaM``, ``c_xf`` or ``c_thetaM`` by a table, e.g.
``k_xf = {distribution = "log-normal", median = 2e6, sigma = 0.5}``.

``[model]``: ``terms = ["tip_mass", ...]`` adds registered model terms
(:mod:`bayes_rcsa.params.terms`); any other key names a parameter of the
model (a term's, or a contact parameter) and gives its prior with the syntax
of ``[priors]`` (a ``[lo, hi]`` pair means the parameter's default kind of
prior) or a number to hold it fixed.

The result's :class:`~bayes_rcsa.params.ParameterModel` is the single
description of what is sampled and fixed; it is written into posterior.nc.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Mapping, Sequence

from ..errors import SetupError
from ..io.setup import ContactSpec, Setup
from ..model.assembly import Configuration, ToolPointModel
from ..model.receptance import FRF
from ..params.growth import GrowthLaw
from ..params.model import CONTACT_NAMES, ParameterModel, contact_parameter, noise_name, term_parameters
from ..params.parameter import Parameter
from ..params.priors import JointNormal, LogUniform, Prior, PriorSet, Uniform, prior_from_spec
from ..params.terms import make_term
from .band import Band, resolve_band
from .likelihood import FRFLikelihood, NoiseModel, make_observation
from .posterior import LikelihoodTerm, LogPosterior

__all__ = ["METHODS", "IdentificationOptions", "Problem", "build_problem", "build_problem_from_setup", "select_measurements"]

METHODS = ("multi", "single", "deterministic")

_LENGTH_MATCH = 1e-7  # m; lengths given in mm on the command line match file values to 0.1 um


@dataclass(frozen=True)
class IdentificationOptions:
    """Choices that are not part of the physical model.

    Attributes
    ----------
    method : {"multi", "single", "deterministic"}
    lengths : tuple of float or None
        m; use only measurements at these clamping lengths.
    band : (lo, hi) Hz or None
        Overrides the default band rule.
    band_ratio, band_rel_height : float
        Parameters of the default band rule (:mod:`.band`).
    noise_floor, min_coherence : float
        Noise model (:mod:`.likelihood`).
    tempering : "auto" or float
        ``"auto"``: ``1 / residual correlation length`` at the optimum.
    noise_scale : (lo, hi)
        Log-uniform prior bounds of the relative noise scales.
    priors : mapping
        User prior tables (``[priors]``).
    model : mapping
        The setup's ``[model]`` table: ``terms`` and per-parameter prior
        overrides or fixed values.
    start : mapping or None
        Physical parameter values to start the walkers around (``[sampler]
        start``) instead of the global optimum.
    contact_prior : JointNormal or None
        A joint prior over some of the contact parameters (e.g. a tool
        library's population predictive, :mod:`bayes_rcsa.library`); it
        replaces their ``[contact]``/``[priors]`` priors.  Needs
        ``contact_growth``.
    contact_growth : GrowthLaw or None
        The growth law the joint prior's stiffness and growth factors refer
        to (its reference length ``l_a``); used even for a single clamping
        length, whose growth factors are then sampled from the joint prior.
    """

    method: str = "multi"
    lengths: tuple[float, ...] | None = None
    band: tuple[float, float] | None = None
    band_ratio: float = 1.25
    band_rel_height: float = 0.5
    noise_floor: float = 0.01
    min_coherence: float = 0.05
    tempering: Any = "auto"
    noise_scale: tuple[float, float] = (1e-4, 10.0)
    priors: Mapping[str, Any] = field(default_factory=dict)
    model: Mapping[str, Any] = field(default_factory=dict)
    start: Mapping[str, float] | None = None
    contact_prior: JointNormal | None = None
    contact_growth: GrowthLaw | None = None

    def __post_init__(self) -> None:
        if (self.contact_prior is None) != (self.contact_growth is None):
            raise SetupError("a joint contact prior needs the growth law it refers to (contact_growth), and vice versa")
        if self.contact_prior is not None and set(self.contact_prior.names) - set(CONTACT_NAMES):
            raise SetupError(f"joint contact prior over {list(self.contact_prior.names)}: expected contact parameters "
                             f"{list(CONTACT_NAMES)}")
        if self.method not in METHODS:
            raise SetupError(f"method = {self.method!r}: expected one of {METHODS}")
        t = self.tempering
        if not (t == "auto" or (isinstance(t, (int, float)) and not isinstance(t, bool) and 0 < t <= 1)):
            raise SetupError(f"likelihood tempering = {t!r}: expected \"auto\" or a number in (0, 1]")

    @classmethod
    def from_setup(cls, extra: Mapping[str, Any], **overrides) -> "IdentificationOptions":
        """Options from the setup's ``[likelihood]``, ``[priors]``, ``[model]`` and ``[sampler]`` tables.

        Keyword ``overrides`` (command-line values) win when not ``None``.
        """
        lik = dict(extra.get("likelihood", {}) or {})
        known = {"band", "band_ratio", "band_rel_height", "noise_floor", "min_coherence", "tempering", "noise_scale"}
        unknown = set(lik) - known
        if unknown:
            raise SetupError(f"[likelihood]: unknown key(s) {sorted(unknown)}; expected some of {sorted(known)}")
        kw: dict[str, Any] = {}
        for key in known:
            if key in lik:
                kw[key] = _tuple(lik[key], f"likelihood.{key}") if key in ("band", "noise_scale") else lik[key]
        for key in ("band_ratio", "band_rel_height", "noise_floor", "min_coherence"):
            if key in kw:
                kw[key] = _number(kw[key], f"likelihood.{key}")
        priors = dict(extra.get("priors", {}) or {})
        sampler = dict(extra.get("sampler", {}) or {})
        start = sampler.get("start")
        if start is not None and not isinstance(start, Mapping):
            raise SetupError(f"sampler.start = {start!r}: expected a table of parameter = value")
        kw["priors"] = priors
        model_table = extra.get("model", {}) or {}
        if not isinstance(model_table, Mapping):
            raise SetupError(f"[model] = {model_table!r}: expected a table (terms = [...], parameter = prior or value)")
        kw["model"] = dict(model_table)
        kw["start"] = None if start is None else {k: _number(v, f"sampler.start.{k}") for k, v in start.items()}
        kw.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**kw)


def _number(v, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise SetupError(f"{what} = {v!r}: expected a finite number")
    return float(v)


def _tuple(v, what: str) -> tuple[float, float]:
    if not isinstance(v, (list, tuple)) or len(v) != 2:
        raise SetupError(f"{what} = {v!r}: expected a [lo, hi] pair")
    return (_number(v[0], what), _number(v[1], what))


@dataclass(frozen=True)
class Problem:
    """A fully specified identification problem.

    Attributes
    ----------
    model : ToolPointModel
    method : str
    measurements : tuple of (Configuration, FRF)
        The measurements used in the fit.
    observations : tuple of Observation
        Their band lines.
    parameters : ParameterModel
        What is sampled and fixed, the growth law and the model terms.
    likelihood : FRFLikelihood
        Untempered (beta = 1).
    growth : GrowthLaw
    options : IdentificationOptions
    all_measurements : tuple of (Configuration, FRF)
        Every measurement of the setup (for transfer checks).
    extra_terms : tuple of LikelihoodTerm
        Likelihood terms of data other than the FRFs (e.g. cutting tests,
        :class:`bayes_rcsa.cuts.joint.CutTerm`), added untempered to every
        log posterior of the fit (:meth:`log_posterior`); empty by default.
    """

    model: ToolPointModel
    method: str
    measurements: tuple
    observations: tuple
    parameters: ParameterModel
    likelihood: FRFLikelihood
    growth: GrowthLaw
    options: IdentificationOptions
    all_measurements: tuple
    extra_terms: tuple = ()

    @property
    def priors(self) -> PriorSet:
        return self.parameters.priors

    def with_extra_terms(self, *terms: LikelihoodTerm) -> "Problem":
        """A copy of the problem whose log posterior also has ``terms`` (after the present ones)."""
        return replace(self, extra_terms=self.extra_terms + tuple(terms))

    def log_posterior(self, tempering: float | None = None) -> LogPosterior:
        """Priors + likelihood tempered by ``tempering`` (untempered if ``None``) + the extra terms.

        Parameters
        ----------
        tempering : float in (0, 1] or None
            The exponent beta of the FRF likelihood (:meth:`FRFLikelihood.with_tempering`).
        """
        likelihood = self.likelihood if tempering is None else self.likelihood.with_tempering(tempering)
        return LogPosterior(self.priors, likelihood, self.extra_terms)

    def band_of(self, frf: FRF) -> Band:
        o = self.options
        return resolve_band(frf, o.band, ratio=o.band_ratio, rel_height=o.band_rel_height)


def select_measurements(measurements: Sequence[tuple[Configuration, FRF]], lengths) -> tuple:
    """Measurements whose clamping length is one of ``lengths`` (all if ``None``).

    Raises
    ------
    SetupError
        If a requested length matches no measurement.
    """
    if lengths is None:
        return tuple(measurements)
    out = []
    for length in lengths:
        hits = [m for m in measurements if abs(m[0].clamping_length - length) < _LENGTH_MATCH]
        if not hits:
            have = sorted({round(m[0].clamping_length * 1e3, 6) for m in measurements})
            raise SetupError(f"--lengths: no measurement at clamping length {length * 1e3:g} mm; measured: {have} mm")
        out.extend(h for h in hits if h not in out)
    return tuple(sorted(out, key=lambda m: (m[0].clamping_length, m[0].tool, m[0].direction)))


def _damping(spec, name: str, user: Mapping[str, Any]) -> tuple[Prior | None, float | None]:
    if name in user:
        return prior_from_spec(user[name], f"priors.{name}"), None
    if isinstance(spec, (list, tuple)):
        return prior_from_spec(spec, f"contact.{name}"), None
    value = float(spec)
    if not (math.isfinite(value) and value >= 0):
        raise SetupError(f"contact damping {name} = {spec!r}: expected a number >= 0 or a [lo, hi] pair")
    return None, value


def build_problem(
    model: ToolPointModel,
    measurements: Sequence[tuple[Configuration, FRF]],
    contact: ContactSpec,
    options: IdentificationOptions = IdentificationOptions(),
) -> Problem:
    """Build the problem from a model, measurements and the contact priors.

    Parameters
    ----------
    model : ToolPointModel
    measurements : sequence of (Configuration, FRF)
        All measurements of the campaign; ``options.lengths`` selects.
    contact : ContactSpec
    options : IdentificationOptions

    Raises
    ------
    SetupError
        Lengths outside the feasible range, ``single`` with several lengths,
        a prior or option that makes no sense.
    DataError
        An empty band.
    """
    if len(measurements) == 0:
        raise SetupError("no measurements to identify from")
    all_meas = tuple(measurements)
    if options.contact_growth is not None:
        # the population's law: its reference length and range are those of the library it was fitted on
        l_a, l_b = options.contact_growth.l_a, options.contact_growth.l_b
    elif contact.clamping_range is not None:
        l_a, l_b = (float(v) for v in contact.clamping_range)
    else:
        l_a, l_b = min(c.clamping_length for c, _ in all_meas), max(c.clamping_length for c, _ in all_meas)
    q = float(contact.growth_bound) if options.contact_growth is None else options.contact_growth.growth_bound
    feasible = GrowthLaw(l_a, l_b, q)
    feasible.check_lengths([c.clamping_length for c, _ in all_meas], "measured clamping length")
    if options.lengths is not None:
        feasible.check_lengths(options.lengths, "--lengths value")
    used = select_measurements(all_meas, options.lengths)
    lengths = sorted({round(c.clamping_length, 12) for c, _ in used})
    if options.method == "single" and len(lengths) != 1:
        raise SetupError(
            f"method 'single' fits one clamping length, but the selected measurements have {len(lengths)} "
            f"({[round(v * 1e3, 4) for v in lengths]} mm); choose one with --lengths"
        )
    joint_growth = options.contact_prior is not None and bool({"g_xf", "g_thetaM"} & set(options.contact_prior.names))
    if joint_growth and options.method == "single":
        raise SetupError("method 'single' holds the contact constant over length; a library prior carries the growth "
                         "law: use method 'multi'")
    growth = feasible if (len(lengths) > 1 or joint_growth) else GrowthLaw(lengths[0], lengths[0], q)

    observations = []
    for cfg, frf in used:
        band = resolve_band(frf, options.band, ratio=options.band_ratio, rel_height=options.band_rel_height)
        observations.append(make_observation(frf, cfg, band, options.min_coherence))
    parameters = build_parameter_model(model, contact, growth, options, len(used))
    noise = NoiseModel(options.noise_floor, options.min_coherence)
    likelihood = FRFLikelihood(model, observations, parameters, noise)
    return Problem(model, options.method, used, tuple(observations), parameters, likelihood, growth, options, all_meas)


def build_parameter_model(model: ToolPointModel, contact: ContactSpec, growth: GrowthLaw,
                          options: IdentificationOptions, n_measurements: int) -> ParameterModel:
    """The parameter model of a fit: contact priors, growth, damping, ``[model]`` terms, noise scales.

    Parameters
    ----------
    model : ToolPointModel
        Terms read their default priors from its geometry.
    contact : ContactSpec
        The setup's ``[contact]`` table.
    growth : GrowthLaw
        Of the selected measurements (no growth for a single clamping length).
    options : IdentificationOptions
        ``priors`` (``[priors]``), ``model`` (``[model]``) and ``noise_scale``.
    n_measurements : int

    Raises
    ------
    SetupError
        Unknown parameter or term names (the message lists the known ones),
        a prior outside the growth law, a parameter given in both
        ``[priors]`` and ``[model]``.
    """
    user = dict(options.priors)
    allowed = set(CONTACT_NAMES)
    if set(user) - allowed:
        raise SetupError(f"[priors]: unknown parameter(s) {sorted(set(user) - allowed)}; expected some of {sorted(allowed)}")
    table = dict(options.model or {})
    term_names = table.pop("terms", [])
    if isinstance(term_names, str) or not isinstance(term_names, (list, tuple)):
        raise SetupError(f"[model] terms = {term_names!r}: expected a list of term names")
    if len(set(term_names)) != len(term_names):
        raise SetupError(f"[model] terms = {list(term_names)}: a term is listed twice")
    terms = [make_term(n, "[model] terms") for n in term_names]
    term_params = term_parameters(terms, model)
    known = set(CONTACT_NAMES) | {p.name for p in term_params}
    unknown = sorted(set(table) - known)
    if unknown:
        raise SetupError(f"[model]: unknown parameter(s) {unknown}; expected 'terms' or some of {sorted(known)}")
    both = sorted(set(table) & set(user))
    if both:
        raise SetupError(f"[model] and [priors] both set {both}; give each parameter once")

    params: list[Parameter] = []

    def add(name: str, prior: Prior | None = None, value: float | None = None) -> None:
        params.append(contact_parameter(name, prior, value))

    # messages name the key the value came from: [priors] overrides [contact]
    add("k_xf", prior_from_spec(user.get("k_xf", list(contact.translational_stiffness)),
                                "priors.k_xf" if "k_xf" in user else "contact.translational_stiffness"))
    add("k_thetaM", prior_from_spec(user.get("k_thetaM", list(contact.rotational_stiffness)),
                                    "priors.k_thetaM" if "k_thetaM" in user else "contact.rotational_stiffness"))
    if growth.has_growth and growth.growth_bound > 0:
        q = growth.growth_bound
        for name in ("g_xf", "g_thetaM"):
            prior = prior_from_spec(user[name], f"priors.{name}", "uniform") if name in user else Uniform(0.0, q)
            lo, hi = prior.bounds
            if lo < 0 or hi > q:
                raise SetupError(f"priors.{name}: support [{lo:g}, {hi:g}] must lie within [0, Q = {q:g}] (growth law)")
            add(name, prior)
    else:
        add("g_xf", value=0.0)
        add("g_thetaM", value=0.0)
    for name, spec in (("c_xf", contact.translational_damping), ("c_thetaM", contact.rotational_damping)):
        prior, value = _damping(spec, name, user)
        add(name, prior, value)
    if options.contact_prior is not None:
        params = _joint_contact(params, options.contact_prior, growth, user)
    params += term_params
    for name, spec in table.items():
        i = next(k for k, p in enumerate(params) if p.name == name)
        params[i] = _override(params[i], spec, growth)
    noise_prior = LogUniform(*options.noise_scale)
    params += [Parameter(noise_name(j), "1", "noise", prior=noise_prior, label=f"relative noise of measurement {j}")
               for j in range(n_measurements)]
    return ParameterModel(params, growth, terms, n_measurements)


def _joint_contact(params: list[Parameter], joint: JointNormal, growth: GrowthLaw,
                   user: Mapping[str, Any]) -> list[Parameter]:
    """``params`` with the contact parameters of ``joint`` sampled from it (members of one group)."""
    clash = sorted(set(joint.names) & set(user))
    if clash:
        raise SetupError(f"[priors] {clash} and the library's joint prior both give a prior; remove them from "
                         "[priors] to use the library")
    if not growth.has_growth and {"g_xf", "g_thetaM"} & set(joint.names):
        raise SetupError("the library's joint prior samples growth factors but the growth law has no range")
    return [p.with_prior(joint.member(p.name)) if p.name in joint.names else p for p in params]


def _override(p: Parameter, spec, growth: GrowthLaw) -> Parameter:
    """``p`` with the ``[model]`` table's prior (pair or table) or fixed value (number)."""
    where = f"model.{p.name}"
    if isinstance(spec, (int, float)) and not isinstance(spec, bool):
        value = _number(spec, where)
        if p.role == "growth" and not (0 <= value <= growth.growth_bound):
            raise SetupError(f"{where} = {value!r}: a growth factor must lie in [0, Q = {growth.growth_bound:g}]")
        return p.fixed_at(value)
    default_kind = p.prior.kind if p.prior is not None and p.prior.kind in ("uniform", "log-uniform") else "log-uniform"
    if p.role == "growth":
        default_kind = "uniform"
    return p.with_prior(prior_from_spec(spec, where, default_kind))




def build_problem_from_setup(setup: Setup, options: IdentificationOptions) -> Problem:
    """:func:`build_problem` for a loaded setup file."""
    meas = []
    for m in setup.measurements:
        if m.frf is None:
            raise SetupError(f"{setup.path}: measurement {m.file} was not loaded (load_setup(..., load_data=True))")
        meas.append((m.configuration, m.frf))
    if not options.model:
        # the [model] table: Setup.model_table once the setup parser validates it, else the raw extra table
        table = getattr(setup, "model_table", None) or setup.extra.get("model") or {}
        if table:
            options = replace(options, model=dict(table))
    return build_problem(setup.model(), meas, setup.contact, options)
