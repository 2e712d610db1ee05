"""A tool library's contact population (hierarchical model, two stages): :func:`build_library` -> :class:`Population`.

The job of ``bayes-rcsa library``: stage 1 identifies every setup of a
manifest on its own (one task per setup, local processes or a Dask cluster,
finished setups reused), stage 2 fits the population per holder type from the
stored draws, each setup's importance ESS and a leave-one-out outlier check.
See docs/library.md.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, ClassVar

from ..errors import SetupError
from ..messages import current_warnings, merge_warnings, warning_log
from ..units import quantity
from ..vocabulary import parameter_name
from .batch_run import CommandLine, check_run_folder, executor_for, progress_printer
from .result import Result, saving

__all__ = ["build_library", "Population"]


@dataclass(eq=False)
class Population(Result):
    """The fitted contact population of a tool library.

    Attributes
    ----------
    population : bayes_rcsa.library.population.Population
        Per holder type the draws of the law (log10 stiffness at the reference length, diameter slope, spread);
        what ``identify(library=...)`` uses as the prior.
    setups : list of dict, per setup its own and pooled estimates, ESS, outlier flag (library.json ``setups``)
    document : dict, library.json
    folder : Path or None, the library folder (setups/<name>/identify, population.nc, laws.json, laws.csv,
        library.json, shrinkage.png)
    ran, reused : list of str, stage-1 setups computed in this run and taken over from an earlier one
    seed : int, stage 2's seed
    warnings : tuple of str
    fit : LibraryFit or None, the fit in memory (what :meth:`save` writes from)
    """

    title: ClassVar[str] = "Tool library population"
    files: ClassVar[tuple[str, ...]] = ("population.nc", "laws.json", "laws.csv", "library.json", "shrinkage.png")

    population: Any
    setups: list
    document: dict
    folder: Path | None = None
    ran: list = field(default_factory=list)
    reused: list = field(default_factory=list)
    seed: int = 0
    warnings: tuple[str, ...] = ()
    fit: Any = field(default=None, repr=False)

    @property
    def holder_types(self) -> list[str]:
        return list(self.population.holder_types)

    @property
    def outliers(self) -> list[str]:
        return [r["name"] for r in self.setups if r.get("outlier")]

    def to_dict(self) -> dict:
        return self.document

    def headline(self) -> list[tuple[str, str]]:
        rows = [("combinations", str(len(self.setups))), ("holder types", ", ".join(self.holder_types)),
                ("outliers", ", ".join(self.outliers) or "no outlier")]
        for law in self.document.get("laws", []):
            if law.get("parameter") in ("k_xf", "k_thetaM"):
                rows.append((f"{law['holder_type']}: {parameter_name(law['parameter'])} at 10 mm shank, 90 % interval",
                             quantity(law["median_at_10mm"], law["unit"], law["median_at_10mm_q05"],
                                      law["median_at_10mm_q95"])))
        return rows

    def summary_line(self) -> str:
        where = None if self.folder is None else Path(self.folder) / "population.nc"
        return (f"{len(self.setups)} combination(s) in {len(self.holder_types)} holder type(s) "
                f"({', '.join(self.holder_types)}); outliers: {', '.join(self.outliers) or 'no outlier'}; "
                f"population in {where}")

    def summary_data(self) -> dict:
        return {"holder_types": self.holder_types, "outliers": self.outliers, "ran": self.ran,
                "reused": self.reused}

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write population.nc, laws.json, laws.csv, library.json and shrinkage.png into ``folder``; returns
        population.nc.  (The stage-1 folders are written by :func:`build_library` while it runs.)"""
        from ..library.workflow import OUTPUT_FILES, write_library

        if self.fit is None:
            raise SetupError(f"{self.folder}: a loaded library is saved by copying its folder (stage 2's chain is "
                             "not stored)")
        folder = Path(folder)
        with saving(folder, force, OUTPUT_FILES):
            return write_library(folder, self.fit, plots=plots, attrs={"seed": self.seed})["population"]

    @classmethod
    def load(cls, folder) -> "Population":
        """Read population.nc and library.json of a library folder."""
        from ..errors import DataError
        from ..library.outputs import read_population

        folder = Path(folder)
        pop = read_population(folder / "population.nc")
        try:
            doc = json.loads((folder / "library.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise DataError(f"{folder / 'library.json'}: cannot read ({exc})") from None
        return cls(population=pop, setups=list(doc.get("setups", [])), document=doc, folder=folder,
                   warnings=tuple(doc.get("warnings", [])))

    def figures(self) -> dict:
        """``shrinkage``: each setup's own against its pooled estimate, per coordinate, vs shank diameter."""
        from ..library.outputs import shrinkage_figure

        return {"shrinkage": shrinkage_figure(self.population.names, self.setups)}


def build_library(manifest, out, *, workers: int | None = None, scheduler: str | None = None, force: bool = False,
                  seed: int = 0, max_steps: int | None = None, outliers: bool = True, tail_correct: bool = False,
                  plots: bool = True, progress=None,
                  runner: Callable[[list[str]], int] | None = None) -> Population:
    """Fit the contact-law population of the tool library of ``manifest`` into ``out``.

    Parameters
    ----------
    manifest : path of the manifest TOML (the ``batch`` format; every setup with a ``[holder] type``)
    out : path of the library folder (an earlier library run's folder is resumed)
    workers : int or None, local worker processes of stage 1 (None: the number of CPU cores)
    scheduler : str or None, a Dask scheduler address: run stage 1 on that cluster
    force : bool, recompute every stage-1 setup
    seed : int, seed of stage 2
    max_steps : int or None, stage 2 stops unconverged (with a warning) after this many steps
    outliers : bool, run the leave-one-out outlier check
    tail_correct : bool, check every stage-1 posterior's interval ends against importance sampling and pool
        importance draws where the chain missed a tail
    plots : bool, write shrinkage.png
    progress : bool or callable ``(k, n, row)``: True prints one line per stage-1 setup on stderr
    runner : callable ``argv -> exit status`` or None (the ``bayes-rcsa`` entry point)

    Returns
    -------
    Population
    """
    with warning_log():
        import numpy as np

        from ..batch import load_manifest
        from ..io.atomic import atomic_write_text, directory_lock, new_output_directory
        from ..library.stage1 import check_setups, collect, run_stage1
        from ..library.stage2 import Stage2Settings
        from ..library.workflow import fit_library, write_library

        manifest = Path(manifest)
        jobs = load_manifest(manifest)
        try:
            check_setups(jobs)  # everything a setup can be refused for, before stage 1 runs
        except SetupError as exc:
            raise SetupError(f"{manifest}: {exc}") from None
        out = check_run_folder(out, "library_run.json", "library", force)
        client, executor = executor_for(scheduler)
        try:
            with directory_lock(out), new_output_directory(out):
                atomic_write_text(out / "library_run.json", json.dumps({"manifest": str(manifest.resolve()),
                                                                        "setups": [j.name for j in jobs]}, indent=1))
                result = run_stage1(jobs, out, runner or CommandLine(), executor=executor,
                                    workers=workers or os.cpu_count() or 1, force=force,
                                    progress=progress_printer(progress, "library", "stage 1 ", converged=False))
                stage1 = collect(jobs, out, result.rows, tail_correct=tail_correct,
                                 rng=np.random.default_rng([seed, 5]))
                settings = {} if max_steps is None else {"settings": Stage2Settings(max_steps=max_steps)}
                fit = fit_library(stage1, np.random.default_rng(seed), outliers=outliers, stage1_dir=out, **settings)
                fit.warnings[:0] = current_warnings()
                write_library(out, fit, plots=plots, attrs={"seed": seed})
        finally:
            if client is not None:
                client.close()
        doc = json.loads((out / "library.json").read_text(encoding="utf-8"))
        return Population(population=fit.population, setups=fit.setups, document=doc, folder=out, ran=result.ran,
                          reused=result.reused, seed=seed, warnings=tuple(merge_warnings(fit.warnings)), fit=fit)
