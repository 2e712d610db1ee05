"""The model check: find what the model is missing, name it, add it, show the gap shrink.

:func:`discrepancy` fits the setup's model, looks for systematic disagreement with the measurements, ranks the
candidate effects (the registered model terms not yet in the setup's ``[model]``), refits them and names the one
the tempered evidence supports; when the model is inadequate and nothing is named, a statistical discrepancy
term widens the intervals instead.  It returns a :class:`ModelCheck`, which ``bayes-rcsa discrepancy`` saves.
The method is :mod:`bayes_rcsa.discrepancy` (docs/discrepancy.md)::

    from bayes_rcsa.workflows.model_check import check_model
    check = check_model("setup.toml", lengths=[0.025, 0.040])
    check.named_effect, check.gap_before, check.gap_after
    check.save("check")                     # discrepancy.json, summary.md, plots, setup.amended.toml
"""

from __future__ import annotations

import copy
import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, ClassVar, Sequence

from ..discrepancy.files import FILES
from ..errors import SetupError
from ..messages import merge_warnings, warning_log
from ..units import num, percent
from ..vocabulary import effect_name, humanise
from .result import Result, saving

if TYPE_CHECKING:  # pragma: no cover
    from ..discrepancy.workflow import DiscrepancyResult
    from ..io.setup import Setup

__all__ = ["check_model", "ModelCheck", "Candidate"]

#: Prefix of the progress lines (the command line's ``--verbose`` prints the same).
PROGRESS_PREFIX = "bayes-rcsa discrepancy: "


@dataclass(frozen=True)
class Candidate:
    """One candidate effect of the model check.

    Attributes
    ----------
    effect : str
        The model term's name, as the setup's ``[model] terms`` lists it.
    name : str
        The printed name (``"tip mass"``).
    description : str
        What the effect is, in a machinist's words.
    score : float
        Score statistic of the term at the baseline fit (orders the refits).
    criterion : float or None
        Laplace log evidence of the tempered posterior minus the baseline's; named above ln 100.  None when
        the candidate was screened but not refitted.
    explained_gap : float or None
        Fraction of the baseline's systematic gap at the fitted measurements that the refitted candidate
        removes (1: all of it; negative: it grew).  None when not refitted or the baseline's gap is at the
        noise floor.
    parameters : dict
        ``{parameter name: {"q05", "q50", "q95"}}`` of the term's parameters (SI units) when refitted.
    """

    effect: str
    name: str
    description: str
    score: float
    criterion: float | None
    explained_gap: float | None
    parameters: dict


