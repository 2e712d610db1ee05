"""The discrepancy workflow in words: summary.md and the one line the command line prints.

Both are made from the document discrepancy.json alone (:mod:`.document`), so a folder written earlier
reads back into the same text.
"""

from __future__ import annotations

import math

from ..units import hz, hz_range, length_mm, num, percent, sci
from ..vocabulary import effect_name, effect_sentence, parameter_name
from .document import MIN_LENGTHS_FOR_BEND
from .select import LN_BF_NAME

__all__ = ["summary_markdown", "summary_line", "law_shape_lines", "second_effect_lines", "HELD_OUT_GAP_NOTE"]


#: Systematic gap at the setup's unfitted measurements above which summary.md and the command line say that
#: the fit does not carry to them (5 %: ten times the gap of a clean two-length fit on the benches).
HELD_OUT_GAP_NOTE = 0.05


def summary_markdown(report: dict) -> str:
    """A short summary a machinist can read."""
    lines = ["# Model check: does the model explain the measurements?", ""]
    named = report["named_effect"]
    held = report.get("gap_held_out_after")
    poor_transfer = held is not None and held > max(HELD_OUT_GAP_NOTE, 2 * report["gap_resolution"])
    if report["adequate"]:
        lines.append("The model explains the measurements it was fitted to: no systematic disagreement was found "
                     "there, so no effect was added.")
        if poor_transfer:
            lines.append(f"**At the clamping lengths it was not fitted to, the systematic mismatch is "
                         f"{percent(held, 3)}:** the fit does not carry there (with one fitted length the growth of "
                         "the contact stiffness is not identified); fit two or more lengths before predicting them.")
    elif named:
        lines.append(f"**Missing effect found: {effect_name(named)}** — {effect_sentence(named)}")
        params = next((c["parameters"] for c in report["candidates"] if c["effect"] == named), {})
        for n, q in params.items():
            lines.append(f"- {parameter_name(n)}: {num(q['q50'])} (90 % interval {num(q['q05'])} to {num(q['q95'])})")
        decided = report.get("held_out_decided")
        if decided:
            lines.append("")
            lines.append(f"{effect_name(decided['instead_of'])} fits the measured clamping lengths about as well, but "
                         f"the clamping lengths that were not fitted decide: {effect_name(named)} carries to them "
                         f"(remaining mismatch there {percent(decided['held_out_gap_named'], 3)}), "
                         f"{effect_name(decided['instead_of'])} does not as well "
                         f"({percent(decided['held_out_gap_instead_of'], 3)}).  Those measurements chose the name; "
                         "the model's parameters are still fitted to the fitted lengths only.")
        if report["confounded_with"]:
            lines.append("")
            lines.append(f"The data explain this equally well by: {_effects(report['confounded_with'])}. "
                         "To tell them apart: " + "; ".join(report["separating_test"].values()) + ".")
        elif report["runner_up"] and not decided:
            lines.append(f"Next best explanation: {effect_name(report['runner_up'])} (behind by "
                         f"{report['margin']:.1f} log units).")
        lines += second_effect_lines(report)
        lines.append("")
        lines.append("`setup.amended.toml` adds " + ("them" if report.get("also_named") else "it")
                     + " to the model; use it for the next `bayes-rcsa identify`.")
    else:
        lines.append("The model disagrees with the measurements, and none of the known effects explains it. "
                     "A statistical discrepancy term was added to widen the stiffness and frequency intervals. "
                     "Reasons for the disagreement:")
        lines += [f"- {r}" for r in report["detection"]["reasons"]]
        for part in report.get("partially_explained_by", []):
            ratio = part["systematic_gap_ratio"]
            if part.get("held_out_gap_grew"):
                lines.append(f"- {effect_name(part['effect'])} fits the fitted lengths decisively better but makes the "
                             "clamping lengths it was not fitted to worse: it does not carry, so it is not named")
            elif part.get("contact_held_on_upper_bound"):
                lines.append(f"- {effect_name(part['effect'])} improves the fit decisively but keeps "
                             f"{_parameters(part['contact_held_on_upper_bound'])} on the stiffest value its prior "
                             "allows, as the original model did, and leaves a systematic mismatch: the measured "
                             "structure is stiffer than the declared one (tool modulus, diameter?), which this term "
                             "does not explain")
            elif part.get("outranked_by_edge") or part.get("outranked_by_implausible"):
                by = part.get("outranked_by_edge") or part.get("outranked_by_implausible")
                cand = next((c for c in report.get("candidates", []) if c["effect"] == by), {})
                if part.get("outranked_by_edge"):
                    lim = cand.get("parameters_on_range_limit") or cand.get("parameters_on_prior_edge") or []
                    why = (f"only with {_parameters(lim) or 'a parameter'} on "
                           "the limit of the physical range its prior allows: the effect is larger than that term "
                           "allows (check the declared values it acts on) or lies outside the library")
                else:
                    why = (f"only with a fit that is physically impossible ({'; '.join(cand.get('implausible', []))}"
                           "): it stands in for an effect outside the library")
                crit = cand.get("criterion")
                far = crit is not None and crit - part["criterion"] > LN_BF_NAME
                lines.append(f"- {effect_name(part['effect'])} improves the fit decisively, but {effect_name(by)} "
                             "explains the data "
                             + ("far better" if far else "as well as it does together with a second known effect")
                             + (f" (criterion {crit:+.1f} against {part['criterion']:+.1f}"
                                + ("" if far else " alone") + ")" if crit is not None else "")
                             + f", {why}; neither is named")
            elif ratio is not None:
                lines.append(f"- {effect_name(part['effect'])} improves the fit decisively but removes only "
                             f"{100 * (1 - ratio):.0f} % of the systematic mismatch: at most part of the explanation")
        lines += pair_lines(report)
        if report.get("mode_bias", {}).get("applied"):
            n_fit = len({round(m["clamping_length"], 9) for m in report.get("measurements_after", []) if m["fitted"]})
            if n_fit < 2:
                how = ("With one measured length the bias's change with clamping length is not seen at all, and "
                       "predictions at other lengths rest on its spread alone. Measure the clamping length you need "
                       "(or two more) to test and narrow them.")
            elif n_fit < MIN_LENGTHS_FOR_BEND:
                how = ("With two measured lengths the interpolation is a straight line that the data cannot "
                       "test, and the intervals there can be off by about one of their own standard deviations. "
                       "Measure the clamping length you need (or a third one) to test and narrow them.")
            elif n_fit == MIN_LENGTHS_FOR_BEND:
                # docs/discrepancy.md, "What a fourth tap buys": one contrast per mode leaves the bend's size open
                how = ("With three measured lengths the bend of that bias between them is judged from one "
                       "difference per mode, which cannot tell a small smooth bend from a rougher one, so the "
                       "intervals between them err on the wide side (on the project's independent bench up to 1.7 "
                       "times the errors). A fourth measured length narrows them.")
            else:
                how = (f"With {n_fit} measured lengths the bend of that bias between them is judged from "
                       f"{n_fit - 2} differences per mode.")
            lines += ["", "The mode frequencies carry the bias between model and measurement learned at the "
                      "measured clamping lengths; between them that bias is interpolated with its uncertainty, "
                      "so predictions at other clamping lengths are wider than the model alone would say. " + how]
        lines += law_shape_lines(report.get("law_shape_prior"))
    missed = report.get("decisive_not_named", [])
    if missed:
        lines += ["", "Effects that fit decisively better than the model (criterion above ln 100) but are not named:"]
        for m in missed:
            part = f", removes {100 * m['explains']:.0f} % of the systematic mismatch" if m.get("explains") is not None else ""
            lines.append(f"- {effect_name(m['effect'])} (criterion {m['criterion']:+.1f}{part}): {m['reason']}. "
                         f"To decide: {m['deciding_test']}.")
    if report.get("gap_grew"):
        labels = {"gap": "overall", "gap_fitted": "at the fitted clamping lengths",
                  "gap_held_out": "at the clamping lengths not fitted"}
        grown = report.get("gaps_grown") or ["gap"]
        detail = "; ".join(f"{labels.get(k, k)} {percent(report[k + '_before'])} -> {percent(report[k + '_after'])}"
                           for k in grown if report.get(k + "_before") is not None)
        lines += ["", f"**The systematic mismatch grew** in the final model ({detail}): the added term makes the "
                  "fit worse, not more honest."]
    if not report.get("usable_for_prediction", True):
        lines += ["", "**Not usable for prediction.** The final model's intervals are too narrow for the "
                  "disagreement, so no frequency interval below may be used to choose a spindle speed:"]
        lines += [f"- {r}" for r in report["usable_for_prediction_reasons"]]
    where = []
    for m in report["detection"]["measurements"]:
        notes = list(m["resonance"]["findings"])
        notes += [f"misfit {b['lo_hz']:.0f}–{b['hi_hz']:.0f} Hz" for b in m["bands"][:3]]
        if notes:
            where.append(f"- {m['direction']} {length_mm(m['clamping_length'])}: " + "; ".join(notes))
    if where:
        lines += ["", "Where the original model disagreed with the measurements:"] + where
    trend = report["detection"]["trend_with_clamping_length"]
    if trend is not None and not report["adequate"]:
        lines.append(f"- frequency error trend with clamping length: {trend['slope_pct_per_mm']:+.3f} % per mm")
    for name in report.get("final_prior_bound_pile_up", []):
        lines += ["", f"**Warning:** in the final model the {parameter_name(name)} piles up on its prior bound: its interval, and "
                  "every prediction that depends on it, holds only if the bound is right."]
    def gap_text(key: str) -> str:
        if report.get(f"{key}_at_noise_floor"):
            return f"at the noise floor (below {percent(report['gap_resolution'])})"
        return percent(report[key])

    lines += ["", f"Systematic mismatch (gap, measurement noise excluded) before: {gap_text('gap_before')}, "
              f"after: {gap_text('gap_after')}; with the noise: {percent(report['gap_raw_before'])} "
              f"-> {percent(report['gap_raw_after'])}", "",
              "| clamping length (mm) | frequency error before (%) | after (%) |", "|---|---|---|"]
    for k in report["frequency_error_pct_before"]:
        lines.append(f"| {k} | {report['frequency_error_pct_before'][k]:+.2f} | {report['frequency_error_pct_after'].get(k, math.nan):+.2f} |")
    usable = report.get("usable_for_prediction", True)
    lines += ["", "Every mode in the band, model mode matched one to one with measured mode (never the model's "
              "highest peak against the measured highest peak when those are different modes); intervals are "
              "the model's 90 % interval and, after, the 90 % predictive interval with measurement noise:", "",
              "| measurement | fitted | mode measured (Hz) | model before, 90 % interval (Hz) | model after (Hz) "
              "| predictive after (Hz) |", "|---|---|---|---|---|---|"]
    for mb, ma in zip(report["measurements_before"], report["measurements_after"]):
        before = {round(m["measured_hz"], 6): m for m in mb["modes"]}
        for md in ma["modes"]:
            b = before.get(round(md["measured_hz"], 6))
            qb = b["model_interval"] if b else None
            qa, qp = md["model_interval"], md["predictive_interval"]
            star = "" if usable else " (not usable)"
            if usable and md.get("straight_line_bias_assumed"):
                star = " (straight-line bias assumed)"
            lines.append(f"| {ma['direction']} {ma['clamping_length'] * 1e3:g} mm | {'yes' if ma['fitted'] else 'no'} "
                         f"| {md['measured_hz']:.1f}{' (most prominent)' if md['most_prominent_measured'] else ''} "
                         + (f"| {_hz(qb)} " if qb else "| no matching mode ")
                         + f"| {_hz(qa)}{star} "
                         f"| {_hz(qp, median=False)}{star} |")
        for fu in ma["unmatched_measured_hz"]:
            lines.append(f"| {ma['direction']} {ma['clamping_length'] * 1e3:g} mm | {'yes' if ma['fitted'] else 'no'} "
                         f"| {fu:.1f} | | no matching model mode | |")
        if ma["prominent_mode_differs"]:
            lines.append(f"| {ma['direction']} {ma['clamping_length'] * 1e3:g} mm | | the most prominent mode "
                         "differs between model and measurement | | | |")
    k_name = parameter_name("k_xf")
    lines += ["", f"| clamping length (mm) | {k_name} before, median (90 % interval) | {k_name} after |",
              "|---|---|---|"]
    for k, q in report["stiffness_before"]["k_xf"].items():
        qa = report["stiffness_after"]["k_xf"][k]
        lines.append(f"| {k} | {sci(q['q50'], 3, q['q05'], q['q95'], 'N/m')} | "
                     f"{sci(qa['q50'], 3, qa['q05'], qa['q95'], 'N/m')} |")
    return "\n".join(lines) + "\n"


