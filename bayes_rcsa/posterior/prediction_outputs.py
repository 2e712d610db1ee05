"""The ``predict`` workflow: posterior file -> predictions -> frequencies.json, CSV, plots, report.

:func:`run_prediction` loads the draws and computes the predictions (nothing
is written); :func:`write_prediction_outputs` writes

* ``frequencies.json``: one entry per configuration and mode (natural
  frequency quantiles, measured value where a measurement exists, peak
  magnitude and dynamic stiffness intervals) plus the parameter influence;
* ``frf_bands.csv``: the |H| quantile bands and the median real and
  imaginary parts of every configuration;
* ``frf_bands.png`` and ``natural_frequencies.png`` (numbers embedded, see
  :mod:`.plots`);
* ``report.md`` / ``report.html``: a table in the style of the reference
  paper's Table 4 (measured vs predicted dominant natural frequency with
  90 % intervals and errors), the per-mode table, and what the data leave
  undetermined.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import DataError, SetupError
from ..io.atomic import atomic_path, atomic_write_text
from ..params.growth import GrowthLaw
from ..params.priors import PriorSet
from .draws import PosteriorDraws, load_posterior
from .growth_prior import transfer_draws
from .identifiability import VERDICT_RULE, combination_statement, fmt_contraction, parameter_identifiability
from ..model.natural_frequencies import NATURAL_FREQUENCY_RULE
from .predict import (
    MODE_REL_HEIGHT,
    MODE_REL_PROMINENCE,
    QUANTILE_KEYS,
    Prediction,
    PredictiveNoise,
    predict,
    prediction_targets,
    quantile_dict,
)
from ..units import hz, hz_range, lengths_mm, sci_parts
from ..vocabulary import effect_name, identification_name, in_words, parameter_name
from .report import fmt, fmt_interval, write_report

__all__ = [
    "PredictionRun",
    "INTERVAL_DEFINITIONS",
    "posterior_status",
    "check_prediction_lengths",
    "contact_identifiability",
    "run_prediction",
    "frequencies_document",
    "influence_summary",
    "write_prediction_outputs",
    "undetermined_statement",
    "DEFAULT_MAX_DRAWS",
    "INSENSITIVE_PCT",
]

DEFAULT_MAX_DRAWS = 1000
# Predictions that move by less than this (% of the natural frequency) are called insensitive to a parameter:
# well below the 1-4 % transfer errors of the reference paper's Tables 4-7 and below typical modal-test scatter.
INSENSITIVE_PCT = 0.5
MODE_RULE = (
    f"local maxima of the posterior-median |H| reaching {MODE_REL_HEIGHT:g} of its largest value with prominence "
    f">= {MODE_REL_PROMINENCE:g} of it; each mode's band runs between the minima of the median |H| on either side; "
    "peak magnitude = max |H| on the band's lines, dynamic stiffness = 1 / peak magnitude"
)

DEFAULT_NOISE_FLOOR = 0.01  # the likelihood's default (inference.problem), used when summary.json is absent
INTERVAL_DEFINITIONS = {
    "q05_hz..q95_hz": "credible interval of the MODEL's (noise-free) natural frequency: where the resonance of the "
                      "identified model lies; narrower than the scatter of measured peaks",
    "predictive_peak_q05_hz..predictive_peak_q95_hz": "posterior-predictive interval of the peak frequency a NEW "
                      "hammer test would show: each draw's FRF plus simulated measurement noise of the fit's noise "
                      "model (relative scale sigma_j, noise floor, coherence 1), the same natural-frequency rule; "
                      "compare a new measurement with this one",
}


def posterior_status(posterior_path, inference_data=None, summary=None) -> dict:
    """Convergence status of the fit behind ``posterior_path`` for the products' outputs.

    Read from the sibling ``summary.json`` written by ``bayes-rcsa
    identify`` (R-hat, ESS, tau, steps, warnings, noise floor); without it,
    from the posterior file's ``converged`` attribute only.

    Parameters
    ----------
    posterior_path : path of posterior.nc, or None for a posterior held in memory only
    inference_data : arviz.InferenceData or None, the file's content when already read (not opened again)
    summary : dict or None, the summary.json document when already loaded (used instead of the file)

    Returns
    -------
    dict
        ``{"converged": bool or None, "rhat_max", "ess_bulk_min", "tau_max",
        "n_steps", "warnings": list of str, "noise_floor", "source"}``
        (``None`` where unknown).
    """
    path = Path(posterior_path) if posterior_path is not None else None
    summary_path = path.parent / "summary.json" if path is not None else "summary.json"
    out = {"converged": None, "rhat_max": None, "ess_bulk_min": None, "tau_max": None, "n_steps": None,
           "warnings": [], "noise_floor": None, "source": None}
    if summary is not None or (path is not None and summary_path.is_file()):
        if summary is None:
            try:
                summary = json.loads(summary_path.read_text(encoding="utf-8"))
            except ValueError as exc:
                raise DataError(f"{summary_path}: not valid JSON ({exc})") from None
        params = summary.get("parameters", {}) or {}
        rhat = [p["rhat"] for p in params.values() if p.get("rhat") is not None]
        ess = [p["ess_bulk"] for p in params.values() if p.get("ess_bulk") is not None]
        tau = [t for t in (summary.get("tau") or {}).values() if t is not None]
        out.update({
            "converged": summary.get("converged"),
            "rhat_max": max(rhat) if rhat else None,
            "ess_bulk_min": min(ess) if ess else None,
            "tau_max": max(tau) if tau else None,
            "n_steps": summary.get("n_steps"),
            "warnings": [str(w) for w in summary.get("warnings", [])],
            "noise_floor": (summary.get("likelihood") or {}).get("noise_floor"),
            "source": str(summary_path),
        })
    else:
        from ..store import posterior_attributes, read_posterior

        attrs = posterior_attributes(read_posterior(path, option=None, arrays=True) if inference_data is None else inference_data)
        if "converged" in attrs:
            out["converged"] = bool(int(attrs["converged"])) if not isinstance(attrs["converged"], str) \
                else attrs["converged"].lower() in ("true", "1")
        out["source"] = str(path)
    if out["converged"] is False:
        out["warnings"] = ["the posterior's sampler did NOT converge: every interval below is unreliable"] + \
            out["warnings"]
    return out


@dataclass(frozen=True)
class PredictionRun:
    """A prediction and what it was made from.

    Attributes
    ----------
    prediction : Prediction
    draws : PosteriorDraws
        The (possibly subsampled) draws used.
    identifiability : dict or None
        Contraction and verdict of the sampled parameters (priors from the
        posterior's parameter model), ``None`` for a fit without sampled
        physical parameters.
    meta : dict
        Setup, posterior file, seed, requested lengths, where the parameter
        model came from (``parameter_model_source``), notes, the posterior's
        convergence status (``posterior_status``) and the predictive noise
        model (``predictive_noise``).
    """

    prediction: Prediction
    draws: PosteriorDraws
    identifiability: dict | None
    meta: dict


def check_prediction_lengths(draws: PosteriorDraws, setup, lengths: Sequence[float]) -> None:
    """Raise :class:`SetupError` for lengths outside the feasible clamping range.

    With a growth law the range is the law's ``[l_a, l_b]``; a constant
    (single-length) posterior may be transferred over the setup's feasible
    range, as the literature method does.
    """
    if len(lengths) == 0:
        raise SetupError("--lengths: expected at least one clamping length")
    if draws.growth.has_growth:
        draws.growth.check_lengths(lengths, "prediction clamping length")
    else:
        l_a, l_b = setup.feasible_range
        GrowthLaw(l_a, l_b).check_lengths(lengths, "prediction clamping length")


def contact_identifiability(draws: PosteriorDraws) -> dict | None:
    """Contraction and verdicts of the sampled parameters of ``draws`` (noise scales excepted).

    The priors are the ones the fit used, recorded in the draws' parameter
    model (posterior.nc), so nothing is rebuilt from the setup.  Returns
    ``None`` when no physical parameter was sampled.
    """
    names = list(draws.sampled)
    if not names:
        return None
    priors = draws.parameters.priors
    sub = PriorSet({n: priors[n] for n in names})
    with np.errstate(divide="ignore", invalid="ignore"):
        theta = np.column_stack([np.asarray(sub[n].to_sampling(draws.values[n]), dtype=float) for n in names])
    return parameter_identifiability(theta, sub)


def run_prediction(setup, posterior_path, lengths: Sequence[float], directions: Sequence[str] | None = None,
                   tool: str | None = None, frequency_hz=None, max_draws: int | None = DEFAULT_MAX_DRAWS,
                   seed: int = 0, *, posterior_draws=None, inference_data=None, summary=None,
                   spindle_samples=None) -> PredictionRun:
    """Load ``posterior_path`` and predict at ``lengths``.

    Parameters
    ----------
    setup : Setup (loaded with its measurements)
    posterior_path : path of posterior.nc
    lengths : clamping lengths, m
    directions, tool, frequency_hz : see :func:`prediction_targets`
    max_draws : int or None
        Random subset of at most this many draws (``None``: all).
    seed : int
        Seed of the generators that pick the subset, simulate the
        measurement noise of the predictive peak intervals and assign the
        spindle samples to the draws.
    posterior_draws : PosteriorDraws or None, the draws of ``posterior_path`` already loaded (not read again)
    inference_data : arviz.InferenceData or None, the content of ``posterior_path`` already read; without it (and
        without ``posterior_draws``) the file is read once here
    summary : dict or None, the fit's summary.json document for a posterior held in memory only
    spindle_samples : SpindleSamples, optional
        Bootstrap samples of the flange receptance (``bayes-rcsa spindle``):
        every draw uses one of them, so the bands and intervals include the
        spindle uncertainty; recorded as ``meta["spindle_uncertainty"]``.
        The draws, their noise and growth transfer stay those of the run
        without samples (the assignment has a stream of its own).
    """
    from ..store import read_posterior

    draws_all = posterior_draws
    if draws_all is None:
        if inference_data is None:
            inference_data = read_posterior(posterior_path, option=None, arrays=True)  # the one read of the file
        draws_all = load_posterior(posterior_path, setup, inference_data=inference_data)
    lengths = [float(v) for v in lengths]
    check_prediction_lengths(draws_all, setup, lengths)
    status = posterior_status(posterior_path, inference_data=inference_data, summary=summary)
    # the subset keeps default_rng(seed) (earlier outputs reproduced draw for draw); the noise, the growth transfer
    # and the spindle samples' assignment get streams of their own (a third child leaves the first two unchanged)
    draws = draws_all.subset(max_draws, np.random.default_rng(seed))
    rng_noise, rng_growth, rng_spindle = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3))
    # a single-length fit says nothing about growth: elsewhere its predictions carry the growth law's prior
    draws = transfer_draws(draws, setup, lengths, rng_growth)
    floor = status["noise_floor"] if status["noise_floor"] is not None else DEFAULT_NOISE_FLOOR
    noise = PredictiveNoise.from_draws(draws, floor, rng_noise)
    targets = prediction_targets(setup, lengths, directions, tool, frequency_hz, draws.fit_lengths)
    prediction = predict(draws, setup.model(), targets, noise=noise, spindle_samples=spindle_samples, rng=rng_spindle)
    ident = contact_identifiability(draws)  # the same draws as the influence, so the report's ranges agree
    meta = {
        "setup": str(setup.path),
        "posterior": str(posterior_path),
        "method": draws.method,
        "fit_lengths": list(draws.fit_lengths),
        "growth_law": {"l_a": draws.growth.l_a, "l_b": draws.growth.l_b, "growth_bound": draws.growth.growth_bound,
                       "has_growth": draws.growth.has_growth},
        "n_draws_available": draws_all.n_draws,
        "n_draws": draws.n_draws,
        "subset_seed": seed,
        "lengths": lengths,
        **draws.provenance(),
        "posterior_status": status,
        "predictive_noise": None if noise is None else {
            "noise_floor": floor, "noise_floor_source": "summary.json" if status["noise_floor"] is not None
            else f"default {DEFAULT_NOISE_FLOOR:g} (no summary.json beside the posterior)",
            "scale_q05": float(np.quantile(noise.scale, 0.05)), "scale_q50": float(np.median(noise.scale)),
            "scale_q95": float(np.quantile(noise.scale, 0.95)), "coherence": 1.0},
    }
    if spindle_samples is not None:
        meta["spindle_uncertainty"] = prediction.spindle_uncertainty
    return PredictionRun(prediction, draws, ident, meta)


def influence_summary(influence: Sequence[dict]) -> dict:
    """Per parameter, the largest effect on any dominant-mode natural frequency.

    Returns
    -------
    dict name -> ``{"posterior_q05", "posterior_q95", "max_delta_hz",
    "max_delta_pct", "max_fraction_of_interval"}``
    """
    out: dict = {}
    for row in influence:
        if not row["dominant"]:
            continue
        s = out.setdefault(row["parameter"], {"posterior_q05": row["posterior_q05"], "posterior_q95": row["posterior_q95"],
                                              "max_delta_hz": None, "max_delta_pct": None,
                                              "max_fraction_of_interval": None})
        for key, src in (("max_delta_hz", "delta_hz"), ("max_delta_pct", "delta_pct"),
                         ("max_fraction_of_interval", "fraction_of_interval")):
            v = row[src]
            if v is not None and (s[key] is None or v > s[key]):
                s[key] = v
    return out


def frequencies_document(run: PredictionRun, warnings: Sequence[str] = ()) -> dict:
    """Content of ``frequencies.json``; ``warnings``: every warning the command printed (data checks included)."""
    p = run.prediction
    pm = run.draws.parameters
    params = {n: {**quantile_dict(run.draws.values[n]), "unit": pm.unit(n), "sampled": n in run.draws.sampled}
              for n in pm.all_names if pm[n].role != "noise"}
    return {
        **run.meta,
        "converged": run.meta["posterior_status"]["converged"],
        "natural_frequency_rule": NATURAL_FREQUENCY_RULE,
        "mode_rule": MODE_RULE,
        "interval_definitions": INTERVAL_DEFINITIONS,
        "quantile_levels": dict(zip(QUANTILE_KEYS, (0.05, 0.25, 0.5, 0.75, 0.95))),
        "predictions": [m.as_dict() for m in p.modes],
        "contact_parameters": params,
        "identifiability": run.identifiability,
        "verdict_rule": VERDICT_RULE if run.identifiability is not None else None,
        "parameter_influence": list(p.influence),
        "parameter_influence_summary": influence_summary(p.influence),
        "warnings": list(warnings),
    }


def _write_bands_csv(path: Path, prediction: Prediction) -> Path:
    header = ("clamping_length_m,direction,tool,frequency_hz,abs_q05,abs_q25,abs_q50,abs_q75,abs_q95,"
              "real_q50,imag_q50")
    lines = ["# bayes-rcsa predict: posterior predictive tool-point receptance h = u/F (m/N) quantiles", header]
    for b in prediction.bands:
        c = b.configuration
        cols = np.column_stack([b.frequency_hz, b.magnitude.T, b.real[2], b.imag[2]])
        prefix = f"{c.clamping_length!r},{c.direction},{c.tool},"
        lines += [prefix + ",".join(repr(float(v)) for v in row) for row in cols]
    atomic_write_text(path, "\n".join(lines) + "\n")
    return path


def _unit(name: str) -> str:
    from ..params.model import CONTACT_UNITS

    u = CONTACT_UNITS.get(name, "")
    return "" if u == "1" else u


def undetermined_statement(name: str, ident: dict, infl: dict | None) -> str | None:
    """Plain-language sentence for a parameter the data do not pin down (``None`` if identified).

    Parameters
    ----------
    name : str
    ident : dict
        Its entry of :func:`.identifiability.parameter_identifiability`.
    infl : dict or None
        Its entry of :func:`influence_summary`.
    """
    if ident["verdict"] == "identified":
        return None
    unit = _unit(name)
    if ident["verdict"].startswith("identified only in combination"):
        # pinned along the ridge, wide across it: say so instead of calling it undetermined
        return combination_statement(name, ident, unit)
    if ident["verdict"] == "not identified":
        why = "its posterior is close to its prior"
    else:
        why = {"upper": "the data bound it only from below; the prior's upper bound ends the posterior",
               "lower": "the data bound it only from above; the prior's lower bound ends the posterior",
               }.get(ident.get("bound"), "its posterior is wide compared with its prior")
    _, lo, hi = sci_parts(None, ident["q05"], ident["q95"], 3)
    text = (f"The {parameter_name(name)} is {in_words(ident['verdict'])} (contraction {fmt_contraction(ident['contraction'])}; "
            f"{why}); no value is quoted for it, its 90 % posterior range is {lo}–{hi}{' ' + unit if unit else ''}.")
    if infl and infl.get("max_delta_hz") is not None:
        frac = infl.get("max_fraction_of_interval")
        text += (f" Wherever it lies in that range, the median predicted dominant natural frequencies change by at most "
                 f"{fmt(infl['max_delta_hz'], 3)} Hz ({fmt(infl['max_delta_pct'], 3)} %")
        if frac is not None:
            text += f", {fmt(frac, 2)} of the width of their 90 % intervals"
        text += ")"
        text += (": the predictions are insensitive to it." if infl["max_delta_pct"] < INSENSITIVE_PCT else
                 ": the predictions depend on it, and their intervals carry this uncertainty.")
    return text


def _predictive_interval(m) -> str:
    pp = m.predictive_peak_hz
    if pp is None or pp["q05"] is None:
        return "—"
    return hz_range(pp["q05"], pp["q95"])


def status_blocks(status: dict) -> list[tuple]:
    """Report blocks stating the posterior's convergence (prominent warnings when it did not converge)."""
    conv = status.get("converged")
    word = {True: "yes", False: "NO", None: "unknown"}[conv if conv in (True, False) else None]
    text = (f"Posterior converged: {word}; largest R-hat {fmt(status.get('rhat_max'), 4)}, smallest bulk ESS "
            f"{fmt(status.get('ess_bulk_min'), 3)}, largest autocorrelation time {fmt(status.get('tau_max'), 3)} steps, "
            f"{status.get('n_steps') if status.get('n_steps') is not None else '?'} steps (from {status.get('source')}).")
    blocks: list[tuple] = [("p", text)]
    if status.get("warnings"):
        blocks.append(("h", 2, "Warnings from the identification" + (" — NOT CONVERGED" if conv is False else "")))
        blocks.append(("ul", [in_words(w) for w in status["warnings"]]))
    return blocks


def _table4(prediction: Prediction) -> tuple[list[str], list[list[str]]]:
    dominant = [m for m in prediction.modes if m.dominant]
    dirs = sorted({m.configuration.direction for m in dominant})
    lengths = sorted({m.configuration.clamping_length for m in dominant})
    head = ["clamping length (mm)"]
    for d in dirs:
        head += [f"ω_n,{d} measured (Hz)", f"ω_n,{d} model median (90 % credible) (Hz)",
                 f"new measured peak {d}, 90 % predictive (Hz)", f"error {d} (%)"]
    rows = []
    for length in lengths:
        row = [f"{length * 1e3:g}" + (" (fitted)" if any(m.fitted for m in dominant
                                                          if m.configuration.clamping_length == length) else "")]
        for d in dirs:
            ms = [m for m in dominant if m.configuration.clamping_length == length and m.configuration.direction == d]
            if not ms:
                row += ["—", "—", "—", "—"]
                continue
            m = ms[0]
            q = m.natural_frequency_hz
            err = None
            if m.measured_hz is not None and q["q50"] is not None:
                err = 100.0 * (q["q50"] - m.measured_hz) / m.measured_hz
            row += [hz(m.measured_hz, unit=False) if m.has_measurement else "not measured", fmt_interval(q, unit="Hz"),
                    _predictive_interval(m), fmt(err, 3)]
        rows.append(row)
    return head, rows


def _spindle_blocks(spindle: dict | None) -> list[tuple]:
    """The report's sentence on the spindle samples mixed into the draws (none without samples)."""
    if not spindle:
        return []
    return [("p", f"Spindle uncertainty included: every draw uses one of {spindle['n_samples']} bootstrap samples of "
                  f"the flange receptance from {spindle['file']} (directions {', '.join(spindle['directions'])}), "
                  "so the bands and intervals carry the spindle's uncertainty as well as the contact's.")]


def _blocks(run: PredictionRun, images: Sequence[str]) -> list[tuple]:
    p = run.prediction
    meta = run.meta
    blocks: list[tuple] = [
        ("h", 1, "Posterior predictions of the tool-point FRF"),
        ("p", f"Setup {meta['setup']}; posterior {meta['posterior']} ({identification_name(str(meta['method']))}, "
              f"fitted at {lengths_mm(meta['fit_lengths']) if meta['fit_lengths'] else '?'}); {meta['n_draws']} of "
              f"{meta['n_draws_available']} draws (subset seed {meta['subset_seed']})."),
        ("p", "Parameter model taken from the " + str(meta.get("parameter_model_source", "posterior"))
              + (f" (model terms: {', '.join(map(effect_name, meta['model_terms']))})" if meta.get("model_terms")
                 else "") + ". "
              + " ".join(in_words(n if n.endswith(".") else n + ".", keys=False)
                         for n in meta.get("parameter_model_notes", []))),
        *status_blocks(meta.get("posterior_status", {})),
        *_spindle_blocks(meta.get("spindle_uncertainty")),
        ("h", 2, "Dominant natural frequency: measured vs predicted (cf. the reference paper's Table 4)"),
        ("table", *_table4(p)),
        ("p", "Two intervals, for two questions. The model's 90 % credible interval says where the noise-free "
              "natural frequency of the identified model lies. The 90 % predictive interval says where the peak of "
              "a NEW hammer test would fall: each draw's FRF with simulated measurement noise of the fit's noise "
              "model, the same rule applied; a measured value is to be compared with this one. "
              "Natural-frequency rule: " + NATURAL_FREQUENCY_RULE.replace("NaN", "no value") + "."),
        ("h", 2, "All modes"),
    ]
    head = ["length (mm)", "dir", "mode", "band (Hz)", "model natural frequency median (90 % credible) (Hz)",
            "new measured peak, 90 % predictive (Hz)", "measured (Hz)",
            "peak |H| median (90 %) (m/N)", "dynamic stiffness median (90 %) (N/m)", "draws without peak"]
    rows = []
    for m in p.modes:
        c = m.configuration
        rows.append([f"{c.clamping_length * 1e3:g}", c.direction, f"{m.mode}{' (dominant)' if m.dominant else ''}",
                     f"{m.band_hz[0]:.0f}–{m.band_hz[1]:.0f}", fmt_interval(m.natural_frequency_hz, unit="Hz"),
                     _predictive_interval(m),
                     hz(m.measured_hz, unit=False) if m.has_measurement else "—",
                     fmt_interval(m.peak_magnitude, digits=3),
                     fmt_interval(m.dynamic_stiffness, digits=3), f"{100 * m.nan_fraction:.1f} %"])
    blocks.append(("table", head, rows))
    blocks.append(("p", "Modes: " + MODE_RULE + "."))
    summary = influence_summary(p.influence)
    if summary:
        blocks.append(("h", 2, "What the predictions depend on"))
        head = ["parameter", "posterior 90 % range", "verdict", "max change of dominant ω_n (Hz)",
                "max change (%)", "share of 90 % interval width"]
        rows = []
        for name, s in summary.items():
            ident = (run.identifiability or {}).get(name)
            _, lo, hi = sci_parts(None, s["posterior_q05"], s["posterior_q95"], 3)
            rows.append([parameter_name(name), f"{lo}–{hi} {_unit(name)}".rstrip(),
                         in_words(ident["verdict"]) if ident else "—", fmt(s["max_delta_hz"], 3), fmt(s["max_delta_pct"], 3),
                         fmt(s["max_fraction_of_interval"], 3)])
        blocks.append(("table", head, rows))
        blocks.append(("p", "Influence of a parameter: the draws are split into equally populated bins of its value "
                            "(the other parameters following their posterior given that value) and the spread of the "
                            "bin medians of the predicted dominant natural frequency is reported (largest over the "
                            f"predicted configurations); below about 0.1 of the interval width it is Monte Carlo noise. "
                            f"A change below {INSENSITIVE_PCT:g} % counts as insensitive."))
        statements = []
        for name in summary:
            ident = (run.identifiability or {}).get(name)
            if ident:
                s = undetermined_statement(name, ident, summary.get(name))
                if s:
                    statements.append(s)
        if statements:
            blocks.append(("h", 2, "Not determined by the data"))
            blocks.append(("ul", statements))
        if run.identifiability is not None:
            blocks.append(("p", "Verdict rule: " + VERDICT_RULE + "."))
    for img in images:
        blocks.append(("img", img, img))
    return blocks


def write_prediction_outputs(run: PredictionRun, out_dir, plots: bool = True, warnings: Sequence[str] = ()) -> list[Path]:
    """Write frequencies.json, frf_bands.csv, plots and report.md/.html to ``out_dir``.

    ``warnings`` (the command's printed warnings) go into frequencies.json as ``"warnings"``.
    """
    from ..inference.results import to_jsonable
    from . import plots as P

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    images = []
    if plots:
        P.frf_band_plot(run.prediction.bands, run.prediction.modes, out / "frf_bands.png",
                        title=f"Posterior predictive |H| ({run.meta['n_draws']} draws)")
        P.frf_zoom_plot(run.prediction.bands, run.prediction.modes, out / "frf_zoom.png")
        P.natural_frequency_plot(run.prediction.modes, out / "natural_frequencies.png")
        images = ["natural_frequencies.png", "frf_zoom.png", "frf_bands.png"]
        written += [out / i for i in images]
    written.append(_write_bands_csv(out / "frf_bands.csv", run.prediction))
    text = json.dumps(to_jsonable(frequencies_document(run, warnings)), indent=2, allow_nan=False)
    with atomic_path(out / "frequencies.json") as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    written.append(out / "frequencies.json")
    written += write_report(out, "report", _blocks(run, images), "bayes-rcsa predictions")
    return written
