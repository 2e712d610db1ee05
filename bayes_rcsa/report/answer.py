"""The answer first: the summary block that heads ``report.html``, the demo's ``index.html`` and ``summary.md``.

A machinist reads the first screen and decides from it.  The block holds,
read from the commands' JSON documents (nothing recomputed):

* the recommended spindle speed and axial depth of every lobes run, with
  their margins (speed tolerance and the distance to the nearest unstable
  speed, depth margin and the distance to the limit above) and the
  confidence they hold at (the required P(stable), the lowest P(stable)
  over the checked neighbourhood, the confidence of the robust envelope and
  the depth it costs against the median point when the lobes run wrote
  them: ``robust_envelope``, ``confidence_cost``, ``median_recommended``);
* the tool-point natural frequency (dominant mode) at each predicted
  clamping length and direction, with the model's 90 % credible interval
  and the 90 % predictive interval of a new hammer test;
* the model check's verdict (adequate, named effect, or remainder) in one
  sentence;
* convergence in one word, with a link to the details;
* the warnings that change the decision: an unconverged sampler, a
  posterior piled up on a prior bound, a model check that is not usable for
  prediction or whose systematic gap grew.

:func:`build_answer` turns the documents into an :class:`Answer`;
:func:`answer_html` renders it as an HTML fragment (template
``templates/answer.html.j2``, autoescaped: names are user strings) and
:func:`answer_markdown` as Markdown.  :data:`ANSWER_CSS` is its style,
included in the ``<head>`` of every page that shows it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable


from ..errors import DataError
from ..units import hz, hz_range, mm, num
from ..vocabulary import depth_limit_name, effect_name, in_words, method_name

__all__ = ["Answer", "build_answer", "answer_html", "answer_markdown", "answer_css", "template_environment",
           "num", "yes_no"]


def yes_no(b) -> str:
    """``yes``/``no`` for a boolean, ``unknown`` for ``None``."""
    return "unknown" if b is None else ("yes" if b else "no")


def template_environment():
    """The Jinja2 environment of the report templates (autoescaped HTML, strict undefined names)."""
    import jinja2

    return jinja2.Environment(loader=jinja2.PackageLoader("bayes_rcsa.report", "templates"),
                              autoescape=jinja2.select_autoescape(["html", "j2"]), undefined=jinja2.StrictUndefined,
                              trim_blocks=True, lstrip_blocks=True)


# -- the answer ------------------------------------------------------------------------------------------


@dataclass
class Answer:
    """The summary block's content, formatted for people.

    Attributes
    ----------
    points : list of dict
        One per lobes run: ``index`` (its section number), ``clamping`` (mm text or None), ``speed`` (rpm
        text), ``depth`` (mm text), ``facts`` ((label, sentence) pairs: margins and the confidence), ``source``
        (method and draws),
        ``none`` (why there is no recommendation, or None).
    frequencies : list of dict
        One per predicted clamping length and direction (dominant mode): ``length`` (mm), ``direction``,
        ``median``, ``interval`` (model 90 %), ``predictive`` (new hammer test, 90 %), ``measured``,
        ``held_out`` (measured but not fitted), ``index`` (predict section number).
    model_check : list of dict
        One per discrepancy run: ``sentence``, ``index``.
    convergence : list of dict
        One per identify run (or predict run when no identify run is given): ``word``
        (``converged``/``unconverged``), ``detail``, ``anchor``.
    warnings : list of dict
        Decision-changing warnings: ``text``, ``anchor``.
    other_warnings : list of dict
        Count of further warnings per section: ``text``, ``anchor``.
    """

    points: list = field(default_factory=list)
    frequencies: list = field(default_factory=list)
    model_check: list = field(default_factory=list)
    convergence: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    other_warnings: list = field(default_factory=list)

    @property
    def empty(self) -> bool:
        """True when no run gave anything to show."""
        return not (self.points or self.frequencies or self.model_check or self.convergence or self.warnings)


def _value(doc: dict, label: str, *keys):
    """``doc[k0][k1]...`` as a finite float, or None when missing or null.

    Raises
    ------
    DataError
        The value is there but not a number (the file and key path are named).
    """
    v = doc
    for k in keys:
        if not isinstance(v, dict) or v.get(k) is None:
            return None
        v = v[k]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise DataError(f"{label}: key {'.'.join(keys)!r} is {v!r}, expected a number (an edited or damaged file; "
                        "rerun the command)")
    v = float(v)
    return v if math.isfinite(v) else None


def _strings(doc: dict, label: str, key: str) -> list[str]:
    v = doc.get(key) or []
    if not isinstance(v, list):
        raise DataError(f"{label}: key {key!r} is {v!r}, expected a list of strings")
    return [str(s) for s in v]


def _rpm(x) -> str:
    return "—" if x is None else f"{x:.0f}"


def _small_depth(x_m: float) -> str:
    """A depth margin or difference for people: mm, as every human output writes it (units.mm)."""
    return mm(x_m)


def _p(x) -> str:
    return "—" if x is None else f"{x:.2f}"


def _interval(lo, hi) -> str:
    return hz_range(lo, hi)


def _point(doc: dict, label: str, index: int) -> dict:
    level = _value(doc, label, "level")
    lvl = num(level, 3) if level is not None else "the required level"
    src = doc.get("source") or {}
    clamp = _value(doc, label, "source", "clamping_length_m")
    n_draws = doc.get("n_draws")
    deterministic = bool(doc.get("deterministic")) or n_draws == 1
    method = method_name(str(doc.get("method") or "?")).capitalize()
    source = (f"{method}, one FRF without its uncertainty (deterministic: P(stable) is 0 or 1)" if deterministic else
              f"{method}, {n_draws} {'posterior' if src.get('mode', 'posterior') == 'posterior' else 'measured-FRF'} "
              "draws")
    out = {"index": index, "clamping": num(1e3 * clamp, 4) if clamp else None, "source": source, "none": None,
           "speed": "—", "depth": "—", "facts": []}
    rec = doc.get("recommended")
    if not rec:
        note = doc.get("recommended_note")
        out["none"] = f"No spindle speed reaches P(stable) ≥ {lvl}" + (f": {note}" if note else ".")
        return out
    if not isinstance(rec, dict):
        raise DataError(f"{label}: key 'recommended' is {rec!r}, expected an object or null")
    speed = _value(rec, label + " recommended", "spindle_speed_rpm")
    depth = _value(rec, label + " recommended", "depth_m")
    out["speed"] = _rpm(speed)
    out["depth"] = mm(depth).removesuffix(" mm") if depth is not None else "—"
    speed_m, depth_m = [], []
    if isinstance(rec.get("margin_speed_rpm"), dict):  # a null side: no chatter on that side in the analysed range
        below = _value(rec, label, "margin_speed_rpm", "below")
        above = _value(rec, label, "margin_speed_rpm", "above")
        speed_m.append(f"{_rpm(below) + ' rpm below' if below is not None else 'nothing below'} and "
                       f"{_rpm(above) + ' rpm above' if above is not None else 'nothing above'} to the nearest "
                       "chatter at this depth (in the analysed range)")
    window = rec.get("speed_window_rpm") or [None, None]
    tol = _value(rec, label, "speed_tolerance_rel")
    if tol is not None and isinstance(window, list) and len(window) == 2 and None not in window:
        speed_m.append(f"checked over ±{num(100 * tol, 3)} % ({_rpm(window[0])} – {_rpm(window[1])} rpm)")
    if "margin_depth_m" in rec:
        margin_d = _value(rec, label, "margin_depth_m")
        depth_m.append(f"{_small_depth(margin_d)} below the P(stable) = {lvl} limit" if margin_d is not None
                       else "no limit above it in the analysed range")
    rel = _value(rec, label, "depth_margin_rel")
    if rel is not None:
        depth_m.append(f"checked up to +{num(100 * rel, 3)} %")
    force = _value(rec, label, "cutting_force_tolerance_rel")
    if force:
        depth_m.append(f"cutting force ±{num(100 * force, 3)} %")
    out["facts"] = [(k, "; ".join(v)) for k, v in (("speed margin", speed_m), ("depth margin", depth_m)) if v]
    binding = str(rec.get("binding_limit") or "stability")
    if binding != "stability":
        out["facts"].append(("depth set by", depth_limit_name(binding)))
    p_pt = _value(rec, label, "p_stable")
    p_nb = _value(rec, label, "p_stable_neighbourhood")
    if deterministic:
        confidence = "none: a single FRF without its uncertainty; only the margins protect the point"
        if src.get("mode") == "measured":
            confidence += " (give files with coherence and --averages N, or repeated hits)"
    else:
        confidence = (f"P(stable) ≥ {lvl} over the whole checked neighbourhood (lowest {_p(p_nb)}; "
                      f"{_p(p_pt)} at the point)")
        env = doc.get("robust_envelope")
        conf = _value(env, label, "confidence") if isinstance(env, dict) else None
        if conf is not None:
            confidence += f"; the lobes show the robust envelope at {num(100 * conf, 3)} % confidence"
    out["facts"].append(("confidence", confidence))
    cost, med = doc.get("confidence_cost"), doc.get("median_recommended")
    if not deterministic and isinstance(cost, dict) and isinstance(med, dict):
        d, rel = _value(cost, label, "depth_m"), _value(cost, label, "relative")
        md, ms = _value(med, label, "depth_m"), _value(med, label, "spindle_speed_rpm")
        if d is not None and md is not None:
            out["facts"].append(("cost of the confidence", _small_depth(d)
                                 + (f" ({num(100 * rel, 2)} %)" if rel is not None else "")
                                 + f" of depth against the median point ({mm(md)} at {_rpm(ms)} rpm, "
                                   "P(stable) ≥ 0.5)"))
    return out


def _frequencies(doc: dict, label: str, index: int) -> list[dict]:
    preds = doc.get("predictions") or []
    if not isinstance(preds, list):
        raise DataError(f"{label}: key 'predictions' is not a list")
    has_dominant = any(isinstance(p, dict) and "dominant" in p for p in preds)
    rows = []
    for i, p in enumerate(preds):
        if not isinstance(p, dict):
            raise DataError(f"{label}: key 'predictions[{i}]' is {p!r}, expected an object")
        if (p.get("dominant") is not True) if has_dominant else (p.get("mode") != 1):
            continue
        where = f"{label} predictions[{i}]"
        length = _value(p, where, "clamping_length")
        q05, q50, q95 = (_value(p, where, k) for k in ("q05_hz", "q50_hz", "q95_hz"))
        pq05, pq95 = _value(p, where, "predictive_peak_q05_hz"), _value(p, where, "predictive_peak_q95_hz")
        measured = _value(p, where, "measured_hz")
        rows.append({"index": index, "length": num(1e3 * length, 4) if length is not None else "—",
                     "direction": str(p.get("direction", "")), "tool": str(p.get("tool", "")),
                     "median": "—" if q50 is None else hz(q50, q05, q95, unit=False).split(" ")[0],
                     "interval": _interval(q05, q95),
                     "predictive": _interval(pq05, pq95),
                     "measured": "—" if measured is None else f"{measured:.1f}",
                     "held_out": measured is not None and p.get("fitted") is False})
    return rows


def _model_check(doc: dict, label: str, index: int) -> dict:
    named = doc.get("named_effect")
    also = _strings(doc, label, "also_named")
    final = doc.get("final_model")
    if doc.get("adequate") is True:
        s = "adequate: the model explains the measurements, nothing was added"
    elif named:
        effects = " and ".join(f"“{effect_name(e)}”" for e in [str(named), *also])
        s = f"the model misses {effects}; the amended setup adds {'them' if also else 'it'}"
    else:
        s = ("the model disagrees with the measurements and no known effect explains it; a statistical "
             "discrepancy term carries the remainder (wider intervals)")
    if final and final not in ("baseline", named, "statistical_discrepancy"):
        s += f" (final model: {effect_name(final)})"
    usable = doc.get("usable_for_prediction")
    if usable is False:
        s += "; NOT usable for prediction"
    elif usable is True and doc.get("adequate") is not True:
        s += "; usable for prediction"
    return {"index": index, "sentence": s[0].upper() + s[1:] + "."}


def _pile_up(warnings: Iterable[str]) -> list[str]:
    """The parameter names of the pile-up warnings among ``warnings`` (text before the first colon)."""
    out = []
    for w in warnings:
        if "prior range from its" in w or "of the growth bound" in w or "within 5 % of g = 0" in w \
                or "piles up" in w:
            out.append(w.split(":")[0].strip())
    return out


def _is_convergence(warning: str) -> bool:
    """A sampler-convergence warning of summary.json (``not converged: ...``, ``name: R-hat = ...``, ``ESS``)."""
    return warning.startswith("not converged") or "R-hat" in warning or " ESS " in warning


def _names(names: list[str]) -> str:
    """``a is`` / ``a and b are`` / ``a, b and c are``."""
    text = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    return text + (" is" if len(names) == 1 else " are")


def build_answer(documents: Iterable[tuple[str, str, dict]]) -> Answer:
    """The summary block from the commands' documents.

    Parameters
    ----------
    documents : iterable of (kind, label, document)
        ``kind`` is one of ``identify``, ``predict``, ``lobes``, ``discrepancy`` (others are ignored);
        ``label`` names the file in error messages; ``document`` is its parsed JSON.  Documents of one kind
        are numbered in order (1, 2, ...) as their sections in ``report.html``.

    Returns
    -------
    Answer

    Raises
    ------
    DataError
        A value the block shows is not a number (file and key named).
    """
    a = Answer()
    counts: dict[str, int] = {}
    predict_status = []
    for kind, label, doc in documents:
        counts[kind] = i = counts.get(kind, 0) + 1
        if kind == "lobes":
            a.points.append(_point(doc, label, i))
            if doc.get("warnings"):
                n = len(_strings(doc, label, "warnings"))
                a.other_warnings.append({"text": f"{n} warning{'s' if n > 1 else ''} of the lobes run",
                                         "anchor": f"lobes-{i}"})
        elif kind == "predict":
            a.frequencies += _frequencies(doc, label, i)
            predict_status.append((i, doc.get("posterior_status") or {}))
        elif kind == "discrepancy":
            a.model_check.append(_model_check(doc, label, i))
            if doc.get("usable_for_prediction") is False:
                why = "; ".join(_strings(doc, label, "usable_for_prediction_reasons"))
                a.warnings.append({"text": "The model check's final model is NOT usable for prediction: its intervals "
                                           "are too narrow for the disagreement; do not choose a speed from them"
                                           + (f" ({why})" if why else "") + ".", "anchor": f"discrepancy-{i}"})
            elif doc.get("gap_grew") is True:
                a.warnings.append({"text": "The model check's systematic mismatch grew in the final model: the added "
                                           "term makes the fit worse.", "anchor": f"discrepancy-{i}"})
            piled = [str(n) for n in doc.get("final_prior_bound_pile_up") or []]
            if piled:
                a.warnings.append({"text": f"Prior pile-up in the model check's final model: {_names(piled)} on "
                                           "a prior bound; predictions depending on it hold only if the bound is "
                                           "right.", "anchor": f"discrepancy-{i}"})
        elif kind == "identify":
            ws = _strings(doc, label, "warnings")
            conv = doc.get("converged")
            a.convergence.append({"word": "converged" if conv else "unconverged", "anchor": f"convergence-{i}",
                                  "detail": f"identify run {i}"})
            if conv is not True:
                reason = doc.get("stop_reason")
                a.warnings.append({"text": "The sampler did NOT converge" + (f" ({reason})" if reason else "")
                                           + ": every interval and P(stable) of this report is unreliable.",
                                   "anchor": f"convergence-{i}"})
            piled = _pile_up(ws)
            if piled:
                a.warnings.append({"text": f"Prior pile-up: {_names(piled)} limited by the prior bound, not by the "
                                           "data; widen the prior or check the data.", "anchor": f"convergence-{i}"})
            # an unconverged chain's R-hat/ESS warnings are said by the warning above
            rest = len(ws) - len(piled) - (sum(map(_is_convergence, ws)) if conv is not True else 0)
            if rest > 0:
                a.other_warnings.append({"text": f"{rest} further warning{'s' if rest > 1 else ''} of the "
                                                 "identification", "anchor": f"convergence-{i}"})
    if not counts.get("identify"):  # the posterior status the predict runs recorded
        for i, st in predict_status:
            if "converged" not in st:
                continue
            a.convergence.append({"word": "converged" if st["converged"] else "unconverged",
                                  "anchor": f"predictions-{i}", "detail": f"posterior of predict run {i}"})
            if st["converged"] is not True:
                a.warnings.append({"text": "The posterior the predictions use did NOT converge: every interval of "
                                           "this report is unreliable.", "anchor": f"predictions-{i}"})
            piled = _pile_up(str(w) for w in st.get("warnings") or [])
            if piled:
                a.warnings.append({"text": f"Prior pile-up: {_names(piled)} limited by the prior bound, not by the "
                                           "data.", "anchor": f"predictions-{i}"})
    for w in a.warnings:  # the documents quote parameter and effect identifiers; people read their names
        w["text"] = in_words(w["text"])
    return a


# -- rendering ----------------------------------------------------------------------------------------------


def answer_css() -> str:
    """The summary block's style sheet (``templates/answer.css``), for the page's ``<head>``."""
    return template_environment().get_template("answer.css").render()


def answer_html(answer: Answer, href: str = "") -> str:
    """The summary block as an HTML fragment (``<section id="answer">``).

    Parameters
    ----------
    answer : Answer
    href : str
        Prefix of the links to the details (``""`` inside ``report.html``, ``"report.html"`` from a page
        beside it).
    """
    return template_environment().get_template("answer.html.j2").render(answer=answer, href=href)


def answer_markdown(answer: Answer, href: str = "report.html") -> str:
    """The summary block as Markdown (the head of ``summary.md``); links point into ``href``."""
    lines = ["# The answer", ""]
    for p in answer.points:
        where = f" at {p['clamping']} mm clamping" if p["clamping"] else ""
        lines.append(f"## Recommended operating point{where}")
        lines.append("")
        if p["none"]:
            lines += [f"**{p['none']}**", ""]
        else:
            lines += [f"**{p['speed']} rpm, axial depth {p['depth']} mm**", ""]
            lines += [f"- {k}: {v}" for k, v in p["facts"]]
        lines += [f"- from: {p['source']}", ""]
    if answer.frequencies:
        lines += ["## Tool-point natural frequency (dominant mode)", "",
                  "| clamping (mm) | dir | median (Hz) | model 90 % interval (Hz) | new hammer test, 90 % (Hz) "
                  "| measured (Hz) |", "|---|---|---|---|---|---|"]
        for r in answer.frequencies:
            lines.append(f"| {r['length']} | {r['direction']} | {r['median']} | {r['interval']} | {r['predictive']} "
                         f"| {r['measured']}{' (held out)' if r['held_out'] else ''} |")
        lines.append("")
    for m in answer.model_check:
        lines += [f"**Model check:** {m['sentence']} ([details]({href}#discrepancy-{m['index']}))", ""]
    for c in answer.convergence:
        lines += [f"**Convergence:** {c['word']} ([details]({href}#{c['anchor']}))", ""]
    if answer.warnings:
        lines += ["## Warnings that change the decision", ""]
        lines += [f"- **{w['text']}** ([details]({href}#{w['anchor']}))" for w in answer.warnings]
        lines.append("")
    for w in answer.other_warnings:
        lines += [f"Also: {w['text']} ([details]({href}#{w['anchor']}))", ""]
    # names and reasons are user strings: no raw HTML reaches a Markdown renderer
    return "\n".join(lines).rstrip().replace("<", "&lt;").replace(">", "&gt;") + "\n"