def _nan(obj):
    """``obj`` with JSON ``null`` numbers back as NaN (the plots of a loaded check compare numbers)."""
    if obj is None:
        return math.nan
    if isinstance(obj, dict):
        return {k: _nan(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_nan(v) for v in obj]
    return obj


@dataclass
class ModelCheck(Result):
    """What the model check found (the document discrepancy.json and what it was computed from).

    Attributes
    ----------
    report : dict
        The document discrepancy.json (:func:`bayes_rcsa.discrepancy.document.build_report`); every number
        below is read from it.
    summary_md : str
        The text of summary.md.
    setup : Setup or None
        The setup checked (None when loaded without one).
    path : Path or None
        The folder the check was saved to or loaded from (None while only in memory).
    warnings : tuple of str
        Every warning issued while the check ran and the check's own (as in discrepancy.json).
    computation : DiscrepancyResult or None
        The fits, evaluations and decisions (:class:`bayes_rcsa.discrepancy.workflow.DiscrepancyResult`);
        None when loaded from a folder.
    amended_setup : dict or None
        A loaded check's setup.amended.toml document (file names relative to ``path``); a computed check
        makes it from ``setup`` when saved.
    """

    title: ClassVar[str] = "Model check"
    files: ClassVar[tuple[str, ...]] = FILES

    report: dict
    summary_md: str = ""
    setup: "Setup | None" = None
    path: Path | None = None
    warnings: tuple[str, ...] = ()
    computation: "DiscrepancyResult | None" = field(default=None, repr=False, compare=False)
    amended_setup: dict | None = field(default=None, repr=False)
    saved_files: tuple[Path, ...] = field(default=(), repr=False, compare=False)
    _draws: dict | None = field(default=None, init=False, repr=False, compare=False)

    # -- the numbers ------------------------------------------------------------------------------------------
    @property
    def adequate(self) -> bool:
        """Whether the setup's model explains the measurements it was fitted to (nothing named was needed)."""
        return bool(self.report["adequate"])

    @property
    def named_effect(self) -> str | None:
        """The missing effect named (a model term's name), or None."""
        return self.report["named_effect"]

    @property
    def also_named(self) -> tuple[str, ...]:
        """A second effect named with the first (second round), if any."""
        return tuple(self.report["also_named"])

    @property
    def confounded_with(self) -> tuple[str, ...]:
        """Effects that explain the data as well as the named one (the data cannot tell them apart)."""
        return tuple(self.report["confounded_with"])

    @property
    def runner_up(self) -> str | None:
        return self.report["runner_up"]

    @property
    def candidates(self) -> tuple[Candidate, ...]:
        """Every candidate, refitted ones first by criterion, then the screened-only ones by score."""
        base = self.report.get("gap_fitted_before")
        floor = self.report.get("gap_before_at_noise_floor")
        out = []
        for c in self.report["candidates"]:
            sys_gap = c.get("systematic_gap_fitted_lines")
            explained = (1.0 - sys_gap / base if c["criterion"] is not None and sys_gap is not None and base
                         and not floor else None)
            out.append(Candidate(c["effect"], effect_name(c["effect"]), c["description"], c["score"],
                                 c["criterion"], explained, dict(c["parameters"])))
        return tuple(out)

    @property
    def gap_before(self) -> float:
        """Systematic relative FRF mismatch of the setup's model (measurement noise excluded), fraction."""
        return self.report["gap_before"]

    @property
    def gap_after(self) -> float:
        """The same for the final model, fraction."""
        return self.report["gap_after"]

    @property
    def gap_grew(self) -> bool:
        """Whether the final model's systematic mismatch is larger than the setup's model's."""
        return bool(self.report["gap_grew"])

    @property
    def usable_for_prediction(self) -> bool:
        return bool(self.report["usable_for_prediction"])

    @property
    def usable_for_prediction_reasons(self) -> tuple[str, ...]:
        return tuple(self.report["usable_for_prediction_reasons"])

    @property
    def final_model(self) -> str:
        """``"baseline"`` (the setup's model), the named term(s) (``"a+b"``) or ``"statistical_discrepancy"``."""
        return self.report["final_model"]

    @property
    def final_terms(self) -> tuple[str, ...]:
        """The model terms the final model adds to the setup's."""
        return tuple(self.report["final_terms"])

    @property
    def seed(self) -> int:
        return self.report["seed"]

    @property
    def posterior_draws(self) -> dict | None:
        """``{parameter: (400,) array}`` of the final model's physical parameters (SI units), drawn from its
        Laplace approximation (the workflow's posterior); None for a loaded check (no fit is stored)."""
        if self.computation is None:
            return None
        if self._draws is None:
            import numpy as np

            from ..discrepancy.fit import laplace_draws

            fit = self.computation.final
            pm = fit.problem.parameters
            vals = pm.values(laplace_draws(fit, np.random.default_rng(self.seed), 400))
            self._draws = {n: np.asarray(vals[n], dtype=float) for n in pm.physical_names}
        return self._draws

    @property
    def inference_data(self):
        """:attr:`posterior_draws` as an ``arviz.InferenceData`` (one chain), or None for a loaded check."""
        draws = self.posterior_draws
        if draws is None:
            return None
        import arviz

        return arviz.from_dict(posterior={n: v[None, :] for n, v in draws.items()},
                               attrs={"method": "laplace", "final_model": self.final_model})

    def to_dict(self) -> dict:
        """The document discrepancy.json (plain JSON values: NaN as None)."""
        from ..io.jsonable import to_jsonable

        return to_jsonable(self.report)

    # -- words ------------------------------------------------------------------------------------------------
    def _parameter_labels(self) -> dict:
        """``{parameter name: printed label}`` of the named terms (empty when neither fit nor setup is known)."""
        if self.computation is not None:
            pm = self.computation.final.problem.parameters
            return {n: pm[n].label or humanise(n) for n in pm.names if pm[n].term}
        if self.setup is not None:
            from ..params.terms import get_term

            model = self.setup.model()
            return {p.name: p.label or humanise(p.name) for t in (self.named_effect, *self.also_named) if t
                    for p in get_term(t)().parameters(model)}
        return {}

    def _gap_text(self, key: str) -> str:
        if self.report.get(f"{key}_at_noise_floor"):
            return f"at the noise floor (below {percent(self.report['gap_resolution'])})"
        return percent(self.report[key])

    def headline(self) -> list[tuple[str, str]]:
        rows = [("Model explains the measurements", "yes" if self.adequate else "no")]
        named = self.named_effect
        if named:
            rows.append(("Missing effect", " + ".join(effect_name(t) for t in (named, *self.also_named))))
            if self.confounded_with:
                rows.append(("Explains the data as well", ", ".join(map(effect_name, self.confounded_with))))
            decided = self.report.get("held_out_decided")
            if decided:
                rows.append(("Chosen over", f"{effect_name(decided['instead_of'])}, which fits the measured lengths "
                                            "about as well but carries worse to the lengths not fitted"))
            labels = self._parameter_labels()
            for c in self.report["candidates"]:
                if c["effect"] == named:
                    for n, q in c["parameters"].items():
                        if n in labels:
                            rows.append((labels[n], f"{num(q['q50'])} (90 % interval {num(q['q05'])} to "
                                                    f"{num(q['q95'])})"))
        elif not self.adequate:
            rows.append(("Missing effect", "none of the known effects; a statistical discrepancy widens the "
                                           "intervals"))
        else:
            rows.append(("Missing effect", "none"))
        rows += [("Systematic mismatch before", self._gap_text("gap_before")),
                 ("Systematic mismatch after", self._gap_text("gap_after"))]
        if self.gap_grew:
            rows.append(("Mismatch grew", "yes: the added term makes the fit worse"))
        rows.append(("Usable for prediction", "yes" if self.usable_for_prediction else "no"))
        return rows

    def summary_line(self) -> str:
        """The line ``bayes-rcsa discrepancy`` prints (naming the files once the check is saved)."""
        from ..discrepancy.render import summary_line

        return summary_line(self.report, self.path)

    def summary_data(self) -> dict:
        r = self.report
        return {"adequate": r["adequate"], "named_effect": r["named_effect"], "also_named": r["also_named"],
                "confounded_with": r["confounded_with"], "gap_before": r["gap_before"], "gap_after": r["gap_after"],
                "gap_grew": r["gap_grew"], "usable_for_prediction": r["usable_for_prediction"]}

    # -- pictures ---------------------------------------------------------------------------------------------
    def figures(self) -> dict:
        """``{name: Figure}``: FRF and residuals before/after (computed checks only), mode frequency errors and
        contact stiffness before/after."""
        from ..discrepancy.plots import plot_figures

        if self.computation is not None:
            return plot_figures(self.computation.evaluation, self.computation.final_label)
        r = self.report
        ev = {k: {"measurements": _nan(r[f"measurements_{k}"]), "stiffness": _nan(r[f"stiffness_{k}"])}
              for k in ("before", "after")}
        return plot_figures(ev, r["final_model"])

    # -- files ------------------------------------------------------------------------------------------------
    def _amended_document(self, folder: Path) -> dict | None:
        from ..discrepancy.files import amended_setup_document, relocate_document

        if not self.named_effect:
            return None
        if self.setup is not None:
            return amended_setup_document(self.setup, folder, [self.named_effect, *self.also_named])
        if self.amended_setup is not None and self.path is not None:
            return relocate_document(copy.deepcopy(self.amended_setup), Path(self.path).resolve(), folder)
        raise SetupError(f"{self.title}: the setup is not known, so setup.amended.toml cannot be written; load the "
                         "check with its setup")

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write the files of ``bayes-rcsa discrepancy`` into ``folder``; returns the path of discrepancy.json.

        ``setup.amended.toml`` (when an effect is named), ``discrepancy.json``, ``summary.md`` and, with
        ``plots``, the PNG plots (a loaded check has no FRFs: only ``frequency_errors.png`` and
        ``stiffness_before_after.png``).
        """
        from ..discrepancy.files import write_files

        with saving(folder, force, earlier_outputs=self.files) as out:
            amended = self._amended_document(Path(out).resolve())
            names = write_files(out, self.report, amended, self.figures() if plots else None,
                                summary=self.summary_md)
        self.path = Path(folder)
        self.saved_files = tuple(Path(folder).resolve() / n for n in names)
        return Path(folder) / "discrepancy.json"

    @classmethod
    def load(cls, folder, setup=None) -> "ModelCheck":
        """Read a folder written by :meth:`save` or ``bayes-rcsa discrepancy``.

        Parameters
        ----------
        folder : path-like
        setup : Setup, path of its TOML or None; only needed for the printed labels of the named effect's
            parameters in :meth:`headline`
        """
        from ..errors import DataError
        from ..io.tables import load_document

        folder = Path(folder)
        try:
            report = json.loads((folder / "discrepancy.json").read_text(encoding="utf-8"))
            summary = (folder / "summary.md").read_text(encoding="utf-8")
        except FileNotFoundError as exc:
            raise DataError(f"{folder}: no model check here ({Path(exc.filename).name} is missing); expected the "
                            "folder written by bayes-rcsa discrepancy") from None
        amended = folder / "setup.amended.toml"
        if setup is not None and not hasattr(setup, "model"):
            from ..io.setup import load_setup

            setup = load_setup(setup)
        return cls(report, summary, setup=setup, path=folder, warnings=tuple(report.get("warnings", ())),
                   amended_setup=load_document(amended) if amended.exists() else None)


def _library_law_shape(library, setup, seed: int) -> tuple:
    """The law-shape prior of a tool library for ``setup`` (docs/discrepancy.md, "A tool library's law shape").

    Parameters
    ----------
    library : path of population.nc, a Population, or None
    setup : Setup (its ``[holder] type`` and the tool's shank diameter choose the population predictive)
    seed : int, seed of the predictive draws

    Returns
    -------
    (LawShapePrior or None, reason the library gives no prior or None, warnings)

    Raises
    ------
    DataError
        A missing or unreadable population file (read by :func:`bayes_rcsa.library.outputs.read_population`).
    SetupError
        A setup without a holder type, or one the library does not know; several tools; an implausible diameter.
    """
    if library is None:
        return None, None, []
    import numpy as np

    from ..discrepancy.law_shape import LawShapePrior
    from ..library.predictive import law_shape_prior
    from ..library.stage1 import holder_type_of, shank_diameter

    if isinstance(library, (str, Path)):
        from ..library.outputs import read_population

        library = read_population(library)
    where = f"--library: {getattr(setup, 'path', 'setup')}"
    htype = library.check_type(holder_type_of(setup), where)
    # its own stream: the workflow's draws (seeded by the same seed) stay those of a run without a library
    rng = np.random.default_rng([int(seed), 43])
    prior, info, warns = law_shape_prior(library, htype, shank_diameter(setup), rng)
    if prior is None:
        return None, info["reason"], []
    return LawShapePrior.from_library(prior, info), None, [f"--library: {w}" for w in warns]


def check_model(setup, *, lengths: Sequence[float] | None = None, candidates: Sequence[str] | None = None,
                seed: int = 0, n_refit: int | None = None, leave_one_out: bool = True, library=None,
                progress: bool | Callable[[str], None] = False) -> ModelCheck:
    """Check the setup's model against its measurements: detect, name the missing effect, add it.

    Parameters
    ----------
    setup : Setup or path-like
        The setup (TOML path or loaded :class:`bayes_rcsa.io.setup.Setup` with its measurements).
    lengths : sequence of float or None
        m; clamping lengths to fit (default: every measured one); the others are held out and predicted.
    candidates : sequence of str or None
        Candidate effects (model term names); default every registered physical term not in the setup's
        ``[model]`` that applies to it.
    seed : int
        Seed of every random draw (Laplace draws, noise realisations).
    n_refit : int or None
        Refit only the ``n_refit`` best candidates of the score test (default: every candidate).
    leave_one_out : bool
        The leave-one-length-out transfer check with three or more fitted lengths.
    library : path of population.nc (``bayes-rcsa library``), a Population, or None
        A tool library whose population gives the unexplained remainder's law shape between the fitted lengths
        its prior (for the setup's holder type and shank diameter; docs/discrepancy.md, "A tool library's law
        shape").  A library that does not pool the law's shape leaves the physics envelope, with a warning.
    progress : bool or callable(str)
        ``True`` prints one line per step on stderr (as ``--verbose``); a callable receives the lines.

    Returns
    -------
    ModelCheck

    Raises
    ------
    SetupError
        An unknown or duplicate candidate, one already in the setup's ``[model]``, no candidate left; with
        ``library``, a setup whose holder type the library does not know (or without one).
    DataError
        Too few fitted lines for the model comparison; a missing or unreadable population file.
    """
    from ..discrepancy.render import summary_markdown
    from ..discrepancy.workflow import DiscrepancyOptions, run_discrepancy

    if candidates is not None:
        candidates = tuple(candidates)
        if not candidates:
            raise SetupError("--candidates: expected at least one effect name")
    if progress is True:
        say = lambda line: print(PROGRESS_PREFIX + line, file=sys.stderr)  # noqa: E731
    else:
        say = progress or None
    with warning_log() as log:
        if not hasattr(setup, "model"):
            from ..io.setup import load_setup

            setup = load_setup(setup)
        law_shape, not_used, lib_warnings = _library_law_shape(library, setup, seed)
        options = DiscrepancyOptions(lengths=tuple(float(x) for x in lengths) if lengths is not None else None,
                                     candidates=candidates, seed=int(seed), n_refit=n_refit,
                                     leave_one_out=leave_one_out, law_shape=law_shape)
        res = run_discrepancy(setup, options, progress=say)
    report = dict(res.report)
    entry = report.get("law_shape_prior")
    if not_used and entry is not None and entry["source"] == "envelope":
        report["law_shape_prior"] = dict(entry, library_not_used=not_used)
        lib_warnings = lib_warnings + [f"--library: {not_used}; the law's shape between the fitted lengths keeps "
                                       "the physics envelope"]
    elif entry is None:
        lib_warnings = []  # nothing used the library's law shape: its notes (e.g. diameter range) do not apply
    warnings = tuple(merge_warnings(log, list(res.report["warnings"]) + lib_warnings))
    report["warnings"] = list(warnings)
    return ModelCheck(report, summary_markdown(report), setup=setup, warnings=warnings, computation=res)
