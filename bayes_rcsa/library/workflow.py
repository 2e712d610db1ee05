"""Fit a library's population from its stage-1 posteriors and write every output (``bayes-rcsa library``)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SetupError
from .outliers import adequacy_rows, flag_outliers, loo_p_values, refit_warnings
from .population import Hyperprior
from .predictive import Population
from .stage1 import Stage1
from .stage2 import ESS_MIN, Stage2Result, Stage2Settings, fit_population

__all__ = ["LibraryFit", "fit_library", "outlier_check", "stage1_summaries", "write_library", "pooling_summary",
           "OUTPUT_FILES"]

#: Files ``bayes-rcsa library`` writes beside the stage-1 folder ``setups/``.
OUTPUT_FILES = ("population.nc", "laws.json", "laws.csv", "library.json", "shrinkage.png")


@dataclass
class LibraryFit:
    """A fitted library: the population, stage 2's result, per-setup rows and warnings."""

    population: Population
    stage2: Stage2Result
    setups: list
    warnings: list


def stage1_summaries(stage1: Stage1, stage1_dir) -> dict:
    """name -> ``stage1_dir/setups/<name>/identify/summary.json`` of every setup (None without a folder)."""
    return {s.name: None if stage1_dir is None else Path(stage1_dir) / "setups" / s.name / "identify" / "summary.json"
            for s in stage1.setups}


def outlier_check(stage2: Stage2Result, stage1: Stage1, stage1_dir, rng: np.random.Generator,
                  adequacy: bool = True) -> tuple[list[dict], list[str]]:
    """The outlier rows and warnings of a library (docs/library.md, "Outliers").

    The leave-one-out contact statistics first, then (``adequacy``) the model-adequacy component of every
    setup from its stage-1 summary in ``stage1_dir``; without a folder (synthetic stage-1 draws, which carry
    no hammer tests) that component is skipped and recorded as such in each row.
    """
    n = len(stage2.setups)
    p_rows = loo_p_values(stage2.fit, stage2.hyper, rng)
    warns = []
    adq = None
    if adequacy:
        adq, warns = adequacy_rows(stage1_summaries(stage1, stage1_dir), n, rng)
        if stage1_dir is None:
            for r in adq.values():
                r["adequacy_skipped"] = "no stage-1 folder: no hammer tests to check (e.g. synthetic stage-1 draws)"
    rows, w = flag_outliers(p_rows, n, adequacy=adq)
    return rows, warns + w + refit_warnings(p_rows)


def fit_library(stage1: Stage1, rng: np.random.Generator, settings: Stage2Settings = Stage2Settings(),
                ess_min: float = ESS_MIN, outliers: bool = True, stage1_dir=None,
                adequacy: bool = True) -> LibraryFit:
    """Stage 2, the outlier check and the population of a library.

    Parameters
    ----------
    stage1 : Stage1 (from :func:`bayes_rcsa.library.stage1.collect`)
    rng : numpy Generator
    settings : Stage2Settings
    ess_min : float, smallest per-setup importance ESS for a pooled estimate
    outliers : bool, run the outlier check
    stage1_dir : path-like or None, the folder holding ``setups/<name>/identify/summary.json`` (the model-adequacy
        component reads each fit's residual correlation there; None skips it, with the reason in every row)
    adequacy : bool, include the model-adequacy component (False: the contact statistics alone)

    Raises
    ------
    SetupError
        One holder type with a single combination (nothing to pool).
    """
    warns = list(stage1.warnings)
    types = sorted({s.holder_type for s in stage1.setups})
    if len(stage1.setups) < 2:
        raise SetupError(f"a library of {len(stage1.setups)} combination(s) in {len(types)} holder type(s): a "
                         "population needs at least two combinations")
    hyper = Hyperprior.from_box(stage1.names, stage1.box, stage1.growth[2])
    res = fit_population(stage1.setups, hyper, rng, settings, ess_min=ess_min)
    warns += res.warnings
    rows = [dict(r) for r in res.setups]
    if outliers:
        flagged, w = outlier_check(res, stage1, stage1_dir, rng, adequacy)
        warns += w
        by_name = {r["name"]: r for r in flagged}
        for r in rows:
            f = by_name[r["name"]]
            r.update({"p_value": f["p_value"], "p_method": f["method"], "outlier": f["outlier"],
                      "outlier_threshold": f["threshold"], "outlier_reason": f["outlier_reason"],
                      # the components behind the combined p-value (library.json): a common shift of the contact
                      # (negative: softer), the omnibus distance, both combined, and the model adequacy of the
                      # setup's own hammer tests (residual correlation at its stage-1 optimum)
                      **{k: f.get(k) for k in ("p_shift", "p_omnibus", "shift_median", "p_contact", "p_adequacy",
                                               "residual_correlation_lines", "adequacy_skipped",
                                               "refit_converged", "refit_steps", "refit_rhat_max")}})
    diameters = {t: (min(s.diameter for s in stage1.setups if s.holder_type == t),
                     max(s.diameter for s in stage1.setups if s.holder_type == t)) for t in types}
    counts = {t: sum(s.holder_type == t for s in stage1.setups) for t in types}
    pop = Population(stage1.names, {t: res.types[t].flat for t in types}, stage1.box, stage1.growth, diameters,
                     counts=counts)
    return LibraryFit(pop, res, rows, list(dict.fromkeys(warns)))