def law_shape_lines(entry: dict | None) -> list[str]:
    """What summary.md says of the prior of the contact law's shape between the fitted lengths (none: no lines)."""
    if not entry:
        return []
    scale = ("Between the measured clamping lengths the contact stiffness may follow anything from a straight line "
             "(contact spread along the shank) to the law of two springs in series (collet and shank contact); on a "
             "scale from 0 (straight) to 1 (two springs), ")
    if entry["source"] == "library":
        n = entry.get("n_combinations")
        whose = f"the {n} tool-holder combinations" if n else "the combinations"
        mean, sd, lo, hi = (num(entry[k], 2) for k in ("mean", "sd", "q05", "q95"))
        text = (f"{whose} of holder type {entry['holder_type']} in the tool library put it at {mean} ± {sd} "
                f"(90 % within {lo} to {hi}), and the predictions between and beyond the measured lengths use that.")
    elif entry["source"] == "setup":
        text = "the setup file's own prior for it is used."
    else:
        text = ("nothing here narrows where it lies, so the predictions at other lengths allow the whole range "
                "between the two.")
    return ["", scale + text]


def second_effect_lines(report: dict) -> list[str]:
    """summary.md's lines on a second effect named with the first, and on any that explains it almost as well."""
    lines = []
    named = report["named_effect"]
    for also in report.get("also_named", []):
        lines += ["", f"**A second effect was found with it: {effect_name(also)}** — {effect_sentence(also)} "
                  f"(second round, with {effect_name(named)} in the model)."]
        for q in (report.get("second_round") or {}).get("almost_as_well", []):
            share = q.get("systematic_gap_ratio")
            part = f", removing {100 * (1 - share):.0f} % of what was left" if share is not None else ""
            lines.append(f"{effect_name(q['effect'])} explains it almost as well (criterion {q['criterion']:+.1f}"
                         f"{part}). To tell them apart: {q['deciding_test']}.")
    return lines


