"""Which test next: a hammer test (expected reduction of a target's uncertainty) or a test cut (``bayes-rcsa design``).

:func:`design` has three modes:

- with a posterior and a ``target``: rank candidate hammer tests by the expected 90 % width of the target after
  each one (:func:`bayes_rcsa.design.workflow.run_design`);
- without a posterior: which two clamping lengths minimise the expected transfer uncertainty (no data yet;
  :func:`~bayes_rcsa.design.workflow.run_planning`);
- ``next_cut=True``: which test cut next (:func:`bayes_rcsa.cuts.next_cut.run_next_cut`).

It returns a :class:`Design` that writes design.json and design.png.  See docs/design.md.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

from ..errors import SetupError
from ..messages import merge_warnings, warning_log
from ..units import length_mm, mm, num, percent, rpm, width
from .result import Result, saving
from ._posterior_input import is_path, posterior_parts, setup_of

__all__ = ["design_test", "Design"]


@dataclass
class Design(Result):
    """The ranking of candidate tests, best first, and the recommendation.

    Attributes
    ----------
    document : dict
        The design.json document (``mode``: "next_cut", "prior" for the no-data plan, else the posterior
        design), with ``"plot": "design.png"`` as the command writes it.
    warnings : tuple of str
    folder : Path or None, where the files were written or read (None until saved)
    result : DesignResult, PlanningResult or NextCutResult in memory (None after :meth:`load`)
    """

    title: ClassVar[str] = "Test design"
    files: ClassVar[tuple[str, ...]] = ("design.json", "design.png")

    document: dict
    warnings: tuple[str, ...] = ()
    folder: Path | None = None
    result: object = field(default=None, repr=False, compare=False)

    @property
    def next_cut(self) -> bool:
        """True for the ranking of test cuts (``--next-cut``)."""
        return self.document.get("mode") == "next_cut"

    @property
    def best(self):
        """The proposed test: a candidate label (hammer), a dict of speed/depth (next cut) or None."""
        best = self.document.get("best")
        return best if self.next_cut or best is None else best["test"]

    @property
    def verdict(self) -> str:
        """Hammer tests: whether another test is worth it (the no-data plan names the pair to measure)."""
        return self.document.get("verdict", f"measure {self.document['best']['test']} (no-data plan)")

    @property
    def verdict_text(self) -> str:
        """:attr:`verdict` for people: the widths in the unit policy's units (mm, Hz, ×10ⁿ N/m)."""
        from ..design import WORTH_IT_FRACTION

        d = self.document
        b, unit = d.get("best"), d.get("unit", "")
        if d.get("mode") != "posterior" or not isinstance(b, dict) or d.get("current_width") is None:
            return self.verdict
        current = width(d["current_width"], unit)
        if d.get("worth_it"):
            return (f"measure {_test_words(b)}: expected to shrink the 90 % width of {d['target']} from {current} to "
                    f"{width(b['expected_width'], unit)}")
        return (f"more tests are not worth it: the best candidate ({_test_words(b)}) is expected to shrink the 90 % width "
                f"of {d['target']} by {width(d.get('expected_gain'), unit)} ({percent(d.get('relative_gain'))}), "
                f"less than {percent(WORTH_IT_FRACTION)} of the current {current}")

    def to_dict(self) -> dict:
        return json.loads(json.dumps(self.document))

    def headline(self) -> list[tuple[str, str]]:
        d = self.document
        if self.next_cut:
            b = d.get("best")
            if b is None:
                return [("next cut", "none proposed")]
            return [("next cut: spindle speed", rpm(b["speed_rpm"])),
                    ("next cut: axial depth", mm(b["depth_m"])),
                    ("P(chatter) of the cut", f"{b['p_chatter']:.2f}"),
                    ("expected gain", f"{num(b['gain'], 3)} of {num(d['current'], 3)}")]
        rows = [("recommendation", self.verdict_text)]
        unit = d.get("unit", "")
        if d.get("current_width") is not None:
            rows.append(("current 90 % width", width(d["current_width"], unit)))
        best = d.get("best") or {}
        if best.get("expected_width") is not None:
            rows.append(("expected 90 % width after the best test", width(best["expected_width"], unit)))
        return rows

    def summary_line(self) -> str:
        if not self.next_cut:
            return f"{self.verdict_text}; results in {self.folder}"
        b = self.document.get("best")
        return ("no cut proposed" if b is None else
                f"next cut {rpm(b['speed_rpm'])}, {mm(b['depth_m'])} (P(chatter) {b['p_chatter']:.2f}, expected "
                f"gain {num(b['gain'], 3)} of {num(self.document['current'], 3)})") + f"; results in {self.folder}"

    def summary_data(self) -> dict:
        if self.next_cut:
            return {"best": self.document.get("best"), "current": self.document["current"]}
        return {"best": self.best, "worth_it": self.document.get("worth_it"), "verdict": self.verdict}

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write design.json and (``plots``) design.png; returns the path of design.json."""
        with saving(folder, force) as out:
            if self.next_cut:
                from ..errors import OutputError
                from ..cuts.next_cut import write_next_cut_outputs

                if self.result is None:
                    raise OutputError("this Design was read from its files (Design.load): the next-cut map is not "
                                      "held in memory; compute it again with bayes_rcsa.design to write it")
                write_next_cut_outputs(self.result, out, plots=plots)
            else:
                from ..design.outputs import write_design_outputs

                write_design_outputs(_Document(self.document), out, plots=plots)
        if not plots:
            self.document.pop("plot", None)  # the file names no plot
        self.folder = Path(folder)
        return self.folder / "design.json"

    @classmethod
    def load(cls, folder) -> "Design":
        from ._documents import read_document

        folder = Path(folder)
        document = read_document(folder, "design.json", "design")
        return cls(document, tuple(_warnings_of(document)), folder)

    def figures(self) -> dict:
        if not self.next_cut:
            from ..design.outputs import design_figure

            return {"design": design_figure(self.document)}
        if self.result is None:
            return {}
        from ..cuts.next_cut import next_cut_figure

        return {"design": next_cut_figure(self.result)}


class _Document:
    """A design.json document in the shape :func:`~bayes_rcsa.design.outputs.write_design_outputs` writes."""

    def __init__(self, document: dict):
        self._document = document

    def as_dict(self) -> dict:
        return {k: v for k, v in json.loads(json.dumps(self._document)).items() if k != "plot"}


def _warnings_of(document: dict) -> list[str]:
    """The lines of design.json that the command prints as warnings."""
    if document.get("mode") == "next_cut":
        return list(document.get("warnings", []))
    return [n for n in document.get("notes", []) if "collapsed" in n or n.startswith("warning:")]


def design_test(setup, posterior=None, *, target=None, candidates=None, draws: int = 1500, truths: int = 120,
           method: str = "auto", seed: int = 0, noise_scale: float | None = None, kt: float | None = None,
           kr: float | None = None, flutes: int | None = None, radial_immersion: float | None = None,
           milling: str = "down", next_cut: bool = False, speeds_rpm=None, depths_m=None,
           clamping_length: float | None = None, cuts=None, next_cut_target="map", risk_budget: float = 1.0,
           kt_tolerance: float = 0.0, kr_tolerance: float = 0.0, feed: str = "x", tool: str | None = None,
           particles: int = 4) -> Design:
    """Rank candidate hammer tests (or, with ``next_cut``, test cuts) by the expected uncertainty after each.

    Parameters
    ----------
    setup : path of the setup TOML, or a loaded Setup (hammer modes)
    posterior : path of posterior.nc, a ``Posterior`` saved to a file, or None for the no-data plan
    target : str (``frequency@L``, ``stiffness@L``, ``lobes@L:START:STOP[:COUNT]``; L in m, speeds in rpm) or a
        parsed :class:`~bayes_rcsa.design.targets.Target`; required with a posterior
    candidates : str (``0.030,0.035,tool:NAME@0.030,dir:y@0.030``) or parsed candidates; the no-data plan takes
        clamping lengths in m (a sequence) or None (7 lengths over the feasible range)
    draws : int, posterior draws re-weighted
    truths : int, simulated measurements per candidate
    method : "auto", "importance" or "laplace"
    seed : int
    noise_scale : float or None, no-data plan: relative noise of the future tests (default 0.02)
    kt, kr : float or None, Pa, cutting-force coefficients (a lobes target; the next cut's coefficient prior)
    flutes : int or None; radial_immersion : float in (0, 1] or None; milling : "down" or "up"
    next_cut : bool, rank test cuts instead of hammer tests
    speeds_rpm, depths_m : (n,) rpm and (m,) m, the candidate cuts' grid (every pair is a candidate)
    clamping_length : float, m, clamping length of the next cut
    cuts : path of the cuts made so far (the ``update`` CSV format) or None
    next_cut_target : str or parsed target, ``map``, ``depth@SPEED`` or ``mrr@P``
    risk_budget : float in (0, 1], largest P(chatter) of a proposed cut
    kt_tolerance, kr_tolerance : float, relative spreads of the next cut's coefficient prior
    feed : "x" or "y"; tool : str or None; particles : int, coefficient draws per posterior draw

    Returns
    -------
    Design
    """
    from ..io.jsonable import dumps_strict

    with warning_log() as log:
        if next_cut:
            result = _next_cut(setup, posterior, target, candidates, kt, kr, kt_tolerance, kr_tolerance, flutes,
                               radial_immersion, milling, feed, speeds_rpm, depths_m, clamping_length, cuts,
                               next_cut_target, risk_budget, draws, particles, seed, tool)
            document = {"mode": "next_cut", **result.as_dict()}
        else:
            result = _hammer(setup, posterior, target, candidates, draws, truths, method, seed, noise_scale, kt, kr,
                             flutes, radial_immersion, milling)
            document = result.as_dict()
        document = json.loads(dumps_strict({**document, "plot": "design.png"}))
        return Design(document, tuple(merge_warnings(log, _warnings_of(document))), None, result)


def _posterior_path(posterior):
    parts = posterior_parts(posterior)
    if parts.path is None:
        raise SetupError("design reads the posterior from its file: save the Posterior first (Posterior.save)")
    if not Path(parts.path).is_file():
        raise SetupError(f"--posterior {parts.path}: no such file (posterior.nc written by 'bayes-rcsa identify')")
    return parts.path


def _hammer(setup, posterior, target, candidates, draws, truths, method, seed, noise_scale, kt, kr, flutes,
            radial_immersion, milling):
    from ..design.targets import parse_candidates, parse_target
    from ..design.workflow import run_design, run_planning
    from ..posterior.growth_prior import feasible_growth_law

    loaded, name = setup_of(setup)
    if posterior is None:
        if target is not None:
            raise SetupError("--target needs --posterior; without data the design plans two clamping lengths for the "
                             "transfer uncertainty over the whole range")
        lengths = None if candidates is None else [float(v) for v in candidates]
        noise = 0.02 if noise_scale is None else float(noise_scale)
        if not (math.isfinite(noise) and noise > 0):
            raise SetupError(f"--noise-scale {str(noise_scale)!r}: expected a finite number > 0")
        return run_planning(loaded, lengths, truths, seed, noise)
    path = _posterior_path(posterior)
    if target is None or candidates is None:
        raise SetupError("--posterior needs --target and --candidates")
    if noise_scale is not None:
        raise SetupError("--noise-scale is for the no-data mode; with --posterior the fit's noise level is used")
    target = parse_target(target) if isinstance(target, str) else target
    feasible = feasible_growth_law(loaded)
    if feasible is None:
        raise SetupError(f"{name}: [contact] clamping_range is needed to check the candidates")
    feasible.check_lengths([target.clamping_length], "--target clamping length")
    if isinstance(candidates, str):
        candidates = parse_candidates(candidates, loaded, feasible)
    cutting = None
    if target.kind == "lobes":
        from ..stability import CuttingConditions

        missing = [o for o, v in (("--kt", kt), ("--kr", kr), ("--flutes", flutes),
                                  ("--immersion", radial_immersion)) if v is None]
        if missing:
            raise SetupError(f"--target {target.text!r}: a lobes target needs {', '.join(missing)}")
        cutting = CuttingConditions(kt=kt, kr=kr, flutes=flutes, radial_immersion=radial_immersion, milling=milling)
    return run_design(loaded, path, target, candidates, draws, truths, seed, method, cutting)


def _next_cut(setup, posterior, target, candidates, kt, kr, kt_tolerance, kr_tolerance, flutes, radial_immersion,
              milling, feed, speeds_rpm, depths_m, clamping_length, cuts, next_cut_target, risk_budget, draws,
              particles, seed, tool):
    from ..cuts import CoefficientPrior
    from ..cuts.next_cut import parse_next_cut_target, run_next_cut
    from ..stability import CuttingConditions

    missing = [o for o, v in (("--posterior", posterior), ("--speeds", speeds_rpm), ("--depths", depths_m),
                              ("--clamping-length", clamping_length), ("--kt", kt), ("--kr", kr),
                              ("--flutes", flutes), ("--immersion", radial_immersion)) if v is None]
    if missing:
        raise SetupError(f"--next-cut needs {', '.join(missing)}")
    if target is not None or candidates is not None:
        raise SetupError("--next-cut ranks cuts: --target and --candidates are for hammer tests (use --next-cut-target)")
    path = _posterior_path(posterior)
    if not (0 < risk_budget <= 1):
        raise SetupError(f"--risk-budget {risk_budget:g}: expected a probability in (0, 1]")
    cutting = CuttingConditions(kt=kt, kr=kr, flutes=flutes, milling=milling, feed=feed,
                                radial_immersion=radial_immersion)
    if isinstance(next_cut_target, str):
        next_cut_target = parse_next_cut_target(next_cut_target)
    setup_path = setup if is_path(setup) else setup.path
    return run_next_cut(setup_path, path, cutting, float(clamping_length),
                        CoefficientPrior.from_tolerances(kt, kt_tolerance, kr, kr_tolerance), speeds_rpm, depths_m,
                        next_cut_target, risk_budget, cuts, draws, particles, seed, tool=tool)


def _test_words(best: dict) -> str:
    """A candidate hammer test in words: ``x at 30 mm`` (its tool named only when the setup names its tools)."""
    if best.get("clamping_length") is None or not best.get("direction"):
        return str(best.get("test"))
    tool = best.get("tool")
    return (f"{best['direction']} at {length_mm(best['clamping_length'])}"
            + ("" if tool in (None, "", "tool") else f" with tool “{tool}”"))