def pooling_summary(fit: LibraryFit) -> dict:
    """What the types share: per coordinate the q05/q50/q95 of the slopes' spread between types ``tau_b`` (units
    of the coordinate per e-fold of diameter) and of the types' spreads' geometric mean and ratio max/min."""
    hf = fit.stage2.fit
    if hf is None:
        return {}
    names = fit.population.names
    d, T = len(names), len(hf.groups)
    ln_s = hf.theta[:, :T * d].reshape(-1, T, d)
    q = (0.05, 0.5, 0.95)
    out = {}
    for j, n in enumerate(names):
        out[n] = {"tau_b": [float(v) for v in np.quantile(hf.tau_b[:, j], q)],
                  "sigma_geometric_mean": [float(v) for v in np.exp(np.quantile(ln_s[:, :, j].mean(axis=1), q))],
                  "sigma_max_over_min": [float(v) for v in np.exp(np.quantile(np.ptp(ln_s[:, :, j], axis=1), q))]}
    # the coupled chain's convergence: stage2_ess, stage2_steps, stage2_rhat_max, stage2_ess_bulk_min, ...
    return {"coordinates": out, **{f"stage2_{k}": v for k, v in hf.quality.summary().items()},
            "sampler": "one emcee over ln sigma per type and coordinate and tau_b per coordinate"}


def write_library(out_dir, fit: LibraryFit, plots: bool = True, attrs: dict | None = None) -> dict[str, Path]:
    """population.nc, laws.json/csv, library.json (per-setup rows, ESS, outliers, warnings), shrinkage.png."""
    from ..io.atomic import atomic_write_text
    from .outputs import law_table, shrinkage_plot, write_law_table, write_population

    out = Path(out_dir)
    pooling = pooling_summary(fit)
    paths = {"population": write_population(out / "population.nc", fit.population, fit.setups,
                                            fit.stage2.hyper.describe(),
                                            {"warnings": json.dumps(fit.warnings), "pooling": json.dumps(pooling),
                                             **(attrs or {})})}
    laws = law_table(fit.population)
    paths["laws_json"], paths["laws_csv"] = write_law_table(out, laws)
    # per type the coupled chain's ESS, autocorrelation time, R-hat and bulk/tail ESS (one chain for all types)
    stage2 = {t: {"n_setups": len(f.names), "acceptance": f.acceptance, **f.quality.summary()}
              for t, f in fit.stage2.types.items()}
    doc = {"holder_types": list(fit.population.holder_types), "coordinates": list(fit.population.names),
           "stage2": stage2, "stage2_exact": fit.stage2.exact, "pooling": pooling, "setups": fit.setups, "laws": laws,
           "outliers": [r["name"] for r in fit.setups if r.get("outlier")], "warnings": fit.warnings}
    atomic_write_text(out / "library.json", json.dumps(doc, indent=1, default=float))
    paths["json"] = out / "library.json"
    if plots:
        paths["shrinkage"] = shrinkage_plot(out / "shrinkage.png", fit.population.names, fit.setups)
    return paths
