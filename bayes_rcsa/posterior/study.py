"""The identifiability study: single-length fits against the multi-length fit, same priors.

:func:`plan_fits` lists the fits (each selected clamping length alone with
the literature method, and all of them together with the growth law);
:func:`run_study` runs them through the inference package
(:func:`bayes_rcsa.inference.identify.identify`, the same path as
``bayes-rcsa identify``) and analyses each posterior
(:mod:`.identifiability`); :func:`write_study` writes identifiability.json,
the plots and the Markdown/HTML summary.

All fits are built from the same setup, so their priors are identical: the
contact stiffness priors of ``[contact]`` (at the fit's reference length),
the same noise-scale prior, and, for the multi-length fit only, the growth
factors ``g`` on ``[0, Q]``.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import SetupError
from ..io.atomic import atomic_write_text
from ..units import lengths_mm
from ..vocabulary import in_words
from .draws import CONTACT_NAMES, PosteriorDraws, draws_from_result
from .identifiability import (
    BOUND_TAIL,
    COMBINATION_RATIO,
    combination_statement,
    IDENTIFIED_FROM,
    NOT_IDENTIFIED_BELOW,
    VERDICT_RULE,
    fisher_information,
    fmt_contraction,
    length_key,
    log_space,
    parameter_identifiability,
    ridge_analysis,
    stiffness_ridge,
    transfer_errors,
)
from .predict import PredictionTarget, predict
from .prediction_outputs import influence_summary, undetermined_statement

__all__ = ["FitSpec", "FitAnalysis", "Study", "plan_fits", "run_fit", "analyse_fit", "run_study", "write_study", "fmt_contraction",
           "study_document", "study_figures"]

_LENGTH_MATCH = 1e-7
ANALYSIS_MAX_DRAWS = 1000  # draws pushed through the model for the influence analysis of each fit


def _fit_title(spec) -> str:
    """A fit of the study in words: ``fit at 25 mm`` or ``fit over 25 and 40 mm`` (its ``name`` stays in the JSON)."""
    return f"{'fit at' if len(spec.lengths) == 1 else 'fit over'} {lengths_mm(spec.lengths)}"


@dataclass(frozen=True)
class FitSpec:
    """One fit of the study.

    Attributes
    ----------
    name : str, e.g. ``"single_25mm"`` or ``"multi"``
    method : {"single", "multi"}
    lengths : tuple of float, m
    """

    name: str
    method: str
    lengths: tuple[float, ...]


@dataclass(frozen=True)
class FitAnalysis:
    """One fit, its result and the analysis of its posterior.

    Attributes
    ----------
    spec : FitSpec
    result : IdentificationResult
    draws : PosteriorDraws
    entry : dict
        The fit's entry of identifiability.json.
    """

    spec: FitSpec
    result: object
    draws: PosteriorDraws
    entry: dict


@dataclass(frozen=True)
class Study:
    """All fits of a study and the document that summarises them."""

    fits: tuple
    document: dict


def _mm(length: float) -> str:
    return f"{round(length * 1e3, 6):g}"


def plan_fits(setup, lengths: Sequence[float] | None = None) -> list[FitSpec]:
    """Single-length fits of every selected length and the multi-length fit.

    Parameters
    ----------
    setup : Setup
    lengths : sequence of float, optional
        m; measured clamping lengths to use (default: all measured).

    Raises
    ------
    SetupError
        A requested length that was not measured, or fewer than one length.
    """
    measured = sorted({round(m.clamping_length, 12) for m in setup.measurements})
    if lengths is None:
        chosen = measured
    else:
        chosen = []
        for length in lengths:
            hits = [m for m in measured if abs(m - length) < _LENGTH_MATCH]
            if not hits:
                raise SetupError(f"--lengths: no measurement at clamping length {length * 1e3:g} mm; "
                                 f"measured: {[_mm(m) for m in measured]} mm")
            if hits[0] not in chosen:
                chosen.append(hits[0])
        chosen.sort()
    if not chosen:
        raise SetupError("the identifiability study needs at least one measured clamping length")
    fits = [FitSpec(f"single_{_mm(l).replace('.', 'p')}mm", "single", (l,)) for l in chosen]
    if len(chosen) >= 2:
        fits.append(FitSpec("multi", "multi", tuple(chosen)))
    return fits


def run_fit(setup, spec: FitSpec, settings, seed: int, sampler: str = "auto"):
    """Run one fit through the inference package (``sampler`` as :func:`bayes_rcsa.inference.identify.identify`);
    returns its IdentificationResult."""
    from ..inference.identify import identify
    from ..inference.problem import IdentificationOptions, build_problem_from_setup

    options = IdentificationOptions.from_setup(setup.extra, method=spec.method, lengths=spec.lengths)
    problem = build_problem_from_setup(setup, options)
    return identify(problem, seed=seed, settings=settings, sampler=sampler)


def _targets(problem) -> list[PredictionTarget]:
    """Every measured configuration on its own lines (inside the spindle data)."""
    used = {round(o.configuration.clamping_length, 12) for o in problem.observations}
    out = []
    for cfg, frf in problem.all_measurements:
        sf = problem.model.spindle_receptance(cfg.direction).frequency_hz
        f = frf.frequency_hz
        f = f[(f >= sf[0]) & (f <= sf[-1])]
        out.append(PredictionTarget(cfg, f, frf, round(cfg.clamping_length, 12) in used))
    return out


def _influence(draws: PosteriorDraws, problem, rng: np.random.Generator) -> dict:
    sub = draws.subset(ANALYSIS_MAX_DRAWS, rng)
    pred = predict(sub, problem.model, _targets(problem))
    return influence_summary(pred.influence)


def analyse_fit(spec: FitSpec, result, rng: np.random.Generator) -> FitAnalysis:
    """Contraction, verdicts, ridge, Fisher information, transfer errors and influence of one fit."""
    problem = result.problem
    draws = draws_from_result(result)
    params = parameter_identifiability(result.flat_theta, problem.priors)
    contact = [n for n in CONTACT_NAMES if n in problem.parameters.names]
    values = result.values()
    z, labels = log_space(values, contact)
    ridge = ridge_analysis(z, contact)
    theta_map = result.optimum.x if result.optimum is not None else result.flat_theta[int(np.argmax(result.log_prob.ravel()))]
    fisher = fisher_information(problem.likelihood, theta_map, contact, result.tempering)
    transfer = transfer_errors(result.summary["natural_frequencies"])
    influence = _influence(draws, problem, rng)
    ik = contact.index("k_xf"), contact.index("k_thetaM")
    stiff_ridge = stiffness_ridge(z[:, ik[0]], z[:, ik[1]])
    statements = []
    for name, p in params.items():
        # a ridge parameter's marginal median and interval are honest numbers; the verdict says what they mean
        p["value_quoted"] = p["verdict"] == "identified" or p["verdict"].startswith("identified only in combination")
        p["unit"] = problem.parameters.unit(name)
    for name in contact:
        p = params[name]
        if p["verdict"].startswith("identified only in combination"):
            statements.append(combination_statement(name, p, p["unit"], stiff_ridge))
        else:
            s = undetermined_statement(name, p, influence.get(name))
            if s:
                statements.append(s)
    entry = {
        "name": spec.name,
        "method": spec.method,
        "lengths": list(spec.lengths),
        "reference_length": problem.growth.l_a,
        "converged": bool(result.summary.get("converged")),
        "stop_reason": result.summary.get("stop_reason"),
        "n_draws": int(result.flat_theta.shape[0]),
        "tempering": result.tempering,
        "parameters": params,
        "correlation": {"names": labels, "matrix": ridge["correlation"]},
        "corr_log_k": ridge["correlation"][ik[0]][ik[1]],
        "stiffness_ridge": stiff_ridge,
        "ridge": {k: ridge[k] for k in ("names", "eigenvalues", "sd", "eigenvectors", "stiff", "sloppy")},
        "fisher": {k: fisher[k] for k in ("names", "eigenvalues", "eigenvectors", "stiff", "sloppy", "matrix")},
        "condition_number": fisher["condition_number"],
        "transfer_error_pct": transfer["transfer_error_pct"],
        "fit_error_pct": transfer["fit_error_pct"],
        "transfer": transfer["rows"],
        "parameter_influence": influence,
        "statements": statements,
        "warnings": list(result.summary.get("warnings", [])),
    }
    return FitAnalysis(spec, result, draws, entry)


def _error_by_length(entry: dict) -> dict:
    groups: dict = {}
    for r in entry["transfer"]:
        if r["error_q50_pct"] is not None:
            groups.setdefault(length_key(r["clamping_length"]), []).append(abs(r["error_q50_pct"]))
    return {k: float(np.mean(v)) for k, v in groups.items()}


def _findings(fits: Sequence[FitAnalysis]) -> tuple[dict, list[str]]:
    comp = {"stiffness_contraction": {}, "corr_log_k": {}, "condition_number": {}, "mean_transfer_error_pct": {},
            "error_pct_by_length": {}}
    for f in fits:
        e = f.entry
        comp["stiffness_contraction"][e["name"]] = {n: e["parameters"][n]["contraction"] for n in ("k_xf", "k_thetaM")}
        comp["corr_log_k"][e["name"]] = e["corr_log_k"]
        comp["condition_number"][e["name"]] = e["condition_number"]
        t = list(e["transfer_error_pct"].values())
        comp["mean_transfer_error_pct"][e["name"]] = float(np.mean(t)) if t else None
        comp["error_pct_by_length"][e["name"]] = _error_by_length(e)
    lines = []
    for f in fits:
        e = f.entry
        c = e["parameters"]
        sr = e["stiffness_ridge"]
        line = (f"{e['name']} ({', '.join(_mm(l) for l in e['lengths'])} mm): "
                + "; ".join(f"{n} {c[n]['verdict']} ({_contraction_text(c[n]['contraction'])}, marginal / "
                            f"conditional width {_ratio(c[n].get('width_ratio'))})" for n in ("k_xf", "k_thetaM"))
                + f"; {sr['statement'][:-1]}; Fisher condition number {e['condition_number']:.3g}")
        t = comp["mean_transfer_error_pct"][e["name"]]
        if t is not None:
            line += f"; mean |error| of the median natural frequency at the lengths not fitted {t:.3g} %"
        lines.append(line + ".")
    multi = [f for f in fits if f.spec.method == "multi"]
    singles = [f for f in fits if f.spec.method == "single"]
    if multi and singles:
        m = multi[0].entry
        for name in ("k_xf", "k_thetaM"):
            best = max(s.entry["parameters"][name]["contraction"] for s in singles)
            mc = m["parameters"][name]["contraction"]
            lines.append(f"{name}: {_contraction_text(mc)} from all lengths together vs at best "
                         f"{_contraction_text(best)} from one length "
                         f"({'more' if mc > best else 'not more'} contraction with several lengths).")
        ridged = [s.entry["name"] for s in singles
                  if max(s.entry["parameters"][n].get("width_ratio") or 0.0 for n in ("k_xf", "k_thetaM"))
                  >= COMBINATION_RATIO]
        if ridged:
            lines.append(f"Single-length fits with a stiffness ridge (marginal width >= {COMBINATION_RATIO:g} x the width "
                         f"at a fixed partner stiffness): {', '.join(ridged)}: one clamping length fixes a combination "
                         f"of the two stiffnesses, not each.")
    return comp, lines


def run_study(setup, lengths: Sequence[float] | None, settings, seed: int = 0, verbose: bool = False,
              sampler: str = "auto") -> Study:
    """Run and analyse every fit of :func:`plan_fits`.

    Parameters
    ----------
    setup : Setup (with measurements)
    lengths : measured clamping lengths to use (m) or ``None`` for all
    settings : SamplerSettings, shared by all fits
    seed : int
        Seed of every fit (each fit is a different problem) and of the
        draw subsets of the analysis.
    verbose : bool
        One line per fit on stderr.
    sampler : {"auto", "importance", "mcmc"}
        How every fit samples its posterior (:func:`bayes_rcsa.inference.identify.identify`).
    """
    specs = plan_fits(setup, lengths)
    fits = []
    rng = np.random.default_rng(seed)
    for spec in specs:
        if verbose:
            print(f"identifiability: fitting {spec.name} ...", file=sys.stderr)
        result = run_fit(setup, spec, settings, seed, sampler)
        fits.append(analyse_fit(spec, result, rng))
    return Study(tuple(fits), study_document(setup, fits, settings, seed, sampler))


def study_document(setup, fits: Sequence[FitAnalysis], settings, seed: int, sampler: str = "auto") -> dict:
    """Content of identifiability.json (without the plot numbers)."""
    comp, lines = _findings(fits)
    priors = fits[-1].result.problem.priors.describe() if fits else {}
    return {
        "setup": str(setup.path),
        "seed": int(seed),
        # "requested": how every fit sampled (each fit's summary.json says what ran: importance or the chain)
        "sampler": {"requested": sampler, "max_steps": settings.max_steps, "check_every": settings.check_every,
                    "n_walkers": settings.n_walkers},
        "priors": priors,
        "verdict_rule": VERDICT_RULE,
        "thresholds": {"identified_from_contraction": IDENTIFIED_FROM,
                       "not_identified_below_contraction": NOT_IDENTIFIED_BELOW, "bound_tail": BOUND_TAIL},
        "log_space": "log10 k, log10 c, log10(1 + g)",
        "fits": [f.entry for f in fits],
        "comparison": comp,
        "findings": lines,
    }


# -- outputs ------------------------------------------------------------------------


def _contraction_text(c) -> str:
    """``contraction 78.6 %`` or ``prior width / posterior width = 5.1e3``."""
    text = fmt_contraction(c)
    return text if text.startswith("prior") else f"contraction {text}"


def _ratio(r) -> str:
    """A marginal / conditional width ratio for text."""
    return "—" if r is None else ("inf" if not np.isfinite(r) else f"{r:.2g}")


def _q(x) -> dict:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return {k: None for k in ("q05", "q25", "q50", "q75", "q95")}
    return dict(zip(("q05", "q25", "q50", "q75", "q95"), (float(v) for v in np.quantile(x, [0.05, 0.25, 0.5, 0.75, 0.95]))))


def _plots(study: Study, out: Path, rng: np.random.Generator) -> dict:
    from .plots import save_plot

    return {name: save_plot(fig, out / name, numbers) for name, (fig, numbers) in study_figures(study, rng).items()}


def study_figures(study: Study, rng: np.random.Generator) -> dict:
    """``{"corner_overlay.png": (Figure, numbers), "forest.png": (Figure, numbers)}`` of the study.

    ``rng`` draws the subsets of each fit's draws shown (seeded with the study's seed, so that the
    figures and their numbers are the same every time they are made).
    """
    from . import plots as P

    fits = study.fits
    names = [f.spec.name for f in fits]
    lengths = sorted({l for f in fits for l in f.spec.lengths})
    groups = []
    forest_k = {n: [] for n in ("k_xf", "k_thetaM")}
    for length in lengths:
        data = {}
        rows = {n: {"label": f"{_mm(length)} mm", "fits": {}} for n in forest_k}
        for f in fits:
            d = f.draws.subset(2000, rng)
            kx, kt = d.contact([length])[:2]
            z = np.column_stack([np.log10(kx[:, 0]), np.log10(kt[:, 0])])
            data[f.spec.name] = z
            rows["k_xf"]["fits"][f.spec.name] = _q(z[:, 0])
            rows["k_thetaM"]["fits"][f.spec.name] = _q(z[:, 1])
        groups.append({"title": f"stiffness at {_mm(length)} mm", "datasets": data})
        for n in forest_k:
            forest_k[n].append(rows[n])
    corner = P.corner_overlay_figure(groups, ["log10 k_xf (N/m)", "log10 k_thetaM (N m/rad)"], fit_order=names)
    err_rows = []
    keys = sorted({(r["clamping_length"], r["direction"]) for f in fits for r in f.entry["transfer"]})
    for length, d in keys:
        row = {"label": f"{_mm(length)} mm {d}", "fits": {}, "reference": 0.0}
        for f in fits:
            for r in f.entry["transfer"]:
                if r["clamping_length"] == length and r["direction"] == d and r["error_q50_pct"] is not None:
                    row["fits"][f.spec.name] = {"q05": r["error_q05_pct"], "q50": r["error_q50_pct"],
                                                "q95": r["error_q95_pct"], "fitted": r["used_in_fit"]}
        err_rows.append(row)
    forest = P.forest_figure([
        {"title": "contact stiffness k_xf", "xlabel": "log10 k_xf (N/m)", "rows": forest_k["k_xf"]},
        {"title": "contact stiffness k_thetaM", "xlabel": "log10 k_thetaM (N m/rad)", "rows": forest_k["k_thetaM"]},
        {"title": "dominant natural frequency", "xlabel": "(predicted - measured) / measured (%)", "rows": err_rows},
    ], fit_order=names, title="Posterior medians, 50 % and 90 % intervals per fit")
    return {"corner_overlay.png": corner, "forest.png": forest}


def _table_rows(study: Study) -> list[tuple]:
    from .report import fmt

    blocks: list[tuple] = []
    fits = study.fits
    head = ["fit", "lengths (mm)"]
    names = []
    for f in fits:
        for n in f.entry["parameters"]:
            if n not in names and not n.startswith("sigma_"):
                names.append(n)
    head += [f"{n} verdict (contraction)" for n in names] + [
        "k_xf, k_θM marginal / conditional width", "corr(log k_xf, log k_θM)", "Fisher condition number"]
    rows = []
    for f in fits:
        e = f.entry
        row = [e["name"], ", ".join(_mm(l) for l in e["lengths"])]
        for n in names:
            p = e["parameters"].get(n)
            row.append("—" if p is None else f"{p['verdict']} ({_contraction_text(p['contraction'])})")
        row += [", ".join(_ratio(e["parameters"][n].get("width_ratio")) for n in ("k_xf", "k_thetaM")),
                f"{e['corr_log_k']:+.3f}", fmt(e["condition_number"], 3)]
        rows.append(row)
    blocks += [("h", 2, "Contraction and verdicts"), ("table", head, rows),
               ("p", "Verdict rule: " + VERDICT_RULE + ". Noise scales are in identifiability.json.")]

    head = ["fit", "posterior quantity"] + [n for n in names]
    rows = []
    for f in fits:
        e = f.entry
        for label, key in (("q50", "q50"), ("90 % interval", None)):
            row = [e["name"], label]
            for n in names:
                p = e["parameters"].get(n)
                if p is None:
                    row.append("—")
                elif key is None:
                    row.append(f"[{fmt(p['q05'])}, {fmt(p['q95'])}]")
                else:
                    row.append(fmt(p["q50"]) if p["value_quoted"] else "not quoted")
            rows.append(row)
    blocks += [("h", 2, "Posterior values (physical units; medians quoted for parameters identified alone or in "
                        "combination)"),
               ("table", head, rows)]

    blocks.append(("h", 2, "Posterior correlations of the contact parameters (log space)"))
    for f in fits:
        c = f.entry["correlation"]
        blocks.append(("p", f"{f.spec.name}:"))
        blocks.append(("table", [""] + c["names"],
                       [[n] + [f"{v:+.3f}" for v in row] for n, row in zip(c["names"], c["matrix"])]))
    blocks.append(("h", 2, "The two stiffnesses: what the data fix"))
    blocks.append(("ul", [f"{f.spec.name}: {f.entry['stiffness_ridge']['statement']}" for f in fits]))
    blocks.append(("h", 2, "Ridges: stiff and sloppy combinations"))
    rows = []
    for f in fits:
        e = f.entry
        rows.append([e["name"], e["ridge"]["stiff"]["combination"], fmt(e["ridge"]["stiff"]["sd"], 3),
                     e["ridge"]["sloppy"]["combination"], fmt(e["ridge"]["sloppy"]["sd"], 3),
                     e["fisher"]["stiff"]["combination"], e["fisher"]["sloppy"]["combination"],
                     ", ".join(fmt(v, 3) for v in e["fisher"]["eigenvalues"])])
    blocks.append(("table", ["fit", "posterior stiff combination", "sd (decades)", "posterior sloppy combination",
                             "sd (decades)", "Fisher stiff", "Fisher sloppy", "Fisher eigenvalues"], rows))
    blocks.append(("p", "Combinations are products of powers of the parameters (log space: log10 k, log10 c, "
                        "log10(1+g)), scaled so that the largest power is 1; sd is the posterior standard deviation "
                        "along the direction, in decades."))

    blocks.append(("h", 2, "Transfer: predicted dominant natural frequency vs measurement (cf. paper Tables 5–7)"))
    keys = sorted({(r["clamping_length"], r["direction"]) for f in fits for r in f.entry["transfer"]})
    head = ["length (mm)", "dir", "measured (Hz)"] + [f"{f.spec.name}: median [90 %] Hz, error %" for f in fits]
    rows = []
    for length, d in keys:
        meas = None
        row = [_mm(length), d]
        cells = []
        for f in fits:
            r = next((r for r in f.entry["transfer"] if r["clamping_length"] == length and r["direction"] == d), None)
            if r is None or r["q50_hz"] is None:
                cells.append("—")
                continue
            meas = r["measured_hz"]
            tag = " (fitted)" if r["used_in_fit"] else ""
            cells.append(f"{r['q50_hz']:.5g} [{r['q05_hz']:.5g}, {r['q95_hz']:.5g}], {fmt(r['error_q50_pct'], 3)} %{tag}")
        rows.append(row + [fmt(meas, 6)] + cells)
    blocks.append(("table", head, rows))
    return blocks


def _describe(prior: dict) -> str:
    args = ", ".join(f"{k}={v:g}" for k, v in prior.items() if k != "distribution" and isinstance(v, (int, float)))
    return f"{prior.get('distribution')}({args})"


def _blocks(study: Study, images: Sequence[str]) -> list[tuple]:
    doc = study.document
    priors = ", ".join(f"{k}: {_describe(v)}" for k, v in doc["priors"].items() if not k.startswith("sigma_"))
    blocks: list[tuple] = [
        ("h", 1, "Identifiability of the tool-holder contact: single- vs multi-length fits"),
        ("p", f"Setup {doc['setup']}; seed {doc['seed']}; all fits share the priors of the setup ({priors})."),
        ("h", 2, "Findings"),
        ("ul", doc["findings"]),
    ]
    statements = [f"{_fit_title(f.spec)}: {s}" for f in study.fits for s in f.entry["statements"]]
    if statements:
        blocks += [("h", 2, "What the data do not determine"), ("ul", statements)]
    blocks += _table_rows(study)
    # in words (docs/data-formats.md): the fits' warnings name parameters by their identifiers (sigma_0: R-hat ...)
    warn = [f"{_fit_title(f.spec)}: {in_words(w)}" for f in study.fits for w in f.entry["warnings"]]
    if warn:
        blocks += [("h", 2, "Warnings of the fits"), ("ul", warn)]
    for img in images:
        blocks.append(("img", img, img))
    return blocks


def write_study(study: Study, out_dir, plots: bool = True, posteriors: bool = True, seed: int = 0) -> list[Path]:
    """Write identifiability.json, plots, identifiability.md/.html and (optionally) each fit's files.

    Parameters
    ----------
    study : Study
    out_dir : path
    plots : bool
        corner_overlay.png and forest.png.
    posteriors : bool
        Each fit's summary.json and posterior.nc under ``fits/<name>/``
        (usable with ``bayes-rcsa predict``).
    seed : int
        Seed of the draw subsets shown in the plots.
    """
    from ..inference.results import to_jsonable
    from .report import write_report

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if posteriors:
        from ..inference.outputs import write_outputs

        for f in study.fits:
            written += write_outputs(f.result, out / "fits" / f.spec.name, plots=False)
    doc = dict(study.document)
    images = []
    if plots:
        doc["plots"] = _plots(study, out, np.random.default_rng(seed))
        images = ["forest.png", "corner_overlay.png"]
        written += [out / i for i in images]
    text = json.dumps(to_jsonable(doc), indent=2, allow_nan=False)
    atomic_write_text(out / "identifiability.json", text + "\n")
    written.append(out / "identifiability.json")
    written += write_report(out, "identifiability", _blocks(study, images), "bayes-rcsa identifiability")
    return written
