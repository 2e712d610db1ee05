"""The report's section of a ``bayes-rcsa library`` run: the population per holder type, setups, outliers.

Reads ``library.json`` (:func:`bayes_rcsa.library.workflow.write_library`
writes it) and embeds ``shrinkage.png`` when present: the law table per
holder type (median at 10 mm with its 90 % interval, diameter slope,
spread), stage 2 per type (ESS, autocorrelation, R-hat, bulk ESS), a row per setup (holder
type, diameter, importance ESS, leave-one-out p-value, outlier flag or the
refusal of its pooled estimate) and the warnings.
"""

from __future__ import annotations

from . import figures as F
from ..units import num, sci
from ..vocabulary import in_words, parameter_name

__all__ = ["library_section"]


def _interval(lo, mid, hi, digits: int = 3) -> str:
    return sci(mid, digits, lo, hi)


def library_section(run) -> dict:
    """Template context of one library run (``run.document`` = library.json)."""
    doc = run.document
    laws = [{"type": r["holder_type"], "parameter": parameter_name(r["parameter"]), "unit": r["unit"],
             "median": _interval(r["median_at_10mm_q05"], r["median_at_10mm"], r["median_at_10mm_q95"]),
             "slope": _interval(r["slope_q05"], r["slope_q50"], r["slope_q95"], 2),
             "spread": _interval(r["spread_q05"], r["spread_q50"], r["spread_q95"], 2),
             "coordinate_unit": r["coordinate_unit"]} for r in doc["laws"]]
    setups = []
    for s in doc["setups"]:
        p = s.get("p_value")
        setups.append({"name": s["name"], "type": s["holder_type"], "diameter": num(1e3 * s["diameter_m"], 3),
                       "ess": num(s["ess"], 3), "p": "—" if p is None else num(p, 2),
                       "verdict": "OUTLIER" if s.get("outlier") else ("refused: " + s["refused"] if s.get("refused")
                                                                      else "consistent")})
    # R-hat and bulk ESS are missing ("—") in the library.json of older versions
    stage2 = [{"type": t, "n": v["n_setups"], "ess": num(v["ess"], 3), "tau": num(v["autocorrelation_steps"], 3),
               "rhat": num(v.get("rhat_max"), 4), "ess_bulk": num(v.get("ess_bulk_min"), 3)}
              for t, v in doc["stage2"].items()]
    images = [F.png_data_uri(p) for p in (run.file("shrinkage.png"),) if p]
    return {"path": str(run.path), "laws": laws, "setups": setups, "stage2": stage2, "outliers": doc["outliers"],
            "warnings": [in_words(w) for w in doc["warnings"]], "images": images}
