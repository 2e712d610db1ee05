"""Stage 1: every combination's own posterior under the broad common prior, through :mod:`bayes_rcsa.batch`.

Each setup of the manifest is run by ``identify`` alone (the manifest's
``predict`` and ``lobes`` steps are not needed for the population), one task
per setup on any executor -- the local process pool or a Dask cluster --
and cached per setup exactly as ``batch`` caches it (a finished setup with
the same options and setup file is not recomputed).  :func:`collect` then
reads each ``posterior.nc`` into population coordinates.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..errors import DataError, SetupError
from .population import COORDINATES, SCALES, SHAPE_COORDINATES, covariate, to_coordinates
from .stage2 import SetupDraws

__all__ = ["identify_only", "check_setups", "run_stage1", "collect", "pooled_shape_coordinates", "MIN_SHAPE_LENGTHS",
           "holder_type_of", "shank_diameter", "stage1_prior", "Stage1"]

_LN10 = math.log(10.0)


def holder_type_of(setup) -> str | None:
    """The setup's ``[holder] type``, or ``None`` when absent (or on a version without the key)."""
    value = getattr(setup, "holder_type", None)
    return None if value is None else str(value)


def shank_diameter(setup) -> float:
    """m, diameter of the clamped shank (the tool's last segment); one tool per library setup.

    Raises
    ------
    SetupError
        Several tools in the setup (a combination is one tool in one holder).
    """
    tools = getattr(setup, "tools", {}) or {}
    if len(tools) != 1:
        raise SetupError(f"{setup.path}: {len(tools)} tools {sorted(tools)}; a library combination is one tool in "
                         "one holder")
    tool = next(iter(tools.values()))
    return float(tool.segments[-1].diameter)


def identify_only(jobs) -> tuple:
    """The manifest's jobs with their ``identify`` step only (stage 1 needs no predictions or lobes)."""
    out = []
    for job in jobs:
        cmds = tuple((s, a) for s, a in job.commands if s == "identify")
        out.append(dataclasses.replace(job, commands=cmds))
    return tuple(out)


def _combination(job):
    """The setup of a job (no data), its holder type and shank diameter; refused without a type."""
    from ..io.setup import load_setup

    setup = load_setup(job.setup_file, load_data=False, load_spindle=False)
    htype = holder_type_of(setup)
    if htype is None:
        raise SetupError(f"{job.setup_file}: no [holder] type; every setup of a library needs one (e.g. "
                         'type = "ER32")')
    diameter = shank_diameter(setup)
    covariate(diameter, f"{job.setup_file}: shank diameter")
    return setup, htype, diameter


def check_setups(jobs) -> list[tuple[str, str, float]]:
    """Check every setup of a library before stage 1 runs (cheap: no data loaded).

    Returns
    -------
    list of (name, holder type, shank diameter m)

    Raises
    ------
    SetupError
        Fewer than two setups, a deterministic identification (stage 1 needs
        posterior draws), a setup without ``[holder] type``, with several
        tools or an implausible shank diameter, or clamping ranges and growth
        bounds that differ between setups (the stiffness must refer to one
        reference length; "mixed units?" when they differ by 100x).
    """
    jobs = list(jobs)
    if len(jobs) < 2:
        raise SetupError(f"{len(jobs)} setup(s) in the manifest; a library population needs at least two "
                         "combinations")
    out = []
    ref = None
    for job in jobs:
        argv = dict(job.commands).get("identify", ())
        if "deterministic" in argv:
            raise SetupError(f"setup {job.name}: method 'deterministic' gives no posterior draws; a library's stage 1 "
                             "needs method 'multi'")
        setup, htype, diameter = _combination(job)
        law = (tuple(float(v) for v in setup.feasible_range), float(setup.contact.growth_bound))
        if ref is None:
            ref = (job.name, law)
        elif law != ref[1]:
            (a, b), q = law
            (a0, b0), q0 = ref[1]
            hint = " (mixed units?)" if max(b, b0) > 100 * min(b, b0) else ""
            raise SetupError(f"setup {job.name}: clamping range [{a:g}, {b:g}] m, growth bound {q:g}; setup {ref[0]} "
                             f"has [{a0:g}, {b0:g}] m, {q0:g}{hint}; a library's stiffness refers to one reference "
                             "length: give every setup the same contact.clamping_range and growth_bound")
        out.append((job.name, htype, diameter))
    return out


