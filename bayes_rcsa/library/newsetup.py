"""A new combination identified with a library's population as its prior (``identify --library``).

With one or more taps, :func:`library_options` returns the identification
options whose contact prior is the population predictive of the setup's
holder type and shank diameter (:func:`~.predictive.predictive_prior`); the
identification itself is the ordinary one.  With zero taps,
:func:`write_zero_tap` writes a ``posterior.nc`` (and ``summary.json``) of
population-predictive draws in exactly the layout of an identify posterior,
so ``predict`` and ``lobes`` read it unchanged.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..errors import SetupError
from ..params.growth import GrowthLaw
from ..params.model import PARAMETER_MODEL_ATTR, ParameterModel, contact_parameter
from ..params.terms.law_shape_uncertainty import LawShapeUncertainty
from .predictive import LAW_SHAPE, Population, contact_names, law_shape_prior, predictive_draws, predictive_prior
from .population import from_coordinates
from .stage1 import holder_type_of, shank_diameter

__all__ = ["library_options", "write_zero_tap", "check_setup", "ZERO_TAP_METHOD"]

#: ``method`` recorded in a zero-tap posterior.
ZERO_TAP_METHOD = "library-predictive"
#: The model term whose one parameter (:data:`~.predictive.LAW_SHAPE`) a population may pool.
LAW_SHAPE_TERM = LawShapeUncertainty.name


def check_setup(pop: Population, setup) -> tuple[str, float, GrowthLaw]:
    """Holder type, shank diameter and the population's growth law for a new setup.

    Raises
    ------
    SetupError
        No or an unknown holder type; an implausible diameter; a clamping
        range or measurement lengths that do not fit the population's
        (e.g. mixed units: mm where the library used m).
    """
    where = str(getattr(setup, "path", "setup"))
    htype = pop.check_type(holder_type_of(setup), where)
    diameter = shank_diameter(setup)
    l_a, l_b, q = pop.growth
    growth = GrowthLaw(l_a, l_b, q) if l_b > l_a else GrowthLaw(l_a, l_a, q)
    rng_ = getattr(setup.contact, "clamping_range", None)
    if rng_ is not None:
        a, b = (float(v) for v in rng_)
        if not (math.isclose(a, l_a, rel_tol=1e-6) and math.isclose(b, l_b, rel_tol=1e-6)):
            hint = " (mixed units?)" if max(b, l_b) > 100 * min(b, l_b) else ""
            raise SetupError(f"{where}: contact.clamping_range [{a:g}, {b:g}] m differs from the library's "
                             f"[{l_a:g}, {l_b:g}] m{hint}; the population's stiffness refers to the library's "
                             "reference length")
    growth.check_lengths([m.clamping_length for m in setup.measurements], f"{where}: measurement clamping length")
    return htype, diameter, growth


def library_options(pop: Population, setup, rng: np.random.Generator) -> tuple[dict, list[str]]:
    """``IdentificationOptions`` keywords (``contact_prior``, ``contact_growth`` and, for a setup with the
    law-shape term, ``model``) and warnings for a tap.

    The contact prior is over the pooled contact parameters only (:func:`~.predictive.contact_names`): a
    population that also pools the law's bend (``law_shape_bend``) gives the marginal of its moment-matched
    joint normal over the contact (the joint prior of ``identify`` is a contact prior).  A setup whose
    ``[model]`` has ``law_shape_uncertainty`` gets the population's bend as that parameter's prior
    (:func:`~.predictive.law_shape_prior`: one or two taps do not identify where the law lies between the
    lengths, the library's combinations at three or more do), through its ``[model]`` table, unless the table
    gives ``law_shape_bend`` a prior itself.
    """
    htype, diameter, growth = check_setup(pop, setup)
    joint, warns = predictive_prior(pop, htype, diameter, rng, names=contact_names(pop))
    kw = {"contact_prior": joint, "contact_growth": growth}
    table = dict(getattr(setup, "model_table", None) or setup.extra.get("model") or {})
    if LAW_SHAPE_TERM in (table.get("terms") or []) and LAW_SHAPE not in table:
        prior, info, more = law_shape_prior(pop, htype, diameter, rng)
        warns = warns + more
        if prior is None:
            warns.append(f"[model] {LAW_SHAPE_TERM}: {info['reason']}; {LAW_SHAPE} keeps its prior (the whole range "
                         "between the parallel and the series law)")
        else:
            kw["model"] = {**table, LAW_SHAPE: prior.describe()}
    return kw, warns


def _fixed_contact(setup, names) -> dict[str, float]:
    """Contact parameters not pooled: the setup's fixed damping, growth 0 (no growth law in the population)."""
    out = {}
    for key, name in (("translational_damping", "c_xf"), ("rotational_damping", "c_thetaM")):
        if name in names:
            continue
        spec = getattr(setup.contact, key)
        if isinstance(spec, (list, tuple)):
            raise SetupError(f"{setup.path}: [contact] {key} = {list(spec)} is sampled, but the library did not pool "
                             f"{name}; give a number")
        out[name] = float(spec)
    for name in ("g_xf", "g_thetaM"):
        if name not in names:
            out[name] = 0.0
    for name in ("k_xf", "k_thetaM"):
        if name not in names:
            raise SetupError(f"the library did not pool {name}; a zero-tap prediction needs it")
    return out


def write_zero_tap(out_dir, pop: Population, setup, rng: np.random.Generator, n_draws: int = 4000,
                   warnings: list[str] | None = None) -> dict:
    """Write ``posterior.nc`` and ``summary.json`` of population-predictive draws (no measurement used).

    Returns
    -------
    dict, the summary written
    """
    from ..inference.diagnostics import inference_data_from_dict
    from ..io.atomic import atomic_write_text
    from ..posterior.setup_match import GEOMETRY_KEY, setup_geometry
    from ..store import write_posterior

    htype, diameter, growth = check_setup(pop, setup)
    names = contact_names(pop)  # the zero-tap posterior is a contact law; a pooled law bend has no term here
    z, warns = predictive_draws(pop, htype, diameter, rng, n_draws)
    z = z[:, [pop.names.index(n) for n in names]]
    joint, _ = predictive_prior(pop, htype, diameter, rng, names=names)
    fixed = _fixed_contact(setup, names)
    params = [contact_parameter(n, prior=joint.member(n)) for n in names]
    params += [contact_parameter(n, value=v) for n, v in fixed.items()]
    pm = ParameterModel(params, growth, (), 0)
    values = from_coordinates(names, z)
    post = {n: values[n][None, :] for n in names}
    lengths = np.array(sorted({round(m.clamping_length, 12) for m in setup.measurements})) if setup.measurements \
        else np.array([growth.l_a])
    full = {**values, **{n: np.full(z.shape[0], v) for n, v in fixed.items()}}
    kx, kt = pm.contact(full, lengths)[:2]
    post["k_xf_at_length"] = kx[None]
    post["k_thetaM_at_length"] = kt[None]
    warns = list(warnings or []) + warns + [
        f"zero taps: the contact is the population predictive of holder type {htype} at a shank diameter of "
        f"{diameter * 1e3:g} mm; no measurement of this combination was used"]
    attrs = {"method": ZERO_TAP_METHOD, "converged": 1, "created_by": "bayes_rcsa identify --library",
             "holder_type": htype, "shank_diameter_m": diameter, "library_model_version": pop.version,
             "l_a": growth.l_a, "l_b": growth.l_b, "growth_bound": growth.growth_bound,
             PARAMETER_MODEL_ATTR: json.dumps(pm.to_dict())}
    dims = {"k_xf_at_length": ["clamping_length"], "k_thetaM_at_length": ["clamping_length"],
            "fit_clamping_length": ["fit_measurement"]}
    idata = inference_data_from_dict(posterior=post, constant_data={"fit_clamping_length": np.zeros(0)}, dims=dims,
                                     coords={"clamping_length": lengths}, attrs=attrs)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_posterior(idata, out / "posterior.nc")
    q = {n: [float(v) for v in np.quantile(full[n], [0.05, 0.5, 0.95])] for n in names}
    summary = {"method": ZERO_TAP_METHOD, "converged": True, "holder_type": htype, "shank_diameter_m": diameter,
               "n_draws": int(z.shape[0]),
               "parameters": {n: {"q05": v[0], "q50": v[1], "q95": v[2], "unit": pm.unit(n)} for n, v in q.items()},
               "fixed": fixed, "warnings": warns, GEOMETRY_KEY: setup_geometry(setup)}
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=1))
    return summary