def pair_lines(report: dict) -> list[str]:
    """One bullet per pair of known effects tried together that did not explain the mismatch either."""
    return [f"- {effect_name(pair['first'])} together with {effect_name(pair['second'])} was tried as a pair and "
            "does not explain the mismatch either (why: discrepancy.json, second_round.pairs_tried)"
            for pair in (report.get("second_round") or {}).get("pairs_tried", []) if pair.get("second")]


def _hz(q: dict, median: bool = True) -> str:
    """A mode's interval ``{q05, q50, q95}`` in Hz, in the digits the interval justifies (no unit: the column has it)."""
    return hz(q["q50"], q["q05"], q["q95"], unit=False) if median else hz_range(q["q05"], q["q95"])


def _effects(names) -> str:
    return ", ".join(effect_name(n) for n in names)


def _parameters(names) -> str:
    return ", ".join(parameter_name(n) for n in names)


def summary_line(report: dict, out=None) -> str:
    """The line ``bayes-rcsa discrepancy`` prints when it has finished.

    Parameters
    ----------
    report : dict, the document discrepancy.json
    out : path-like or None, the folder the files were written to (None: the line says nothing about files)
    """
    def pct(key):
        return "at the noise floor" if report[f"{key}_at_noise_floor"] else percent(report[key])

    gap = f"systematic gap {pct('gap_before')} -> {pct('gap_after')}"
    wrote = f"; wrote {out}/discrepancy.json" if out is not None else ""
    if report["named_effect"]:
        extra = f" (confounded with {_effects(report['confounded_with'])})" if report["confounded_with"] else ""
        both = " + ".join(effect_name(e) for e in [report["named_effect"], *report["also_named"]])
        return f"named {both}{extra}: {gap}" + (f"{wrote} and setup.amended.toml" if wrote else "")
    if report["adequate"]:
        held = report.get("gap_held_out_after")
        if held is not None and held > HELD_OUT_GAP_NOTE:
            gaps = (f"systematic gap {percent(report['gap_fitted_after'], 3)} at the fitted lengths, "
                    f"{percent(held, 3)} at the others, where the fit does not carry")
        else:
            gaps = f"systematic gap {pct('gap_before')}"
        return f"model adequate, nothing named ({gaps}){wrote}"
    return f"model inadequate and no known effect explains it: statistical discrepancy added ({gap}){wrote}"
