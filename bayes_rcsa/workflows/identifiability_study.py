"""``identifiability``: which contact parameters do the data pin down, from one clamping length or several?

>>> study = bayes_rcsa.identifiability("setup.toml", max_steps=2000)
>>> study.save("ident")                     # identifiability.json/.md/.html, plots, fits/<name>/posterior.nc
>>> study.posteriors["multi"].predict([0.035])

Every selected measured clamping length is fitted alone (one constant
contact, the literature method) and all of them together (the growth law),
with identical priors; per fit and parameter the study reports the
contraction of the posterior, the verdict, ridges, the Fisher information
and the transfer errors.  The same as ``bayes-rcsa identifiability SETUP
--out DIR`` (this call and :meth:`Identifiability.save`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..errors import DataError, SetupError
from ..messages import warning_log
from .result import Result, saving

__all__ = ["identifiability", "Identifiability"]

#: Printed names of the contact parameters (the headline never shows internal identifiers).
_NAMES = {"k_xf": "translational contact stiffness", "k_thetaM": "rotational contact stiffness",
          "g_xf": "growth of the translational stiffness", "g_thetaM": "growth of the rotational stiffness",
          "c_xf": "translational contact damping", "c_thetaM": "rotational contact damping"}


def _readable(text: str) -> str:
    for key in sorted(_NAMES, key=len, reverse=True):
        text = text.replace(key, _NAMES[key])
    return text


@dataclass
class Identifiability(Result):
    """Single- vs multi-length fits of one setup (what ``bayes-rcsa identifiability`` writes).

    Attributes
    ----------
    document : dict
        identifiability.json without its ``"plots"`` entry: setup, seed, sampler settings, priors,
        verdict rule, thresholds, per fit (``document["fits"]``) the contraction and verdict of every
        parameter, correlations, ridge and Fisher analyses, transfer errors, and the findings.
    seed : int, seed of every fit and of the draw subsets of the analysis and the plots
    plot_numbers : dict or None
        The numbers drawn in corner_overlay.png and forest.png (identifiability.json ``"plots"``); made on
        request from the fits, or read back with :meth:`load` (``None`` for a folder written without plots).
    path : Path or None, the folder it was saved to or loaded from
    warnings : tuple of str (a fit that did not converge included)
    study : bayes_rcsa.posterior.study.Study or None
        The fits in memory; ``None`` when loaded from files (which then can neither be saved again nor drawn).
    setup : Setup or None, the setup the fits were made on
    """

    title: ClassVar[str] = "Identifiability: single- vs multi-length fits"
    files: ClassVar[tuple[str, ...]] = ("identifiability.json", "identifiability.md", "identifiability.html",
                                        "corner_overlay.png", "forest.png", "fits/<name>/summary.json",
                                        "fits/<name>/posterior.nc")

    document: dict
    seed: int = 0
    plot_numbers: dict | None = None
    path: Path | None = None
    warnings: tuple[str, ...] = ()
    study: object = field(default=None, repr=False, compare=False)
    setup: object = field(default=None, repr=False, compare=False)

    # -- numbers ---------------------------------------------------------------------------------------------
    @property
    def fits(self) -> list[dict]:
        """Each fit's entry of identifiability.json (name, method, lengths, parameters, transfer, ...)."""
        return self.document["fits"]

    @property
    def findings(self) -> list[str]:
        return self.document["findings"]

    @property
    def not_converged(self) -> list[str]:
        """Names of the fits whose chains did not converge (their verdicts are not reliable)."""
        return [f["name"] for f in self.fits if not f.get("converged", True)]

    def _plot_numbers(self) -> dict | None:
        if self.plot_numbers is None and self.study is not None:
            from ..posterior.study import study_figures

            self.plot_numbers = {name: numbers for name, (_, numbers) in
                                 study_figures(self.study, np.random.default_rng(self.seed)).items()}
        return self.plot_numbers

    def to_dict(self) -> dict:
        """identifiability.json (as written with plots)."""
        from ..io.jsonable import to_jsonable

        numbers = self._plot_numbers()
        doc = self.document if numbers is None else {**self.document, "plots": numbers}
        return json.loads(json.dumps(to_jsonable(doc), allow_nan=False))

    def headline(self) -> list[tuple[str, str]]:
        from ..posterior.identifiability import fmt_contraction

        rows = []
        for f in self.fits:
            lengths = ", ".join(f"{v * 1e3:g}" for v in f["lengths"])
            rows.append((f"fit {f['name']}", f"{f['method']}-length fit at {lengths} mm"
                         + ("" if f.get("converged", True) else " (NOT converged)")))
            for name, p in f["parameters"].items():
                if name in _NAMES:
                    c = fmt_contraction(p.get("contraction"))
                    rows.append((f"  {_NAMES[name]}", f"{_readable(p['verdict'])} "
                                 f"({c if c.startswith('prior') else f'contraction {c}'})"))
            errors = [v for v in (f.get("transfer_error_pct") or {}).values() if v is not None]
            if errors:  # {length: mean |error| over directions} at the lengths the fit did not see
                rows.append(("  natural frequency error at the other lengths", f"{np.mean(errors):.2g} % (mean)"))
        return rows

    def summary_line(self) -> str:
        bad = self.not_converged
        return f"{len(self.fits)} fit(s){'' if not bad else f', {len(bad)} NOT converged'}; results in {self.path}"

    def summary_data(self) -> dict:
        return {"fits_not_converged": self.not_converged}

    # -- posteriors ------------------------------------------------------------------------------------------
    @property
    def draws(self) -> dict:
        """``{fit name: PosteriorDraws}`` (read from fits/<name>/posterior.nc for a loaded result)."""
        if self.study is not None:
            return {f.spec.name: f.draws for f in self.study.fits}
        from ..posterior.draws import load_posterior

        return {name: load_posterior(path, self.setup) for name, path in self._posterior_files().items()}

    def _posterior_files(self) -> dict:
        if self.path is None:
            return {}
        files = {f["name"]: Path(self.path) / "fits" / f["name"] / "posterior.nc" for f in self.fits}
        return {n: p for n, p in files.items() if p.is_file()}

    @property
    def posteriors(self) -> dict:
        """``{fit name: Posterior}`` of every fit (usable with ``predict`` and ``lobes``).

        Saved fits are read from fits/<name>/posterior.nc; fits only in memory carry their draws and summary.
        """
        from .identification import Posterior

        saved = self._posterior_files()
        if self.study is None:
            return {name: Posterior.load(path, setup=self.setup) for name, path in saved.items()}
        return {f.spec.name: (Posterior.load(saved[f.spec.name], setup=self.setup) if f.spec.name in saved else
                              Posterior(summary=f.result.summary, draws=f.draws, inference_data=None,
                                        setup=self.setup, path=None))
                for f in self.study.fits}

    # -- files -----------------------------------------------------------------------------------------------
    def _in_memory(self, what: str) -> None:
        if self.study is None:
            raise SetupError(f"{what}: this identifiability study was loaded from {self.path}; its fits are not in "
                             "memory (run identifiability again)")

    def save(self, folder, *, force: bool = False, plots: bool = True, posteriors: bool = True) -> Path:
        """Write identifiability.json/.md/.html, the plots and (``posteriors``) fits/<name>/summary.json and
        posterior.nc into ``folder``; returns identifiability.json's path."""
        from ..posterior.study import write_study

        self._in_memory("save")
        with saving(folder, force) as out:
            write_study(self.study, out, plots=plots, posteriors=posteriors, seed=self.seed)
        self.path = Path(folder)
        return self.path / "identifiability.json"

    @classmethod
    def load(cls, folder, setup=None) -> "Identifiability":
        """Read a folder written by :meth:`save` (or by ``bayes-rcsa identifiability``)."""
        folder = Path(folder)
        try:
            doc = json.loads((folder / "identifiability.json").read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise DataError(f"{folder}: no identifiability.json; not written by bayes-rcsa identifiability") from None
        numbers = doc.pop("plots", None)
        bad = [f["name"] for f in doc["fits"] if not f.get("converged", True)]
        return cls(document=doc, seed=doc["seed"], plot_numbers=numbers, path=folder, setup=setup,
                   warnings=tuple(_not_converged(bad)))

    # -- pictures --------------------------------------------------------------------------------------------
    def figures(self) -> dict:
        """``{"corner_overlay": Figure, "forest": Figure}``: the stiffness posteriors of every fit overlaid at
        each length, and the medians with 50 % and 90 % intervals of the stiffnesses and transfer errors."""
        from ..posterior.study import study_figures

        self._in_memory("figures")
        return {Path(name).stem: fig for name, (fig, _) in
                study_figures(self.study, np.random.default_rng(self.seed)).items()}


def _not_converged(names) -> list[str]:
    return [f"fit {n} did not converge: its verdicts are not reliable" for n in names]


def _sampler_setting(setup, key: str, given, default):
    """``given``, else the setup's ``[sampler] key`` (checked against the documented limits), else ``default``."""
    if given is not None:
        return given
    table = dict(setup.extra.get("sampler", {}) or {})
    if key not in table:
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise SetupError(f"{setup.path}: [sampler] {key} = {v!r}: expected a positive integer")
    from ..io.limits import check_count

    check_count(key, v, f"{setup.path}: [sampler] {key} =")
    return v


def identifiability(setup, *, lengths=None, seed: int = 0, max_steps: int | None = None, walkers: int | None = None,
                    check_every: int | None = None, progress: bool = False, sampler: str = "auto") -> Identifiability:
    """Fit every selected measured clamping length alone and all of them together; analyse each posterior.

    Parameters
    ----------
    setup : path of the setup TOML file, or a loaded :class:`bayes_rcsa.io.setup.Setup` (with measurements)
    lengths : sequence of float, m, optional
        Measured clamping lengths to use (default all measured).
    seed : int >= 0, seed of every fit
    max_steps : int, optional; sampler steps per fit (default ``[sampler] max_steps`` or 20000)
    walkers : int, optional; walkers per fit (even; default max(32, 4 x parameters))
    check_every : int, optional; steps between convergence checks (default ``[sampler] check_every`` or 250)
    progress : bool, one line per fit and the sampler's progress on stderr
    sampler : {"auto", "importance", "mcmc"}, how every fit samples its posterior (as :func:`bayes_rcsa.identify`;
        ``max_steps``, ``walkers`` and ``check_every`` act on a chain only)

    Returns
    -------
    Identifiability
    """
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise SetupError(f"--seed {seed}: expected an integer >= 0")
    from ..inference.identify import check_sampler

    check_sampler(sampler, False)
    with warning_log() as log:
        from ..inference.sampler import SamplerSettings
        from ..io.setup import Setup, load_setup
        from ..posterior.study import run_study

        if not isinstance(setup, Setup):
            setup = load_setup(setup)
        if lengths is not None:
            lengths = [float(v) for v in lengths]
        settings = SamplerSettings(n_walkers=_sampler_setting(setup, "walkers", walkers, None),
                                   max_steps=_sampler_setting(setup, "max_steps", max_steps, 20000),
                                   check_every=_sampler_setting(setup, "check_every", check_every, 250),
                                   progress=progress)
        study = run_study(setup, lengths, settings, seed=seed, verbose=progress, sampler=sampler)
        warnings = tuple(log)
    from ..io.jsonable import to_jsonable
    from ..messages import merge_warnings

    document = json.loads(json.dumps(to_jsonable(study.document), allow_nan=False))  # as the file reads back
    bad = [f["name"] for f in document["fits"] if not f.get("converged", True)]
    return Identifiability(document=document, seed=int(seed), study=study, setup=setup,
                           warnings=tuple(merge_warnings(warnings, _not_converged(bad))))
