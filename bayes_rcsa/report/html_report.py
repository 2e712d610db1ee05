"""One self-contained HTML report from the outputs of identify, predict, identifiability, discrepancy, design and lobes.

:func:`build_report` reads the run directories (:mod:`.runs`), turns their
JSON documents into the template's context (numbers formatted for people,
booleans as words) and renders ``templates/report.html.j2`` with Jinja2.
Every figure is embedded as a PNG data URI, so the page can be mailed or
archived alone.  The tables show the numbers of the JSON files (rounded to
the digits printed), nothing recomputed; the figures that need the model
(geometry, zoomed FRF bands) are drawn from the setup and posterior files
the predict run names, and are left out with a note when those files are
not found.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import BayesRCSAError, DataError
from ..io.atomic import atomic_write_text
from ..units import hz, mm, num, rpm, sci_parts
from ..units import width as units_width
from ..vocabulary import depth_limit_name, effect_name, in_words, method_name, parameter_name
from . import figures as F
from .answer import answer_markdown, build_answer, template_environment, yes_no
from .cuts_section import cuts_section
from .library_section import library_section
from .runs import KINDS, RunDir, collect_runs

__all__ = ["build_report", "write_report_html", "write_summary_markdown", "answer_of_runs", "num", "yes_no", "FRF_DRAWS",
           "printed_names"]

FRF_DRAWS = 200  # posterior draws behind the zoomed FRF bands (5-95 % quantiles stable to ~1/sqrt(200 * 0.05))
ZOOM_LINES = 161  # lines of a mode's zoom window


def _mm(length_m) -> str:
    return num(1e3 * float(length_m), 4)


def printed_names(summary: dict, parameter_model=None) -> dict:
    """``{parameter identifier: printed name}`` of an identification (``summary.json``): contact parameters by
    the vocabulary, noise scales by their measurement (``noise scale, 25 mm x``), term parameters by their label."""
    names = list((summary.get("parameters") or {}) if summary else [])
    if summary:
        names += [n for n in (*(summary.get("parameter_names") or []), *(summary.get("fixed_parameters") or {}))
                  if n not in names]
    if parameter_model is not None:
        names += [n for n in parameter_model.all_names if n not in names]
    where = {}
    for m in (summary.get("measurements_used") or []) if summary else []:
        if m.get("noise_parameter"):
            where[m["noise_parameter"]] = f"{num(1e3 * m['clamping_length'])} mm {m.get('direction', '')}".strip()
    if parameter_model is not None:
        labels = {n: parameter_model[n].label for n in parameter_model.all_names}
    else:
        declared = (summary.get("parameter_model") or {}).get("parameters") if summary else None
        labels = {p["name"]: p.get("label") or "" for p in declared or [] if isinstance(p, dict) and "name" in p}
    return {n: (f"noise scale, {where[n]}" if n in where else parameter_name(n, labels.get(n, ""))) for n in names}


# -- sections ------------------------------------------------------------------


def _identify_section(run: RunDir) -> dict:
    s = run.document
    params = s.get("parameters", {}) or {}
    tau = s.get("tau", {}) or {}
    printed = printed_names(s)
    conv_rows = [{"name": printed.get(n, n), "rhat": num(p.get("rhat"), 4), "ess_bulk": num(p.get("ess_bulk"), 4),
                  "ess_tail": num(p.get("ess_tail"), 4), "tau": num(tau.get(n), 4),
                  "rhat_bad": p.get("rhat") is not None and p["rhat"] >= 1.01} for n, p in params.items()]
    par_rows = []
    for n, p in params.items():
        q50, q05, q95 = sci_parts(p.get("q50"), p.get("q05"), p.get("q95"), 3)
        par_rows.append({"name": printed.get(n, n), "unit": p.get("unit", ""), "q05": q05, "q50": q50, "q95": q95,
                         "mean": sci_parts(p.get("mean"), p.get("q05"), p.get("q95"), 3)[0],
                         "sd": num(p.get("sd"), 3)})
    corner = run.file("corner.png")
    trace = run.file("trace.png")
    how = s.get("sampler") or {}
    importance = None
    if how.get("mode") == "importance":
        importance = {"pareto_k": num(how.get("pareto_k"), 2), "ess": num(how.get("ess"), 4)}
        sampler_words = "importance sampling of the exact posterior (accepted)"
    elif how.get("fallback_reason"):
        sampler_words = f"emcee chain (importance sampling refused: {in_words(str(how['fallback_reason']))})"
    else:
        sampler_words = "emcee chain"
    return {
        "path": str(run.path),
        "importance": importance,
        "method": s.get("method"),
        "method_name": _identification_name(s),
        "converged": s.get("converged"),
        "converged_word": yes_no(s.get("converged")),
        "stop_reason": s.get("stop_reason"),
        "facts": [("sampler", sampler_words), ("converged", yes_no(s.get("converged"))), ("steps", num(s.get("n_steps"), 6)),
                  ("burn-in", num(s.get("burn_in"), 6)), ("thinning", num(s.get("thin"), 4)),
                  ("walkers", num(s.get("n_walkers"), 4)), ("draws", num(s.get("n_draws"), 6)),
                  ("acceptance fraction", num(s.get("acceptance_fraction"), 3)),
                  ("likelihood tempering β", num((s.get("likelihood") or {}).get("tempering"), 3))],
        "conv_rows": conv_rows,
        "par_rows": par_rows,
        "warnings": [in_words(str(w)) for w in s.get("warnings", [])],
        "corner": F.png_data_uri(corner) if corner else None,
        "trace": F.png_data_uri(trace) if trace else None,
    }


def _describe_prior(d: dict) -> str:
    if not d:
        return "—"
    dist = d.get("distribution", "?")
    if "lo" in d and "hi" in d:
        return f"{dist} from {num(d['lo'], 4)} to {num(d['hi'], 4)}"
    return dist + " " + ", ".join(f"{k} = {num(v) if isinstance(v, (int, float)) else v}"
                                   for k, v in d.items() if k != "distribution")


def _identification_name(summary: dict) -> str:
    from ..vocabulary import identification_name

    return identification_name(str(summary.get("method")), library=bool(summary.get("library")))


def _parameter_model_rows(pm, summary: dict | None = None) -> list[dict]:
    rows = []
    printed = printed_names(summary or {}, pm)
    for n in pm.all_names:
        p = pm[n]
        rows.append({"name": printed.get(n, n), "role": p.role, "status": "sampled" if p.sampled else "fixed",
                     "value": _describe_prior(p.prior.describe()) if p.sampled else num(p.value, 5),
                     "unit": pm.unit(n)})
    return rows


class _Posteriors(dict):
    """posterior.nc path -> PosteriorDraws, each file read once per report."""

    def get_draws(self, path):
        from ..posterior.draws import load_posterior

        key = str(Path(path).resolve())
        if key not in self:
            self[key] = load_posterior(path)
        return self[key]


def _setup_section(predict_run: RunDir | None, identify_run: RunDir | None, posteriors: _Posteriors) -> dict:
    """Geometry drawing and the sampled/fixed parameters (from the posterior's parameter model)."""
    out: dict = {"notes": [], "geometry": None, "parameter_rows": [], "setup": None, "posterior": None}
    posterior = None
    if predict_run is not None and predict_run.document.get("posterior"):
        posterior = Path(predict_run.document["posterior"])
    if (posterior is None or not posterior.is_file()) and identify_run is not None:
        posterior = identify_run.path / "posterior.nc"
    if posterior is not None and posterior.is_file():
        pm = posteriors.get_draws(posterior).parameters
        out["parameter_rows"] = _parameter_model_rows(pm, identify_run.document if identify_run is not None else None)
        out["posterior"] = str(posterior)
    elif identify_run is not None:  # summary.json only: the same facts without the model object
        s = identify_run.document
        printed = printed_names(s)
        out["parameter_rows"] = ([{"name": printed.get(n, parameter_name(n)), "role": "", "status": "sampled", "value": _describe_prior(d),
                                   "unit": (s.get("parameters", {}).get(n) or {}).get("unit", "")}
                                  for n, d in (s.get("priors") or {}).items()]
                                 + [{"name": printed.get(n, parameter_name(n)), "role": "", "status": "fixed", "value": num(v, 5), "unit": ""}
                                    for n, v in (s.get("fixed_parameters") or {}).items()])
    setup_path = predict_run.document.get("setup") if predict_run is not None else None
    if setup_path and Path(setup_path).is_file():
        from ..io.setup import load_setup

        setup = load_setup(setup_path, load_data=False, load_spindle=False)
        out["setup"] = str(setup_path)
        out["name"] = setup.name
        lengths = predict_run.document.get("fit_lengths") or predict_run.document.get("lengths") or []
        tool = next(iter(setup.tools.values()))
        cl = float(lengths[0]) if lengths else float(sum(setup.feasible_range) / 2)
        out["geometry"] = F.geometry_figure(setup.holder, tool, cl, tuple(setup.feasible_range))
        out["geometry_length"] = _mm(cl)
    else:
        out["notes"].append("geometry drawing left out: no predict run naming a readable setup file was given")
    return out


def _zoom_windows(modes: list[dict]) -> None:
    """Set each mode's zoom window: wide enough for its predictive interval, a few % of its frequency."""
    for m in modes:
        c = m.get("q50_hz") or 0.5 * (m["band_lo_hz"] + m["band_hi_hz"])
        lo_p = m.get("predictive_peak_q05_hz") or m.get("q05_hz") or c
        hi_p = m.get("predictive_peak_q95_hz") or m.get("q95_hz") or c
        half = max(4.0 * (hi_p - lo_p), 0.015 * c)
        m["zoom_lo_hz"] = max(c - half, m["band_lo_hz"])
        m["zoom_hi_hz"] = min(c + half, m["band_hi_hz"])


def _frf_figures(run: RunDir, posteriors: _Posteriors, seed: int = 0) -> tuple[list[str], list[str]]:
    """Zoomed |H| and phase bands of every predicted configuration (needs its setup and posterior)."""
    doc = run.document
    setup_path, posterior = doc.get("setup"), doc.get("posterior")
    if not (setup_path and Path(setup_path).is_file() and posterior and Path(posterior).is_file()):
        return [], [f"zoomed FRF bands left out: setup {setup_path} or posterior {posterior} not found"]
    from ..io.setup import load_setup
    from ..model.assembly import Configuration
    from ..posterior.predict import predictive_frf

    setup = load_setup(setup_path)
    draws = posteriors.get_draws(posterior).subset(FRF_DRAWS, np.random.default_rng(seed))
    model = setup.model()
    groups: dict = {}
    for p in doc.get("predictions", []):
        groups.setdefault((p["clamping_length"], p["direction"], p["tool"]), []).append(dict(p))
    uris = []
    for (length, d, tool), modes in groups.items():
        _zoom_windows(modes)
        f = np.unique(np.concatenate([np.linspace(m["zoom_lo_hz"], m["zoom_hi_hz"], ZOOM_LINES) for m in modes]))
        cfg = Configuration(float(length), d, tool)
        h = predictive_frf(draws, model, cfg, f)
        meas = next((m.frf for m in setup.measurements if m.configuration.direction == d and m.configuration.tool == tool
                     and abs(m.configuration.clamping_length - length) < 1e-7), None)
        uris.append(F.frf_zoom_figure(f"{_mm(length)} mm, {d}", f, h, modes, meas))
    return uris, []


def _predict_section(run: RunDir, posteriors: _Posteriors, seed: int) -> dict:
    doc = run.document
    rows = []
    for p in doc.get("predictions", []):
        model = hz(p.get("q50_hz"), p.get("q05_hz"), p.get("q95_hz"), unit=False)
        new_peak = hz(None, p.get("predictive_peak_q05_hz"), p.get("predictive_peak_q95_hz"), unit=False)
        rows.append({
            "length": _mm(p["clamping_length"]), "direction": p["direction"], "mode": p["mode"],
            "dominant": yes_no(p.get("dominant")), "fitted": yes_no(p.get("fitted")) if "fitted" in p else "not measured",
            "measured": hz(p.get("measured_hz"), unit=False),
            "model_q05": _end(model, 0), "model_q50": model.split(" ")[0], "model_q95": _end(model, 1),
            "pred_q05": _end(new_peak, 0), "pred_q95": _end(new_peak, 1),
            "in_model": yes_no(p.get("measured_in_90")) if "measured_hz" in p else "—",
            "in_pred": yes_no(p.get("measured_in_predictive_90")) if "measured_hz" in p else "—",
        })
    status = dict(doc.get("posterior_status") or {})
    status["warnings"] = [in_words(str(w)) for w in status.get("warnings") or []]
    frf, notes = _frf_figures(run, posteriors, seed)
    images = [F.png_data_uri(p) for p in (run.file("natural_frequencies.png"),) if p]
    ident_rows = []
    for name, e in (doc.get("identifiability") or {}).items():
        ratio = e.get("prior_to_posterior_width")
        _, q05, q95 = sci_parts(None, e.get("q05"), e.get("q95"), 4)
        ident_rows.append({"name": parameter_name(name), "verdict": in_words(e.get("verdict", "—")),
                           "width_ratio": num(ratio, 3) if ratio is not None else "—",
                           "partner": parameter_name(e["partner"]) if e.get("partner") else "—",
                           "correlation": num(e.get("correlation"), 3), "q05": q05, "q95": q95})
    return {"path": str(run.path), "rows": rows, "status": status,
            "status_converged": yes_no(status.get("converged")),
            "interval_definitions": doc.get("interval_definitions") or {}, "frf": frf, "notes": notes,
            "images": images, "ident_rows": ident_rows, "verdict_rule": doc.get("verdict_rule"),
            "noise": doc.get("predictive_noise")}


def _lobes_section(run: RunDir) -> dict:
    doc = run.document
    rec = doc.get("recommended")
    facts = []
    if rec:
        facts = [("spindle speed (rpm)", rpm(rec.get("spindle_speed_rpm"), unit=False)),
                 ("axial depth (mm)", mm(rec.get("depth_m")).removesuffix(" mm")),
                 ("P(stable)", num(rec.get("p_stable"), 3)),
                 ("P(stable) in the speed/depth neighbourhood", num(rec.get("p_stable_neighbourhood"), 3)),
                 ("depth set by", depth_limit_name(rec.get("binding_limit") or "stability"))]
    images = [F.png_data_uri(p) for p in (run.file("lobes.png"),) if p]
    npz = run.file("p_stable.npz")
    if npz:
        with np.load(npz) as z:
            images.append(F.p_stable_figure(z["spindle_speed_rpm"], z["depth_m"], z["p_stable"],
                                            float(doc.get("level", 0.95)), rec))
    src = doc.get("source") or {}
    return {"path": str(run.path), "recommended": rec, "facts": facts, "images": images,
            "level": num(doc.get("level"), 3), "method": method_name(str(doc.get("method"))),
            "n_draws": doc.get("n_draws"),
            "warnings": [in_words(str(w)) for w in doc.get("warnings", [])],
            "clamping": _mm(src["clamping_length_m"]) if src.get("clamping_length_m") else None,
            "cutting": doc.get("cutting") or {}}


def _images(run: RunDir, names: Sequence[str]) -> list[str]:
    return [F.png_data_uri(p) for p in (run.file(n) for n in names) if p]


def _identifiability_section(run: RunDir) -> dict:
    doc = run.document
    return {"path": str(run.path), "findings": [str(f) for f in doc.get("findings", [])],
            "images": _images(run, ("forest.png", "corner_overlay.png"))}


def _discrepancy_section(run: RunDir) -> dict:
    from ..discrepancy.render import law_shape_lines

    d = run.document
    rows = [{"key": k, "before": num(v, 3), "after": num((d.get("frequency_error_pct_after") or {}).get(k), 3)}
            for k, v in (d.get("frequency_error_pct_before") or {}).items()]
    return {"path": str(run.path), "adequate": yes_no(d.get("adequate")),
            "named": effect_name(d["named_effect"]) if d.get("named_effect") else "nothing is missing",
            "confounded": ", ".join(map(effect_name, d.get("confounded_with") or [])) or "no other",
            "gap_before": num(100 * d["gap_before"], 3) if d.get("gap_before") is not None else "—",
            "gap_after": num(100 * d["gap_after"], 3) if d.get("gap_after") is not None else "—",
            "runner_up": effect_name(d["runner_up"]) if d.get("runner_up") else "—", "rows": rows,
            "reasons": [in_words(str(r)) for r in ((d.get("detection") or {}).get("reasons") or [])],
            # decisive candidates not named, each with why and the test that decides it (issue #43: none in silence)
            "not_named": [f"{effect_name(m['effect'])} (criterion {m['criterion']:+.1f}): {m['reason']}. "
                          f"To decide: {m['deciding_test']}." for m in d.get("decisive_not_named") or []]
            + [f"{effect_name(q['effect'])} (criterion {q['criterion']:+.1f}) explains the second effect almost as "
               f"well. To decide: {q['deciding_test']}." for q in (d.get("second_round") or {}).get("almost_as_well", [])],
            "grew": bool(d.get("gap_grew")),
            # the unexplained remainder's law shape between the fitted lengths: a tool library's or the envelope
            "law_shape": " ".join(law_shape_lines(d.get("law_shape_prior"))).strip(),
            "images": _images(run, ("frf_before_after.png", "frequency_errors.png", "stiffness_before_after.png"))}


def _design_section(run: RunDir) -> dict:
    d = run.document
    best = d.get("best") or {}
    unit = d.get("unit", "")
    shown = "mm" if unit == "m" else unit

    def width(x):
        return units_width(x, unit).removesuffix(f" {shown}") if x is not None else "—"

    return {"path": str(run.path), "verdict": d.get("verdict", "—"), "worth_it": yes_no(d.get("worth_it")),
            "target": d.get("target", "—"), "unit": shown, "best": best.get("test", "—"),
            "current_width": width(d.get("current_width")), "expected_width": width(best.get("expected_width")),
            "mc_error": width(best.get("mc_error")), "images": _images(run, ("design.png",))}


def _end(text: str, i: int) -> str:
    """End ``i`` (0 low, 1 high) of the interval in :func:`~bayes_rcsa.units.hz`'s text ``"median (lo–hi)"``."""
    if "(" not in text:
        return "—"
    return text.split("(", 1)[1].rstrip(")").split("–")[i]


# -- assembly ------------------------------------------------------------------


def answer_of_runs(runs: Sequence[RunDir]):
    """The summary block (:class:`~bayes_rcsa.report.answer.Answer`) of run directories, numbered as their
    sections in the report."""
    return build_answer((r.kind, str(r.path / KINDS[r.kind]), r.document) for r in runs)


def _title(runs) -> str:
    """The setup's name (from the first run that names a readable setup file), else a plain title."""
    for r in runs:
        setup = (r.document.get("source") or {}).get("setup") if r.kind == "lobes" else r.document.get("setup")
        if isinstance(setup, str) and Path(setup).is_file():
            try:
                from ..io.setup import load_setup

                return f"{load_setup(setup, load_data=False, load_spindle=False).name}: bayes_rcsa report"
            except (BayesRCSAError, OSError):  # the title is a courtesy; a damaged setup is named by its section
                continue
    return "bayes_rcsa report"


def build_report(paths: Sequence, seed: int = 0, title: str | None = None) -> str:
    """The report's HTML text from run directories ``paths``.

    Parameters
    ----------
    paths : sequence of path-like
        Output directories of identify, predict, identifiability,
        discrepancy, design and lobes (any subset; a demo directory expands
        to its sub-directories).
    seed : int
        Seed of the draw subset behind the zoomed FRF bands.
    title : str, optional

    Raises
    ------
    DataError
        No run directory, an unreadable or malformed output file.
    """
    runs = collect_runs(paths)
    by_kind: dict[str, list[RunDir]] = {}
    for r in runs:
        by_kind.setdefault(r.kind, []).append(r)
    first = lambda k: by_kind.get(k, [None])[0]  # noqa: E731
    posteriors = _Posteriors()
    try:
        ctx = {
            "title": title or _title(runs),
            "runs": [(r.kind, str(r.path)) for r in runs],
            "setup": _setup_section(first("predict"), first("identify"), posteriors),
            "identify": [_identify_section(r) for r in by_kind.get("identify", [])],
            "predict": [_predict_section(r, posteriors, seed) for r in by_kind.get("predict", [])],
            "identifiability": [_identifiability_section(r) for r in by_kind.get("identifiability", [])],
            "discrepancy": [_discrepancy_section(r) for r in by_kind.get("discrepancy", [])],
            "lobes": [_lobes_section(r) for r in by_kind.get("lobes", [])],
            "design": [_design_section(r) for r in by_kind.get("design", [])],
            "cuts": [cuts_section(r) for r in by_kind.get("update", [])],
            "library": [library_section(r) for r in by_kind.get("library", [])],
            "answer": answer_of_runs(runs),
            "href": "",
        }
    except (KeyError, TypeError) as exc:
        raise DataError(f"an output file lacks an expected entry ({exc!r}); was it written by this bayes_rcsa?") from None
    return template_environment().get_template("report.html.j2").render(**ctx)


def write_report_html(paths: Sequence, out, seed: int = 0, title: str | None = None, summary_md=None) -> Path:
    """Build the report (everything validated first) and write it atomically to ``out``; returns the path.

    Parameters
    ----------
    paths, seed, title
        As :func:`build_report`.
    out : path-like
        The HTML file.
    summary_md : path-like, optional
        Also write the report's summary block as Markdown there (:func:`~bayes_rcsa.report.answer.answer_markdown`,
        links into ``out``).
    """
    text = build_report(paths, seed=seed, title=title)
    out = Path(out)
    atomic_write_text(out, text)  # makes the missing folders, and removes them again if the write fails
    if summary_md is not None:
        write_summary_markdown(paths, out, summary_md)
    return out


def write_summary_markdown(paths: Sequence, out, summary_md) -> Path:
    """Write the summary block of the report of ``paths`` as Markdown to ``summary_md`` (links into the HTML
    file ``out``); returns its path."""
    summary_md = Path(summary_md)
    href = os.path.relpath(Path(out).resolve(), summary_md.resolve().parent).replace(os.sep, "/")
    atomic_write_text(summary_md, answer_markdown(answer_of_runs(collect_runs(paths)), href=href))
    return summary_md
