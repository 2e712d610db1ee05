"""Identify the tool-holder contact from tool-point FRFs: :func:`identify` -> :class:`Posterior`.

The job of ``bayes-rcsa identify``: the optional tool-library prior
(``library=``, ``no_taps=``), the optional joint fit of cutting-test outcomes
(``cuts=``), the memory check, the sampler (resumable: with ``out=`` the
checkpoint lives in that folder while it samples), the optional tail check,
and the summary with the warnings of the run and the setup's geometry (what
``predict`` and ``lobes`` compare their setup with).

>>> post = bayes_rcsa.identify("setup.toml", lengths=[0.025, 0.040])   # doctest: +SKIP
>>> post.save("identify")                                              # doctest: +SKIP
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Sequence

from ..errors import SetupError
from ..messages import current_warnings, merge_warnings, warn, warning_log
from ..units import hz, length_mm, sci
from ..vocabulary import identification_name, parameter_name
from .result import Result, check_output_directory, saving

__all__ = ["identify", "Posterior", "CutTestOptions", "EARLIER_OUTPUTS", "CHECKPOINT_FILES", "sampler_setting"]

#: Files of an identify run, removed by ``force`` before a new run (other files in the folder are left alone).
EARLIER_OUTPUTS = ("summary.json", "posterior.nc", "chain.h5", "chain.mirror.h5", "trace.png", "corner.png", "frf.png")
#: The checkpoint of a Bayesian run: kept after an interrupt, continued with ``resume=True``.
CHECKPOINT_FILES = ("chain.h5", "chain.mirror.h5")


@dataclass(frozen=True)
class CutTestOptions:
    """Cutting-test outcomes fitted together with the hammer FRFs (``identify --cuts``).

    Attributes
    ----------
    path : path of the cut table (spindle_speed_rpm, depth_m, outcome[, clamping_length_m, radial_immersion,
        feed_direction, tool])
    flutes : int, number of teeth (required)
    kt, kr : float, Pa (required); kt_tolerance : relative prior spread of the cutting-force level (0.3 = ±30 %);
        kr_tolerance : relative prior spread of Kr/Kt
    clamping_length : float or None, m, of cuts without their own; tool : tool of cuts without their own
    radial_immersion : fraction in (0, 1], or entry_angle, exit_angle : rad
    milling : "down" or "up"; feed : "x" or "y"; pitch_angles : rad or None (variable pitch)
    boundary_width : float or (lo, hi) or None, probit width in ln(depth / limit) (None: 0.1)
    label_error : float or None, probability that a cut far from the boundary is reported the other way (None: 0.01)
    """

    path: Any
    flutes: int | None = None
    kt: float | None = None
    kr: float | None = None
    kt_tolerance: float = 0.0
    kr_tolerance: float = 0.0
    clamping_length: float | None = None
    tool: str | None = None
    radial_immersion: float | None = None
    entry_angle: float | None = None
    exit_angle: float | None = None
    milling: str = "down"
    feed: str = "x"
    pitch_angles: Sequence[float] | None = None
    boundary_width: float | tuple[float, float] | None = None
    label_error: float | None = None


def sampler_setting(table: dict, key: str, default, path):
    """A positive integer from a setup's ``[sampler]`` table (``walkers``, ``max_steps``, ``check_every``), or ``default``.

    Raises
    ------
    SetupError
        ``"<setup>: [sampler] KEY = V: expected a positive integer"`` (or above the documented count limit).
    """
    if key not in table:
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise SetupError(f"{path}: [sampler] {key} = {v!r}: expected a positive integer")
    from ..io.limits import check_count

    check_count(key, v, f"{path}: [sampler] {key} =")
    return v


# -- the result --------------------------------------------------------------------------------------------------


@dataclass(eq=False)
class Posterior(Result):
    """The posterior of the tool-holder contact (or the deterministic fit) of :func:`identify`.

    Attributes
    ----------
    summary : dict
        The summary.json document (parameters with 5/50/95 % quantiles, stiffness and natural frequencies per
        clamping length, convergence, warnings, the setup's geometry).
    draws : PosteriorDraws or None
        Physical draws of every parameter (:class:`bayes_rcsa.posterior.draws.PosteriorDraws`); None for the
        deterministic method.
    inference_data : arviz.InferenceData or None
        The content of posterior.nc (None for the deterministic method).
    setup : Setup or None
        The setup it was fitted on (None when loaded without one).
    path : Path or None
        The posterior.nc it was read from or saved to (None while only in memory, and for the deterministic
        method: its folder holds summary.json only).
    warnings : tuple of str
        Every warning of the run (also in summary.json).
    identification : IdentificationResult or None
        The run in memory (chain, problem): what :meth:`save` writes the plots from.
    cut_draws : (K_t, K_r, w) per draw or None
        The cutting coefficients of a joint fit with cutting tests (written into posterior.nc).
    """

    title: ClassVar[str] = "Posterior of the tool-holder contact"
    files: ClassVar[tuple[str, ...]] = ("summary.json", "posterior.nc", "trace.png", "corner.png", "frf.png")

    summary: dict
    draws: Any = None
    inference_data: Any = field(default=None, repr=False)
    setup: Any = None
    path: Path | None = None
    warnings: tuple[str, ...] = ()
    identification: Any = field(default=None, repr=False)
    cut_draws: Any = field(default=None, repr=False)

    # -- numbers -------------------------------------------------------------------------------------------------
    @property
    def method(self) -> str:
        return str(self.summary.get("method"))

    @property
    def converged(self) -> bool:
        return bool(self.summary.get("converged"))

    @property
    def bayesian(self) -> bool:
        return self.method != "deterministic"

    @property
    def zero_taps(self) -> bool:
        from ..library.newsetup import ZERO_TAP_METHOD

        return self.method == ZERO_TAP_METHOD

    def to_dict(self) -> dict:
        return self.summary

    def headline(self) -> list[tuple[str, str]]:
        rows = [("method", self.method_name), ("converged", "yes" if self.converged else "NO")]
        for e in self.summary.get("natural_frequencies", []) or []:
            q = [e.get(k) for k in ("q05_hz", "q50_hz", "q95_hz")]
            if q[1] is None:
                continue
            label = f"natural frequency at {length_mm(e['clamping_length'])} ({e.get('direction', 'x')}), 90 % interval"
            rows.append((label, hz(q[1], q[0], q[2])))
        for e in self.summary.get("stiffness", []) or []:
            for key, unit in (("k_xf", "N/m"), ("k_thetaM", "N m/rad")):
                k = e.get(key) or {}
                if k.get("q50") is not None:
                    rows.append((f"{parameter_name(key)} at {length_mm(e['clamping_length'])}, 90 % interval",
                                 sci(k["q50"], 3, k.get("q05"), k.get("q95"), unit)))
        return rows

    @property
    def method_name(self) -> str:
        """The method in words (``Bayesian fit of the tap tests with the library prior``)."""
        return identification_name(self.method, library=bool(self.summary.get("library")))

    def summary_line(self) -> str:
        where = "memory" if self.path is None and self.folder is None else str(self.folder)
        if self.zero_taps:
            return f"zero taps: population predictive of holder type {self.summary['holder_type']}; results in {where}"
        status = "converged" if self.converged else "NOT converged"
        return f"{self.method_name}: {status}{self._sampler_note()}; results in {where}"

    def _sampler_note(self) -> str:
        """How the draws were made, when importance sampling was asked for (accepted, or why the chain ran)."""
        block = self.summary.get("sampler") or {}
        if block.get("requested", "mcmc") == "mcmc":
            return ""
        if block.get("mode") == "importance":
            return f" (importance sampling: Pareto k = {block['pareto_k']:.2f}, ESS {block['ess']:.0f})"
        return f" (emcee chain; {block.get('fallback_reason')})"

    def summary_data(self) -> dict:
        if self.zero_taps:
            return {"method": self.method, "converged": True}
        return {"method": self.method, "converged": self.converged}

    @property
    def folder(self) -> Path | None:
        """The folder the results were saved to or loaded from."""
        return None if self._folder is None else Path(self._folder)

    _folder: Any = field(default=None, repr=False)

    # -- files ---------------------------------------------------------------------------------------------------
    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write summary.json, posterior.nc (Bayesian methods) and the PNG plots into ``folder``; returns summary.json.

        A run still in memory writes exactly what ``bayes-rcsa identify`` writes; a loaded posterior writes its
        summary.json and posterior.nc again (no plots: the chain is not stored).
        """
        folder = Path(folder)
        with saving(folder, force, EARLIER_OUTPUTS):
            self._write(folder, plots)
        return folder / "summary.json"

    def _write(self, folder: Path, plots: bool) -> None:
        if self.identification is not None:
            _write_identification(self.identification, folder, plots, self.cut_draws, self.summary)
        else:
            from ..inference.results import write_summary
            from ..store import write_posterior
            from ..io.atomic import atomic_write_text

            if self.inference_data is not None:
                write_posterior(self.inference_data, folder / "posterior.nc")
            if self.zero_taps:  # the layout write_zero_tap uses
                atomic_write_text(folder / "summary.json", json.dumps(self.summary, indent=1))
            else:
                write_summary(folder / "summary.json", self.summary)
        self._folder = folder
        bayesian = self.identification.bayesian if self.identification is not None \
            else self.inference_data is not None
        self.path = folder / "posterior.nc" if bayesian else None

    @classmethod
    def load(cls, folder_or_posterior_nc, setup=None) -> "Posterior":
        """Read a folder of ``bayes-rcsa identify`` (or its posterior.nc) back.

        Parameters
        ----------
        folder_or_posterior_nc : path of the folder (summary.json, posterior.nc) or of posterior.nc
        setup : Setup or path, optional
            Kept as :attr:`setup`; its differences from the recorded parameter model become notes of the draws.
        """
        p = Path(folder_or_posterior_nc)
        folder = p if p.is_dir() else p.parent
        nc = folder / "posterior.nc" if p.is_dir() else p
        if setup is not None and not hasattr(setup, "measurements"):
            from ..io.setup import load_setup

            setup = load_setup(setup, load_data=False)
        summary_path = folder / "summary.json"
        summary = {}
        if summary_path.is_file():
            try:
                summary = json.loads(summary_path.read_text(encoding="utf-8"))
            except ValueError as exc:
                from ..errors import DataError

                raise DataError(f"{summary_path}: not valid JSON ({exc})") from None
        idata = draws = None
        if nc.is_file() or summary.get("method", "multi") != "deterministic":
            from ..posterior.draws import posterior_attributes

            idata = _InferenceDataOnFirstUse.snapshot(nc, "--posterior")
            draws = _draws_of(idata, setup)
            if not summary:  # a posterior.nc alone: its attributes say what summary.json would
                attrs = posterior_attributes(idata.array_data)
                summary = {"method": str(attrs.get("method", "multi")),
                           "converged": bool(int(attrs.get("converged", 0)))}
        return cls(summary=summary, draws=draws, inference_data=idata, setup=setup,
                   path=nc if idata is not None else None, warnings=tuple(summary.get("warnings", [])),
                   _folder=folder)

    # -- pictures ------------------------------------------------------------------------------------------------
    def figures(self) -> dict:
        """``trace``, ``corner`` and ``frf`` of a run in memory; ``corner`` (physical values) of a loaded one."""
        import numpy as np

        from ..inference import plots as P

        ir = self.identification
        if ir is not None:
            from ..inference.identify import corner_columns, sampling_labels
            from ..inference.outputs import frf_panels

            labels = sampling_labels(ir.problem.parameters)
            out = {}
            if ir.chain is not None:
                out["trace"] = P.trace_figure(ir.chain.chain, labels, ir.chain.burn)
            if ir.bayesian:
                cols = corner_columns(ir.problem.parameters)
                out["corner"] = P.corner_figure(ir.flat_theta[:, cols], [labels[i] for i in cols])
            out["frf"] = P.frf_figure(frf_panels(ir, np.random.default_rng(ir.seed)))
            return out
        if self.draws is None:
            return {}
        noise = set(self.draws.parameters.noise_names)  # as corner_columns: the noise scales are in the tables
        names = [n for n in self.draws.sampled if n not in noise] or list(self.draws.sampled)
        samples = np.column_stack([self.draws.values[n] for n in names])
        labels = [f"{n} [{self.draws.parameters.unit(n)}]" for n in names]
        return {"corner": P.corner_figure(samples, labels)}

    # -- predictions ---------------------------------------------------------------------------------------------
    def predict(self, lengths, **kw):
        """Tool-point FRF and natural frequencies at ``lengths`` (m): :func:`bayes_rcsa.workflows.prediction.predict`."""
        from .prediction import predict

        return predict(self.setup, self, lengths, **kw)


def _get_inference_data(self):
    held = self.__dict__.get("_inference_data")
    return held.data() if isinstance(held, _InferenceDataOnFirstUse) else held


def _set_inference_data(self, value) -> None:
    self.__dict__["_inference_data"] = value


# ``inference_data`` is decoded by ArviZ when first read (an ``arviz.InferenceData``, which every ArviZ function
# takes); until then the posterior holds the file's bytes or path, and its numbers for the package's own readers
Posterior.inference_data = property(_get_inference_data, _set_inference_data,
                                    doc="The content of posterior.nc as an arviz.InferenceData (decoded on first use).")


def _numbers(posterior):
    """The file content of ``posterior`` for the package's readers: h5py numbers when not yet decoded by ArviZ."""
    held = posterior.__dict__.get("_inference_data")
    return held.array_data if isinstance(held, _InferenceDataOnFirstUse) else held


def _loaded(idata):
    """``idata`` with every group read into memory (the file may be replaced or removed afterwards)."""
    for group in idata.groups():
        getattr(idata, group).load()
    return idata


def _write_identification(ir, folder: Path, plots: bool, cut_draws, summary: dict) -> None:
    """summary.json, posterior.nc and the plots of a run, and the cut coefficients of a joint fit."""
    from ..inference.outputs import write_outputs

    write_outputs(ir, folder, plots=plots)
    if cut_draws is not None:
        from ..cuts.joint import add_coefficients_to_posterior

        add_coefficients_to_posterior(folder / "posterior.nc", *cut_draws,
                                      {"cuts_file": summary["cuts"]["file"], "n_cuts": summary["cuts"]["n_cuts"]})


# -- the workflow ------------------------------------------------------------------------------------------------


def identify(setup, *, lengths: Sequence[float] | None = None, method: str = "multi", seed: int = 0,
             walkers: int | None = None, max_steps: int | None = None, check_every: int | None = None,
             ess_min: float = 400.0, checkpoint_interval: float = 2.0, band: tuple[float, float] | None = None,
             spindle_samples=None, allow_no_resonance: bool = False, tail_check: bool | None = None, library=None,
             no_taps: bool = False, cuts: CutTestOptions | dict | None = None, out=None, resume: bool = False,
             force: bool = False, progress: bool = False, plots: bool = True, sampler: str = "auto") -> Posterior:
    """Identify the tool-holder contact (k_xf, k_thetaM, ...) from the setup's measured tool-point FRFs.

    Parameters
    ----------
    setup : path of the setup TOML or a loaded :class:`bayes_rcsa.io.setup.Setup` (with its data)
    lengths : (n,) m or None, use only the measurements at these clamping lengths
    method : {"multi", "single", "deterministic"}
    seed : int, same seed, same posterior
    walkers, max_steps, check_every : int or None (None: the setup's ``[sampler]`` table, else max(32, 4 x
        parameters), 20000, 250)
    ess_min : float, bulk ESS required for convergence
    checkpoint_interval : float, s between checkpoint writes (with ``out``)
    band : (lo, hi) Hz or None, likelihood band of every measurement (None: the rule around the dominant modes)
    spindle_samples : path of spindle_samples.npz or SpindleSamples, optional (Bayesian methods): the predicted
        natural-frequency intervals mix the posterior draws with these flange-receptance samples
    allow_no_resonance : bool, proceed (with a warning) when a measurement holds no resonance in its band
    tail_check : bool or None, compare every parameter's 90 % interval ends with an importance-sampling estimate
        (Bayesian methods; part of the reported convergence: ``summary["convergence"]``, and a disagreement makes
        ``converged`` false).  None (default): on, except for a joint fit with cutting tests (``cuts``), whose every
        evaluation runs the stability limits of all cuts, so that the check would cost several times the chain;
        ``True`` runs it there too

    library : path of population.nc or a Population (``bayes-rcsa library``), optional (method "multi"): the
        contact prior is the population predictive of the setup's holder type and shank diameter
    no_taps : bool, with ``library``: use no measurement; the posterior is the population predictive
    cuts : CutTestOptions (or its keywords as a dict), optional: cut outcomes sampled with the FRFs
    out : path, optional
        Sample with the checkpoint in this folder and save the results there at the end (locked; a failure
        removes what the run wrote, except the checkpoint after an interrupt).  Without it the run stays in
        memory (:meth:`Posterior.save` writes it later).
    resume : bool, continue the run checkpointed in ``out``
    force : bool, replace an earlier run's files in ``out``
    progress : bool, progress lines on stderr while sampling
    plots : bool, write the PNG plots (with ``out``)
    sampler : {"mcmc", "importance", "auto"}
        "auto" (default) importance-samples the exact posterior around its optimum and keeps the draws when the
        Pareto shape k <= 0.7 and the weights' ESS >= 1000, else runs the emcee chain and notes why (summary.json's
        ``sampler`` block: mode, pareto_k, ess, n_proposals, fallback_reason; docs/identification.md, "Exact
        posteriors by importance sampling"); "importance" the same with the fall-back as a warning; "mcmc" always
        the chain (``walkers``, ``max_steps``, ``check_every``, ``ess_min`` and ``checkpoint_interval`` act only on a
        chain).  ``resume`` continues a chain: refused with "importance", the chain with "auto".  Bayesian methods
        only (ignored by "deterministic").

    Returns
    -------
    Posterior

    Raises
    ------
    SetupError, DataError
        Everything that can be refused without sampling is refused before ``out`` is touched.
    """
    with warning_log():
        return _identify(setup, lengths, method, seed, walkers, max_steps, check_every, ess_min, checkpoint_interval,
                         band, spindle_samples, allow_no_resonance, tail_check, library, no_taps, cuts,
                         None if out is None else Path(out), resume, force, progress, plots, sampler)


def _population(library, method: str, resume: bool, no_taps: bool, lengths, spindle_samples):
    """The population of ``library`` (None without); checks the combinations."""
    if library is None:
        if no_taps:
            raise SetupError("--no-taps needs --library (the population the prediction comes from)")
        return None
    if method != "multi":
        raise SetupError(f"--library: method {method!r}; a library prior is used with method 'multi'")
    if resume:
        raise SetupError("--library cannot be combined with --resume")
    if no_taps and (lengths is not None or spindle_samples is not None):
        raise SetupError("--no-taps uses no measurement: drop --lengths and --spindle-uncertainty")
    if not isinstance(library, (str, Path)):
        return library
    from ..library.outputs import read_population

    return read_population(library)


def _setup(setup, load_data: bool = True):
    if hasattr(setup, "measurements"):
        return setup
    from ..io.setup import load_setup

    return load_setup(setup, load_data=load_data)


def _identify(setup, lengths, method, seed, walkers, max_steps, check_every, ess_min, checkpoint_interval, band,
              spindle_samples, allow_no_resonance, tail_check, library, no_taps, cuts, out, resume, force, progress,
              plots, sampler) -> Posterior:
    import numpy as np

    from ..inference.problem import IdentificationOptions, build_problem_from_setup
    from ..inference.sampler import SamplerSettings

    # Everything that can be checked without sampling is checked before out is touched.
    if ess_min <= 0:
        raise SetupError(f"--ess-min {ess_min!r}: expected a number > 0")
    if checkpoint_interval < 0:
        raise SetupError(f"--checkpoint-interval {checkpoint_interval!r}: expected a number >= 0 (seconds)")
    bayesian = method != "deterministic"
    from ..inference.identify import check_sampler

    check_sampler(sampler, resume)
    if resume and not bayesian:
        raise SetupError("--resume applies to the Bayesian methods only")
    if resume and out is None:
        raise SetupError("--resume continues the run checkpointed in an output folder: give out=DIR")
    if spindle_samples is not None and not bayesian:
        raise SetupError("--spindle-uncertainty applies to the Bayesian methods only")
    lengths = None if lengths is None else tuple(float(v) for v in lengths)
    population = _population(library, method, resume, no_taps, lengths, spindle_samples)
    if no_taps:
        return _zero_taps(_setup(setup, load_data=False), population, seed, out, force, library)
    ckpt = None if out is None else out / "chain.h5"
    if resume and not (ckpt.exists() or ckpt.with_name("chain.mirror.h5").exists()):
        raise SetupError(f"--resume: no checkpoint found at {ckpt}")
    setup = _setup(setup)
    library_kw = {}
    if population is not None:
        import warnings

        from ..errors import DataWarning
        from ..library.newsetup import library_options

        library_kw, lib_warnings = library_options(population, setup, np.random.default_rng(seed))
        for w in lib_warnings:
            warn(w, DataWarning, stacklevel=2)
    options = IdentificationOptions.from_setup(setup.extra, method=method, lengths=lengths, band=band, **library_kw)
    problem = build_problem_from_setup(setup, options)
    _check_resonances(problem, allow_no_resonance)
    cut_term = _cut_term(cuts, problem, setup, method, resume)
    table = dict(setup.extra.get("sampler", {}) or {})
    pick = lambda given, key, default: given if given is not None else sampler_setting(table, key, default, setup.path)  # noqa: E731
    settings = SamplerSettings(n_walkers=pick(walkers, "walkers", None), max_steps=pick(max_steps, "max_steps", 20000),
                               check_every=pick(check_every, "check_every", 250), ess_min=ess_min,
                               checkpoint_interval=checkpoint_interval, progress=progress)
    if bayesian:
        from ..io.limits import check_memory

        n_walkers = settings.walkers(problem.priors.ndim)  # refuses an odd or too small walker count now
        # the chain is kept in memory (twice while it grows) until the run ends
        check_memory(2 * 8.0 * settings.max_steps * n_walkers * (problem.priors.ndim + 1),
                     f"--max-steps {settings.max_steps} x {n_walkers} walkers", "lower --max-steps or --walkers")
    spindle_samples = _spindle_samples(spindle_samples, setup)
    run = dict(problem=problem, setup=setup, seed=seed, settings=settings, resume=resume, sampler=sampler,
               spindle_samples=spindle_samples,
               tail_check=bayesian and (tail_check if tail_check is not None else cut_term is None), cut_term=cut_term,
               population=population, library=library)
    if out is None:
        return _in_memory(_fit(**run, checkpoint=None))
    with _run_folder(out, force, resume, bayesian):
        posterior = _fit(**run, checkpoint=ckpt if bayesian else None)
        posterior._write(out, plots)
    if posterior.path is not None:
        # the draws as predict/lobes read them (h5py, no ArviZ); the InferenceData only when a script asks for it
        held = _InferenceDataOnFirstUse(posterior.path)
        posterior.inference_data = held
        posterior.draws = _draws_of(held, setup)
    else:
        posterior.inference_data = None
    return posterior


def _run_folder(out: Path, force: bool, resume: bool, bayesian: bool):
    """The output folder of a run that checkpoints into it: locked, checked, cleaned on failure."""
    import contextlib

    from ..io.atomic import directory_lock, new_output_directory

    @contextlib.contextmanager
    def block():
        with directory_lock(out):
            check_output_directory(out, force, resume, resumable=bayesian)
            if force and not resume:
                # an earlier run's results must not survive beside the new ones (a deterministic rerun writes no
                # posterior.nc, and predict would read the old one)
                for name in EARLIER_OUTPUTS:
                    (out / name).unlink(missing_ok=True)
            # a failure removes what this run wrote (a checkpoint too: a rerun must not be blocked by it), except
            # the checkpoint after Ctrl-C, which resume continues
            with new_output_directory(out, keep_on_interrupt=CHECKPOINT_FILES):
                yield out

    return block()


class _InferenceDataOnFirstUse:
    """The ``arviz.InferenceData`` of a posterior.nc, decoded on first use and kept.

    identify returned the file read back with ArviZ (importing ArviZ and xarray and decoding every group: seconds
    per run, paid by every command-line run and every batch worker, which never look at it); a script that reads
    ``posterior.inference_data`` (a property calling :meth:`data`) pays once.  The numbers the package
    itself needs (draws, attributes, cut coefficients) come from :attr:`array_data` (h5py, read once).

    Made by identify, the file must still be where identify wrote it; made by :meth:`snapshot` (``Posterior.load``
    and runs kept in memory), the file's bytes are held, so it may be replaced or removed afterwards.
    """

    __slots__ = ("_path", "_idata", "_content", "_arrays")

    def __init__(self, path: Path, content: bytes | None = None):
        self._path = Path(path)
        self._idata = None
        self._content = content
        self._arrays = None

    @classmethod
    def snapshot(cls, path: Path, option: str | None = None) -> "_InferenceDataOnFirstUse":
        """The file as it is now: its numbers read (and checked) at once, its bytes kept for a later decode.

        ``option`` names the file in the message of a missing file, as in :func:`bayes_rcsa.store.read_posterior`.

        Raises
        ------
        DataError, SetupError
            As :func:`bayes_rcsa.store.read_posterior` (missing, unreadable, newer schema).
        """
        from ..posterior.draws import read_posterior

        out = cls(path)
        out._arrays = read_posterior(path, option=option, arrays=True)
        out._content = Path(path).read_bytes()
        return out

    @property
    def array_data(self):
        """The file's numbers and attributes (:class:`bayes_rcsa.store.netcdf.ArrayData`), without ArviZ."""
        if self._arrays is None:
            from ..posterior.draws import read_posterior

            self._arrays = read_posterior(self._path, option=None, arrays=True)
        return self._arrays

    def data(self):
        """The decoded ``arviz.InferenceData`` (decoded on the first call, then kept)."""
        if self._idata is None:
            if self._content is None:
                self._idata = _read_idata(self._path)
            else:
                # ArviZ reads files by name: the kept bytes go through a private temporary copy
                with tempfile.TemporaryDirectory(prefix="bayes_rcsa_posterior_") as tmp:
                    copy = Path(tmp) / "posterior.nc"
                    copy.write_bytes(self._content)
                    self._idata = _read_idata(copy)
                self._content = None
        return self._idata


def _draws_of(idata: _InferenceDataOnFirstUse, setup):
    """The posterior draws of ``idata``'s file, from its numbers (no ArviZ)."""
    from ..posterior.draws import load_posterior

    return load_posterior(idata._path, setup, inference_data=idata.array_data)


def _read_idata(path: Path):
    from ..posterior.draws import read_posterior

    return _loaded(read_posterior(path))


def _in_memory(posterior: Posterior) -> Posterior:
    """A run kept in memory: its draws, and its InferenceData as posterior.nc would hold it."""
    from ..posterior.draws import draws_from_result

    ir = posterior.identification
    if not ir.bayesian:
        return posterior
    posterior.draws = draws_from_result(ir)
    with tempfile.TemporaryDirectory(prefix="bayes_rcsa_identify_") as tmp:
        _write_identification(ir, Path(tmp), False, posterior.cut_draws, posterior.summary)
        posterior.inference_data = _InferenceDataOnFirstUse.snapshot(Path(tmp) / "posterior.nc")
    return posterior


#: Importance draws of the default tail check: as many as the chain's log-posterior evaluations, within these bounds
#: (its cost then stays at most about that of the chain; 1e5 evaluations take ~2 s on the bundled example).
TAIL_CHECK_MIN, TAIL_CHECK_MAX = 20_000, 100_000


def convergence_report(summary: dict) -> dict:
    """The ``convergence`` entry of an identify summary, and its verdict in ``summary["converged"]``.

    Two independent checks: the chain's own rule (tau, R-hat, bulk ESS; :mod:`bayes_rcsa.inference.sampler`) and
    the importance-sampling check of the 5 % and 95 % points (:mod:`bayes_rcsa.inference.tail_check`), which sees
    a tail the chain under-samples while its own diagnostics pass (docs/identification.md, "Sampler moves and the
    tails").  A ``"disagrees"`` verdict makes the run not converged (``summary["converged"]`` set to False); an
    ``"unreliable"`` one (Pareto k > 0.7 or too few effective weights) cannot judge and leaves the chain's verdict.

    Returns
    -------
    dict: ``converged``, ``reason``, ``chain`` ({``converged``, ``reason``}) and ``tail_check`` (its verdict,
    ``pareto_k``, ``ess`` and ``reason``; ``"not run"`` without one)
    """
    chain = {"converged": bool(summary["converged"]), "reason": summary.get("stop_reason", "")}
    tc = summary.get("tail_check")
    if tc is None:
        tail = {"verdict": "not run", "reason": "identify ran with tail_check=False (--no-tail-check)"}
    else:
        tail = {"verdict": tc["verdict"], "reason": tc["reason"], "pareto_k": tc.get("pareto_k"),
                "ess": tc.get("ess"), "n": tc.get("n")}
    reasons = [] if chain["converged"] else [f"chain: {chain['reason']}"]
    if tail["verdict"] == "disagrees":
        reasons.append(f"tail check: {tail['reason']}")
    converged = not reasons
    summary["converged"] = converged
    return {"converged": converged, "reason": "; ".join(reasons) if reasons else (
        "chain converged" + ("; tail check consistent" if tail["verdict"] == "consistent" else
                             f"; tail check {tail['verdict']} (no verdict)")),
        "chain": chain, "tail_check": tail}


def _fit(problem, setup, seed, settings, resume, sampler, spindle_samples, tail_check, cut_term, population, library,
         checkpoint) -> Posterior:
    """Sample (or fit), then the summary's additions: tail check, cut coefficients, warnings, geometry, library."""
    import numpy as np

    from ..inference.identify import identify as run_identification
    from ..inference.tail_check import check_identification
    from ..posterior.setup_match import GEOMETRY_KEY, setup_geometry

    if cut_term is not None:  # a joint fit: the cut outcomes are an extra likelihood term of the problem
        problem = problem.with_extra_terms(cut_term)
    result = run_identification(problem, seed=seed, settings=settings, checkpoint_path=checkpoint, resume=resume,
                                spindle_samples=spindle_samples, sampler=sampler)
    if tail_check and result.chain is not None:  # an accepted importance-sampling posterior is its own check
        # its own stream: the chain's seed stays the chain's; cheap: at most as many evaluations as the chain's
        # (between TAIL_CHECK_MIN and TAIL_CHECK_MAX, ~2 s at the maximum)
        n_check = int(np.clip(result.summary["timing"]["log_posterior_evaluations"], TAIL_CHECK_MIN, TAIL_CHECK_MAX))
        result.summary["tail_check"] = check_identification(result, np.random.default_rng([seed, 7]), n=n_check)
    if problem.method != "deterministic":
        result.summary["convergence"] = convergence_report(result.summary)
    cut_draws = None
    if cut_term is not None:
        from ..cuts.joint_fit import cut_coefficients

        cut_draws, result.summary["cuts"] = cut_coefficients(result.flat_theta, cut_term, seed)
    s = result.summary
    tc = s.get("tail_check")
    # "unreliable" (no verdict) is recorded in summary["convergence"], not warned about: it says nothing of the chain
    if tc is not None and tc["verdict"] == "disagrees":
        s.setdefault("warnings", []).append(f"tail check {tc['verdict']}: {tc['reason']}")
    # the data-plausibility warnings of the run travel with the results too
    s["warnings"] = merge_warnings(current_warnings(), s.get("warnings", []))
    # what predict and lobes compare their setup with (a changed tool length, diameter or modulus)
    s[GEOMETRY_KEY] = setup_geometry(setup)
    if population is not None:  # which population was the prior
        s["library"] = {"population": str(library), "model_version": population.version,
                        "holder_type": setup.holder_type, "pooled_parameters": list(population.names)}
    return Posterior(summary=s, setup=setup, warnings=tuple(s["warnings"]), identification=result,
                     cut_draws=cut_draws)


def _cut_term(cuts, problem, setup, method: str, resume: bool):
    """The :class:`~bayes_rcsa.cuts.joint.CutTerm` of ``cuts`` (None without); checks the combinations first."""
    if cuts is None:
        return None
    if isinstance(cuts, dict):
        cuts = CutTestOptions(**cuts)
    if method == "deterministic":
        raise SetupError("--cuts needs a Bayesian method (multi or single): the outcomes enter the posterior")
    if resume:
        raise SetupError("--cuts cannot be combined with --resume (the checkpoint does not record the cuts)")
    missing = [o for o, v in (("--cut-flutes", cuts.flutes), ("--cut-kt", cuts.kt), ("--cut-kr", cuts.kr)) if v is None]
    if missing:
        raise SetupError(f"--cuts needs {', '.join(missing)}")
    from ..cuts.joint_fit import joint_cut_term

    kw = {k: v for k, v in dataclasses.asdict(cuts).items() if k != "path"}
    for name in ("boundary_width", "label_error"):
        if kw[name] is None:
            del kw[name]
    return joint_cut_term(problem, setup, cuts.path, **kw)


def _check_resonances(problem, allow: bool) -> None:
    """Refuse (or, with ``allow``, warn about) a fitted measurement without a resonance in its band."""
    import warnings

    from ..errors import DataError, DataWarning
    from ..io.checks import resonance_problem

    for _, frf in problem.measurements:
        why = resonance_problem(frf.frequency_hz, frf.values)
        if why is None:
            continue
        if not allow:
            raise DataError(f"{frf.source}: {why}; --allow-no-resonance proceeds anyway")
        warn(f"{frf.source}: {why}; the posterior of the contact mostly restates its prior", DataWarning,
                      stacklevel=2)


def _spindle_samples(spindle_samples, setup):
    """The SpindleSamples of ``spindle_samples`` (a path or loaded), checked against the setup's directions."""
    if spindle_samples is None:
        return None
    source = spindle_samples
    if isinstance(spindle_samples, (str, Path)):
        from ..spindle.uncertainty import load_spindle_samples

        spindle_samples = load_spindle_samples(spindle_samples)
    else:
        source = spindle_samples.source
    missing = sorted({m.direction for m in setup.measurements} - set(spindle_samples.directions))
    if missing:
        raise SetupError(f"--spindle-uncertainty {source}: no samples for direction(s) {missing}; the file has "
                         f"{spindle_samples.directions}")
    return spindle_samples


def _zero_taps(setup, population, seed: int, out: Path | None, force: bool, library) -> Posterior:
    """``no_taps``: posterior.nc of population-predictive draws and its summary (no measurement used)."""
    import warnings

    import numpy as np

    from ..errors import DataWarning
    from ..library.newsetup import write_zero_tap

    def write(folder: Path) -> dict:
        return write_zero_tap(folder, population, setup, np.random.default_rng(seed), warnings=current_warnings())

    if out is not None:
        with saving(out, force, EARLIER_OUTPUTS):
            summary = write(out)
        posterior = Posterior.load(out, setup)
    else:
        with tempfile.TemporaryDirectory(prefix="bayes_rcsa_identify_") as tmp:
            summary = write(Path(tmp))
            posterior = Posterior.load(tmp, setup)
        posterior.path = posterior._folder = None
    for w in summary["warnings"]:
        warn(w, DataWarning, stacklevel=2)
    posterior.setup = setup
    posterior.warnings = tuple(merge_warnings(current_warnings(), summary["warnings"]))
    return posterior