def run_stage1(jobs, out_dir, run_command: Callable[[list[str]], int], executor=None, workers: int = 1,
               force: bool = False, progress=None):
    """Run (or reuse) every setup's ``identify`` into ``out_dir/setups/<name>/identify``.

    Parameters
    ----------
    jobs : sequence of SetupJob (from :func:`bayes_rcsa.batch.load_manifest`)
    out_dir : path-like
    run_command : ``argv -> exit status`` (:func:`bayes_rcsa.cli.main.main`, passed in by the command line)
    executor : concurrent.futures.Executor or None (local process pool of ``workers``)
    workers, force, progress : as :func:`bayes_rcsa.batch.run_batch`

    Returns
    -------
    BatchResult
    """
    from ..batch import run_batch

    return run_batch(identify_only(jobs), out_dir, run_command, executor=executor, workers=workers, force=force,
                     progress=progress)


def stage1_prior(pm, names: Sequence[str], where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gaussian part (mean, precision) and box of a fit's prior in the population coordinates.

    Flat priors (log-uniform stiffness or damping, uniform growth) have zero
    precision; a log-normal (normal) prior becomes a normal in log10 (linear)
    coordinates.

    Raises
    ------
    SetupError
        A prior kind the population cannot divide out.
    """
    d = len(names)
    mean, prec, box = np.zeros(d), np.zeros((d, d)), np.zeros((d, 2))
    for j, n in enumerate(names):
        p = pm[n].prior
        desc = p.describe()
        kind = desc.get("distribution")
        lo, hi = p.bounds
        if SCALES[n] == "log10":
            if kind == "log-uniform":
                box[j] = (lo, hi)
            elif kind == "log-normal":
                box[j] = (lo / _LN10, hi / _LN10)
                mean[j], prec[j, j] = math.log10(desc["median"]), (_LN10 / desc["sigma"]) ** 2
            else:
                raise SetupError(f"{where}: prior of {n} is {kind}; a library's stage 1 needs a log-uniform or "
                                 "log-normal prior (flat or normal in log10)")
        else:
            if kind == "uniform":
                box[j] = (lo, hi)
            elif kind == "normal":
                box[j] = (lo, hi)
                mean[j], prec[j, j] = desc["mu"], 1.0 / desc["sigma"] ** 2
            else:
                raise SetupError(f"{where}: prior of {n} is {kind}; a library's stage 1 needs a uniform or normal "
                                 "prior of the growth factors")
    return mean, prec, box


@dataclasses.dataclass
class Stage1:
    """The library's stage-1 posteriors in population coordinates.

    Attributes
    ----------
    names : tuple of str, pooled coordinates (sampled in every setup)
    setups : list of SetupDraws
    growth : (l_a, l_b, Q) common growth law
    box : (d, 2) the widest stage-1 prior box over the setups (for the hyperprior and new setups)
    warnings : list of str
    """

    names: tuple
    setups: list
    growth: tuple
    box: np.ndarray
    warnings: list


def _tail_corrected(job, folder: Path, draws, rng: np.random.Generator):
    """A setup's stage-1 draws with a missed tail replaced by importance-sampling draws; (draws, note or None).

    The stage-1 chain's interval ends are compared with an importance-sampling estimate of the same log
    posterior (:func:`bayes_rcsa.inference.tail_check.importance_tail_check`).  Where they disagree and the
    importance estimate is reliable, the draws are replaced by as many importance draws, resampled
    from the check's own importance draws (``resample``): identify's old default moves under-sampled a
    one-sided tail (docs/identification.md), and a population pooled from such draws inherits it.  The log
    posterior is rebuilt from the setup file and the run's summary, and must reproduce the stored one.
    """
    import json

    from ..inference.problem import IdentificationOptions, build_problem_from_setup
    from ..inference.tail_check import importance_tail_check
    from ..io.setup import load_setup
    from ..store import read_posterior

    summary = json.loads((folder / "summary.json").read_text())
    if (summary.get("sampler") or {}).get("mode") == "importance":
        return draws, None  # accepted importance sampling (identify's default): exact draws, no tail to miss
    setup = load_setup(job.setup_file)
    problem = build_problem_from_setup(setup, IdentificationOptions.from_setup(
        setup.extra, method=summary["method"], lengths=None, band=None))
    lp = problem.log_posterior(summary["likelihood"]["tempering"])
    names = problem.priors.names
    missing = [n for n in names if n not in draws.values]
    if missing:
        return draws, f"setup {job.name}: tail correction skipped: the stage-1 draws lack {missing}"
    theta = np.column_stack([np.asarray(problem.priors.priors[n].to_sampling(draws.values[n]), float) for n in names])
    stored = np.asarray(read_posterior(folder / "posterior.nc", option=None, arrays=True).sample_stats["lp"].values,
                        float).ravel()
    if stored.size != theta.shape[0] or not np.allclose(lp(theta), stored, rtol=0.0, atol=1e-6):
        return draws, (f"setup {job.name}: tail correction skipped: the log posterior rebuilt from {job.setup_file} "
                       "differs from the stage-1 run's (setup edited since?)")
    # one importance run serves both the check and the replacement: "disagrees" is only ever returned when the
    # importance estimate is reliable (Pareto k <= 0.7, ESS >= MIN_ESS), the condition for resampling it
    check = importance_tail_check(lp, theta, names, rng, resample=theta.shape[0])
    if check["verdict"] != "disagrees":
        return draws, None if check["verdict"] == "consistent" else f"setup {job.name}: tail check {check['reason']}"
    values = dict(draws.values)
    for j, n in enumerate(names):
        values[n] = np.asarray(problem.priors.priors[n].to_physical(check["draws"][:, j]), float)
    return dataclasses.replace(draws, values=values), (
        f"setup {job.name}: stage-1 draws replaced by importance-sampling draws (Pareto k = "
        f"{check['pareto_k']:.2f}, ESS {check['ess']:.0f}): {check['reason']}")


#: Fewest fitted clamping lengths at which a stage-1 fit identifies the law's bend (two fix only its ends).
MIN_SHAPE_LENGTHS = 3


def pooled_shape_coordinates(fits) -> tuple[tuple, list[str]]:
    """The law-shape coordinates (:data:`~.population.SHAPE_COORDINATES`) the library pools, and why not the others.

    A coordinate is pooled when every stage-1 fit samples it at :data:`MIN_SHAPE_LENGTHS` or more clamping lengths.
    A library that samples it nowhere is the common case and passes silently; one that samples it in some setups,
    or only at two lengths (where the bend is its uniform prior and pooling returns that prior), leaves it out with
    a warning rather than refusing: the contact coordinates are still pooled as before.

    Parameters
    ----------
    fits : sequence of (setup name, PosteriorDraws)

    Returns
    -------
    (names, warnings)
    """
    names, warns = [], []
    for n in SHAPE_COORDINATES:
        having = [name for name, d in fits if n in d.parameters.names]
        if not having:
            continue
        short = [f"{name} ({len(d.fit_lengths)})" for name, d in fits
                 if n in d.parameters.names and len(d.fit_lengths) < MIN_SHAPE_LENGTHS]
        if len(having) < len(fits):
            warns.append(f"{n} is sampled by {len(having)} of {len(fits)} setups; not pooled (give every setup "
                         "[model] terms = [\"law_shape_uncertainty\"] to pool the law's shape)")
        elif short:
            warns.append(f"{n} is not identified at fewer than {MIN_SHAPE_LENGTHS} fitted clamping lengths "
                         f"(setups {', '.join(short)}); not pooled")
        else:
            names.append(n)
    return tuple(names), warns


def collect(jobs, out_dir, rows: Sequence[dict] | None = None, tail_correct: bool = False,
            rng: np.random.Generator | None = None) -> Stage1:
    """Read every finished setup's posterior into population coordinates.

    Parameters
    ----------
    jobs : sequence of SetupJob
    out_dir : path-like, the stage-1 folder (``setups/<name>/identify/posterior.nc``)
    rows : batch rows or None; setups whose row is not ``done`` are left out with a warning
    tail_correct : bool
        Check every setup's stage-1 interval ends against importance sampling of its log posterior and, where
        they disagree and the importance estimate is reliable, pool importance draws instead (see
        :func:`_tail_corrected`; about 10^5 likelihood evaluations per setup).  Every replacement or refusal is
        a warning.
    rng : numpy.random.Generator, required with ``tail_correct``

    Raises
    ------
    SetupError
        A setup without ``[holder] type``, with several tools, an implausible
        shank diameter (mixed units), a growth law or set of sampled contact
        parameters that differs from the others, or fewer than two usable
        setups.  The law's bend (``law_shape_bend``) is not refused when it
        differs: it is then left out with a warning (:func:`pooled_shape_coordinates`).
    """
    from ..posterior.draws import load_posterior

    status = {r["name"]: r for r in rows or ()}
    warns: list[str] = []
    entries = []
    for job in jobs:
        row = status.get(job.name)
        if row is not None and row.get("status") != "done":
            warns.append(f"setup {job.name}: stage 1 {row.get('status')} ({row.get('error')}); left out of the "
                         "population")
            continue
        setup, htype, diameter = _combination(job)
        path = Path(out_dir) / "setups" / job.name / "identify" / "posterior.nc"
        try:
            draws = load_posterior(path)
        except DataError as exc:
            warns.append(f"setup {job.name}: {exc}; left out of the population")
            continue
        if row is not None and row.get("converged") is False:
            warns.append(f"setup {job.name}: its stage-1 posterior did not converge; pooled as it is")
        if tail_correct:
            if rng is None:
                raise ValueError("collect(tail_correct=True) needs rng")
            draws, note = _tail_corrected(job, path.parent, draws, rng)
            if note:
                warns.append(note)
        entries.append((job.name, htype, diameter, draws))
    if len(entries) < 2:
        raise SetupError(f"a library needs at least two usable combinations to estimate a population; got "
                         f"{len(entries)}")
    names_of = {e[0]: tuple(n for n in COORDINATES if n in e[3].parameters.names and n not in SHAPE_COORDINATES)
                for e in entries}
    ref_name, ref = entries[0][0], names_of[entries[0][0]]
    g0 = entries[0][3].parameters.growth
    for name, _, _, draws in entries:
        if names_of[name] != ref:
            raise SetupError(f"setup {name}: samples the contact parameters {list(names_of[name])}, setup {ref_name} "
                             f"{list(ref)}; a library pools one set (give every setup the same [contact] table "
                             "kinds and the same number of clamping lengths)")
        g = draws.parameters.growth
        if (g.l_a, g.l_b, g.growth_bound) != (g0.l_a, g0.l_b, g0.growth_bound):
            hint = " (mixed units?)" if max(g.l_b, g0.l_b) > 100 * min(g.l_b, g0.l_b) else ""
            raise SetupError(f"setup {name}: growth law [l_a, l_b] = [{g.l_a:g}, {g.l_b:g}] m, Q = {g.growth_bound:g}; "
                             f"setup {ref_name} has [{g0.l_a:g}, {g0.l_b:g}] m, Q = {g0.growth_bound:g}{hint}; a "
                             "library's stiffness refers to one reference length: give every setup the same "
                             "contact.clamping_range and growth_bound")
    if not ref:
        raise SetupError("no contact parameter is sampled in the stage-1 fits; nothing to pool")
    shape, notes = pooled_shape_coordinates([(e[0], e[3]) for e in entries])
    ref += shape
    warns += notes
    setups = []
    for name, htype, diameter, draws in entries:
        mean, prec, box = stage1_prior(draws.parameters, ref, f"setup {name}")
        z = to_coordinates(ref, draws.values)
        setups.append(SetupDraws(name, htype, diameter, z, mean, prec, box))
    box = np.column_stack([np.min([s.box[:, 0] for s in setups], axis=0), np.max([s.box[:, 1] for s in setups], axis=0)])
    return Stage1(ref, setups, (g0.l_a, g0.l_b, g0.growth_bound), box, warns)
