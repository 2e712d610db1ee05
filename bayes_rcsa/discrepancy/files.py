"""The files of the discrepancy workflow: setup.amended.toml and the writing of every file.

``bayes-rcsa discrepancy`` (and :meth:`bayes_rcsa.workflows.model_check.ModelCheck.save`) write into one
folder: ``setup.amended.toml`` when an effect is named, ``discrepancy.json`` (:mod:`.document`), ``summary.md``
(:mod:`.render`) and the PNG plots (:mod:`.plots`).  :func:`write_files` writes them into a folder the caller
has made safe to write (locked, or a temporary one); :func:`write_discrepancy` does it atomically on its own.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import SetupError
from .render import summary_markdown

__all__ = ["amended_setup_document", "relocate_document", "amended_setup_text", "write_files", "write_discrepancy",
           "AMENDED_HEADER", "FILES"]

#: The first line of setup.amended.toml.
AMENDED_HEADER = "# The setup with the effect named by `bayes-rcsa discrepancy` added to [model].\n"
#: Every file the workflow can write, in the order it writes them (the plots only with ``plots``, the amended
#: setup only when an effect is named).
FILES = ("setup.amended.toml", "discrepancy.json", "summary.md", "frf_before_after.png", "residuals_before_after.png",
         "frequency_errors.png", "stiffness_before_after.png")


def relocate_document(doc: dict, here, out_dir) -> dict:
    """``doc`` (a setup document read from folder ``here``) with its file names relative to ``out_dir``."""
    here, out_dir = Path(here), Path(out_dir)

    def rel(name: str) -> str:
        return os.path.relpath(os.path.abspath(here / name), out_dir).replace(os.sep, "/")

    if isinstance(doc.get("spindle"), dict):
        doc["spindle"] = {k: rel(v) if isinstance(v, str) else v for k, v in doc["spindle"].items()}
    for m in doc.get("measurement", []) or []:
        if isinstance(m, dict) and isinstance(m.get("file"), str):
            m["file"] = rel(m["file"])
    return doc


def amended_setup_document(setup, out_dir: Path, term) -> dict:
    """The user's setup document with ``term`` (a name or a list of names) added to ``[model] terms`` and file
    names relative to ``out_dir``."""
    from ..io.tables import load_document

    doc = relocate_document(load_document(setup.path), Path(setup.path).parent, out_dir)
    model = dict(doc.get("model", {}) or {})
    terms = list(model.get("terms", []) or [])
    new = [term] if isinstance(term, str) else list(term)
    for t in new:
        if t in terms:
            raise SetupError(f"{setup.path}: [model] terms already contains {t!r}")
    model["terms"] = terms + new
    doc["model"] = model
    return doc


def amended_setup_text(doc: dict) -> str:
    """The text of setup.amended.toml for the document ``doc``."""
    from ..io.toml_writer import dump_toml

    return AMENDED_HEADER + dump_toml(doc)


def write_files(folder: Path, report: dict, amended: dict | None = None, figures: dict | None = None,
                summary: str | None = None) -> list[str]:
    """Write the workflow's files into ``folder`` (which exists and may be written); returns their names.

    Parameters
    ----------
    folder : Path
    report : dict, the document discrepancy.json
    amended : dict or None, the setup.amended.toml document (:func:`amended_setup_document`), written when given
    figures : dict or None, ``{name: Figure}`` (:func:`.plots.plot_figures`), each written as ``name.png``
    summary : str or None, the text of summary.md (default: :func:`.render.summary_markdown` of ``report``)
    """
    from ..io.atomic import atomic_write_text
    from ..io.figures import save_png
    from ..io.jsonable import dumps_strict

    folder = Path(folder)
    names = []
    if amended is not None:
        atomic_write_text(folder / "setup.amended.toml", amended_setup_text(amended))
        names.append("setup.amended.toml")
    # each file whole or not at all (a full disk mid-write leaves no half file; the saving block removes the rest)
    atomic_write_text(folder / "discrepancy.json", dumps_strict(report, indent=2) + "\n")
    atomic_write_text(folder / "summary.md", summary_markdown(report) if summary is None else summary)
    names += ["discrepancy.json", "summary.md"]
    for name, fig in (figures or {}).items():
        save_png(fig, folder / f"{name}.png")
        names.append(f"{name}.png")
    return names


def write_discrepancy(result, out_dir, plots: bool = True, overwrite: bool = False) -> list[Path]:
    """Write discrepancy.json, summary.md, plots and (when an effect is named) setup.amended.toml, atomically.

    Everything goes to a temporary sibling directory that is renamed onto ``out_dir`` at the end,
    so a failure leaves nothing half-written.

    Parameters
    ----------
    result : :class:`~.workflow.DiscrepancyResult`
    out_dir : path-like
    plots : bool, write the PNG plots
    overwrite : bool, replace a non-empty ``out_dir``
    """
    import shutil

    from ..io.atomic import begin_directory
    from .plots import plot_figures

    final_dir, tmp = begin_directory(out_dir, overwrite=overwrite)
    try:
        amended = None
        if result.decision["named"]:
            amended = amended_setup_document(result.setup, final_dir,
                                             [result.decision["named"], *result.report.get("also_named", [])])
        figures = plot_figures(result.evaluation, result.final_label) if plots else None
        names = write_files(tmp, result.report, amended, figures)
        if final_dir.exists():
            shutil.rmtree(final_dir)
        os.replace(tmp, final_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return [final_dir / n for n in names]
