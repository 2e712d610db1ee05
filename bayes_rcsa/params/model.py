"""The parameter model: every parameter of a fit, and how it enters the RCSA model.

A :class:`ParameterModel` is the one place that knows

* which parameters exist (contact stiffness and damping, the growth
  factors, one relative noise scale per measurement, the parameters of the
  active model terms), their units, roles and plot labels;
* which of them are *sampled* (have a prior, :class:`~.priors.PriorSet` in
  vector order) and which are *fixed* (a value);
* how a batch of sampling coordinates ``theta`` becomes physical values
  (:meth:`ParameterModel.values`), how those become contact parameters per
  configuration (:meth:`ParameterModel.contact`: the growth law, then the
  joint terms) and noise scales (:meth:`ParameterModel.noise`);
* how it is written to and read from ``posterior.nc``
  (:meth:`ParameterModel.to_dict` / :meth:`ParameterModel.from_dict`, plain
  JSON), so predictions never rebuild the identification problem.

The forward evaluation of a batch on a stack of configurations (including
the substructure, spindle and FRF terms) is :class:`bayes_rcsa.params.forward.ForwardModel`.

Parameter names (physical units)
--------------------------------
``k_xf``, ``k_thetaM``
    Contact stiffness at the reference clamping length ``l_a`` (N/m,
    N m/rad).  For Method II ``l_a`` is the short end of the feasible range;
    for a single clamping length it is that length.
``g_xf``, ``g_thetaM``
    Growth factors of :class:`~.growth.GrowthLaw` (dimensionless; fixed at
    0 without growth).
``c_xf``, ``c_thetaM``
    Contact damping (N s/m, N m s/rad), the same at every clamping length.
``sigma_<j>``
    Relative noise scale of measurement ``j`` (dimensionless).
term parameters
    Declared by the terms (:mod:`bayes_rcsa.params.terms`), e.g. ``tip_mass_kg``.

Vector order of the sampled parameters: contact stiffness, growth, damping,
term parameters (in the order of the terms), noise scales.
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..errors import DataError, SetupError
from .growth import GrowthLaw
from .parameter import Parameter
from .priors import PriorSet, prior_from_spec
from .terms import Contact, ModelTerm, make_term

__all__ = ["ParameterModel", "CONTACT_NAMES", "CONTACT_UNITS", "FORMAT_VERSION", "PARAMETER_MODEL_ATTR", "noise_name",
           "contact_parameter", "term_parameters"]

#: The contact parameters every model has (sampled or fixed).
CONTACT_NAMES = ("k_xf", "k_thetaM", "g_xf", "g_thetaM", "c_xf", "c_thetaM")
CONTACT_UNITS = {"k_xf": "N/m", "k_thetaM": "N m/rad", "g_xf": "1", "g_thetaM": "1", "c_xf": "N s/m",
                 "c_thetaM": "N m s/rad"}
_CONTACT_ROLES = {"k_xf": "contact", "k_thetaM": "contact", "g_xf": "growth", "g_thetaM": "growth",
                  "c_xf": "contact", "c_thetaM": "contact"}
#: Version of the :meth:`ParameterModel.to_dict` layout (bumped on incompatible changes).
FORMAT_VERSION = 1
#: posterior.nc attribute holding :meth:`ParameterModel.to_dict` as JSON.
PARAMETER_MODEL_ATTR = "parameter_model"


def noise_name(j: int) -> str:
    """Name of the relative noise scale of measurement ``j``."""
    return f"sigma_{j}"


def contact_parameter(name: str, prior=None, value: float | None = None) -> Parameter:
    """One of :data:`CONTACT_NAMES` with its unit and role."""
    return Parameter(name, CONTACT_UNITS[name], _CONTACT_ROLES[name], prior=prior,
                     value=None if value is None else float(value))


class ParameterModel:
    """Parameters of a fit (sampled and fixed), the growth law and the active model terms.

    Parameters
    ----------
    parameters : sequence of Parameter
        Every parameter; must include all of :data:`CONTACT_NAMES`,
        ``sigma_0 .. sigma_{n-1}`` and the parameters of every term.  The
        order of the sampled ones is the vector order.
    growth : GrowthLaw
    terms : sequence of ModelTerm
        Active model terms (instances), applied in this order within each kind.
    n_measurements : int
        Number of noise scales.

    Attributes
    ----------
    priors : PriorSet
        The sampled parameters in vector order.
    fixed : dict of str to float
        The fixed parameters (physical units).

    Notes
    -----
    Immutable by convention: nothing mutates a ParameterModel after
    construction; :meth:`with_parameter` returns a new one.  This API
    (``names``, ``ndim``, ``priors``, ``fixed``, ``values``, ``contact``,
    ``noise``, ``to_dict``/``from_dict``, ``describe``) is stable: the
    likelihood, the posterior products and the discrepancy workflow build
    on it.
    """

    def __init__(self, parameters: Sequence[Parameter], growth: GrowthLaw, terms: Sequence[ModelTerm] = (),
                 n_measurements: int = 1):
        self.parameters = tuple(parameters)
        self.growth = growth
        self.terms = tuple(terms)
        self.n_measurements = int(n_measurements)
        if not isinstance(growth, GrowthLaw):
            raise SetupError("a parameter model needs a growth law")
        by_name: dict[str, Parameter] = {}
        for p in self.parameters:
            if p.name in by_name:
                raise SetupError(f"parameter {p.name!r} is defined twice")
            by_name[p.name] = p
        self._by_name = by_name
        required = list(CONTACT_NAMES) + [noise_name(j) for j in range(self.n_measurements)]
        names_of_terms = [t.name for t in self.terms]
        if len(set(names_of_terms)) != len(names_of_terms):
            raise SetupError(f"[model] terms: {names_of_terms} lists a term twice")
        missing = [n for n in required if n not in by_name]
        orphans = [p.name for p in self.parameters if p.term is not None and p.term not in names_of_terms]
        if orphans:
            raise SetupError(f"parameter model: parameter(s) {orphans} belong to terms that are not active "
                             f"(active: {names_of_terms})")
        if missing:
            raise SetupError(f"parameter model: parameter(s) {missing} neither sampled nor fixed")
        sampled = {p.name: p.prior for p in self.parameters if p.sampled}
        if not sampled:
            raise SetupError("a parameter model needs at least one sampled parameter")
        self.priors = PriorSet(sampled)
        self.fixed = {p.name: float(p.value) for p in self.parameters if not p.sampled}
        self._noise_names = [noise_name(j) for j in range(self.n_measurements)]

    # -- what there is ---------------------------------------------------------

    @property
    def names(self) -> tuple[str, ...]:
        """Sampled parameters in vector order."""
        return self.priors.names

    @property
    def ndim(self) -> int:
        return self.priors.ndim

    @property
    def all_names(self) -> tuple[str, ...]:
        """Every parameter, sampled and fixed, in declaration order."""
        return tuple(p.name for p in self.parameters)

    def __getitem__(self, name: str) -> Parameter:
        try:
            return self._by_name[name]
        except KeyError:
            raise SetupError(f"unknown parameter {name!r}; known: {list(self._by_name)}") from None

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def unit(self, name: str) -> str:
        return self[name].unit

    def units(self) -> dict[str, str]:
        """Unit of every parameter."""
        return {p.name: p.unit for p in self.parameters}

    @staticmethod
    def noise_name(j: int) -> str:
        return noise_name(j)

    @property
    def noise_names(self) -> tuple[str, ...]:
        return tuple(self._noise_names)

    @property
    def physical_names(self) -> tuple[str, ...]:
        """Sampled parameters that are not noise scales (contact, growth, terms)."""
        return tuple(n for n in self.names if self[n].role != "noise")

    def terms_of_kind(self, kind: str) -> tuple[ModelTerm, ...]:
        return tuple(t for t in self.terms if t.kind == kind)

    @property
    def term_names(self) -> tuple[str, ...]:
        return tuple(t.name for t in self.terms)

    @property
    def has_structural_terms(self) -> bool:
        """True if a term changes the spindle or a substructure (the general forward path is needed)."""
        return any(t.kind in ("spindle", "substructure") for t in self.terms)

    # -- from sampling coordinates to the model's inputs -----------------------

    def values(self, theta: np.ndarray) -> dict[str, np.ndarray]:
        """Physical values of all parameters, sampled and fixed, ``{name: (n,)}``.

        Parameters
        ----------
        theta : (n, ndim) or (ndim,) sampling coordinates
        """
        theta = np.atleast_2d(theta)
        out = self.priors.to_physical(theta)
        n = theta.shape[0]
        for name, v in self.fixed.items():
            out[name] = np.full(n, v)
        return out

    def contact(self, values: Mapping[str, np.ndarray], lengths) -> Contact:
        """Contact parameters at ``lengths``: the growth law, then the joint terms.

        Parameters
        ----------
        values : mapping name -> (n,) physical values (from :meth:`values`)
        lengths : (n_cfg,) m, clamping length of every configuration

        Returns
        -------
        Contact
            ``k_xf``, ``k_thetaM``, ``c_xf``, ``c_thetaM``, each (n, n_cfg).
        """
        lengths = np.atleast_1d(np.asarray(lengths, dtype=float))
        kx = self.growth.stiffness(values["k_xf"], values["g_xf"], lengths)
        kt = self.growth.stiffness(values["k_thetaM"], values["g_thetaM"], lengths)
        shape = kx.shape
        cx, ct = np.empty(shape), np.empty(shape)
        cx[...] = np.asarray(values["c_xf"], dtype=float)[:, None]
        ct[...] = np.asarray(values["c_thetaM"], dtype=float)[:, None]
        contact = Contact(kx, kt, cx, ct)
        for t in self.terms_of_kind("joint"):
            contact = t.joint(values, contact, lengths, self.growth.l_a, self.growth.l_b)
        return contact

    def noise(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """Relative noise scales, (n, n_measurements)."""
        return np.column_stack([values[n] for n in self._noise_names])

    def sampling(self, values: Mapping[str, float]) -> np.ndarray:
        """Sampling coordinates (ndim,) of one physical parameter set (all sampled names needed)."""
        return self.priors.to_sampling(values)

    # -- construction helpers --------------------------------------------------

    @classmethod
    def from_priors(cls, growth: GrowthLaw, priors: Mapping[str, Any], fixed: Mapping[str, float] | None = None,
                    terms: Sequence[ModelTerm | str] = (), n_measurements: int = 0, model=None) -> "ParameterModel":
        """A model from ``{name: prior}`` and ``{name: value}`` (tests, scripts, hand-made draws).

        Parameters
        ----------
        growth : GrowthLaw
        priors : mapping name -> Prior, in vector order
        fixed : mapping name -> float
            Every contact parameter, noise scale and term parameter not in
            ``priors`` must be here, except term parameters, which default to
            their term's prior.
        terms : sequence of ModelTerm or registered names
        n_measurements : int
        model : ToolPointModel, optional
            Passed to the terms' :meth:`~ModelTerm.parameters`.
        """
        fixed = dict(fixed or {})
        terms = [make_term(t) if isinstance(t, str) else t for t in terms]
        declared = {p.name: p for p in term_parameters(terms, model)}
        both = set(priors) & set(fixed)
        if both:
            raise SetupError(f"parameter(s) {sorted(both)} given both a prior and a fixed value")
        params = []
        order = list(priors) + [n for n in fixed if n not in priors]
        order += [n for n in declared if n not in order]
        for name in order:
            prior, value = priors.get(name), fixed.get(name)
            if name in CONTACT_UNITS:
                params.append(contact_parameter(name, prior, value))
            elif name in declared:
                p = declared[name]
                params.append(p if prior is None and value is None else
                              (p.with_prior(prior) if prior is not None else p.fixed_at(value)))
            elif name.startswith("sigma_"):
                params.append(Parameter(name, "1", "noise", prior=prior, value=value))
            else:
                raise SetupError(f"unknown parameter {name!r}: not a contact parameter, a noise scale or a parameter "
                                 f"of the terms {[t.name for t in terms]}")
        return cls(params, growth, terms, n_measurements)

    # -- variants ----------------------------------------------------------------

    def with_parameter(self, parameter: Parameter) -> "ParameterModel":
        """A copy with ``parameter`` replacing the one of the same name."""
        if parameter.name not in self._by_name:
            raise SetupError(f"unknown parameter {parameter.name!r}")
        params = [parameter if p.name == parameter.name else p for p in self.parameters]
        return ParameterModel(params, self.growth, self.terms, self.n_measurements)

    # -- files -----------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able description from which :meth:`from_dict` rebuilds the model exactly."""
        return {
            "format_version": FORMAT_VERSION,
            "growth": {"l_a": self.growth.l_a, "l_b": self.growth.l_b, "growth_bound": self.growth.growth_bound},
            "n_measurements": self.n_measurements,
            "terms": [t.name for t in self.terms],
            "parameters": [_parameter_dict(p) for p in self.parameters],
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], where: str = "parameter model") -> "ParameterModel":
        """Rebuild from :meth:`to_dict`; terms are looked up by registered name.

        Raises
        ------
        DataError
            A malformed description or a term that is not registered in this
            installation (its name and the known ones are given).
        """
        try:
            version = int(d.get("format_version", 0))
            if version != FORMAT_VERSION:
                raise DataError(f"{where}: format_version {version}, expected {FORMAT_VERSION}")
            g = d["growth"]
            growth = GrowthLaw(float(g["l_a"]), float(g["l_b"]), float(g["growth_bound"]))
            terms = [make_term(str(n), f"{where}: terms") for n in d.get("terms", [])]
            params = []
            for p in d["parameters"]:
                prior = None if p.get("prior") is None else prior_from_spec(p["prior"], f"{where}: {p['name']}")
                params.append(Parameter(
                    name=str(p["name"]), unit=str(p.get("unit", "1")), role=str(p.get("role", "contact")),
                    prior=prior, value=None if p.get("value") is None else float(p["value"]),
                    label=str(p.get("label", "")), baseline=None if p.get("baseline") is None else float(p["baseline"]),
                    term=p.get("term"), description=str(p.get("description", "")),
                ))
            return cls(params, growth, terms, int(d["n_measurements"]))
        except DataError:
            raise
        except SetupError as exc:
            raise DataError(f"{where}: {exc}") from None
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(f"{where}: malformed parameter model ({type(exc).__name__}: {exc})") from None

    def describe(self) -> dict[str, Any]:
        """Summary for summary.json / frequencies.json: every parameter with unit, role and prior or value."""
        return {
            "terms": [t.describe() for t in self.terms],
            "parameters": {p.name: {k: v for k, v in _parameter_dict(p).items() if k != "name"} for p in self.parameters},
            "sampled": list(self.names),
            "fixed": dict(self.fixed),
        }

    def __repr__(self) -> str:
        return (f"ParameterModel(sampled={list(self.names)}, fixed={self.fixed}, terms={list(self.term_names)}, "
                f"growth={self.growth})")

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ParameterModel) and self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]


def _parameter_dict(p: Parameter) -> dict[str, Any]:
    return {
        "name": p.name, "unit": p.unit, "role": p.role,
        "prior": None if p.prior is None else p.prior.describe(),
        "value": p.value, "label": p.label, "baseline": p.baseline, "term": p.term, "description": p.description,
    }


def term_parameters(terms: Iterable[ModelTerm], model) -> list[Parameter]:
    """Default parameters of ``terms`` for a :class:`~bayes_rcsa.model.ToolPointModel`, tagged with their term."""
    from dataclasses import replace

    out = []
    for t in terms:
        for p in t.parameters(model):
            if p.term is None:
                p = replace(p, term=t.name)
            if p.role not in ("term", "discrepancy"):
                raise SetupError(f"model term {t.name!r}: parameter {p.name} has role {p.role!r}, expected 'term' or "
                                 f"'discrepancy'")
            out.append(p)
    return out

