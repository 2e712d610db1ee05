"""The identification workflow: optimum -> tempering -> emcee (or importance sampling) -> summaries and files.

:func:`identify` runs one method on a :class:`~.problem.Problem` and returns
an :class:`IdentificationResult` (nothing is written except the optional
checkpoint); :func:`.outputs.write_outputs` writes posterior.nc,
summary.json and the plots, :mod:`.fingerprint` checks that a checkpoint
belongs to the run it would continue.  :func:`posterior_stiffness` and
:func:`predict_frf` transfer the result to other clamping lengths.

Random numbers: one :class:`numpy.random.Generator` is made from ``seed``
and split with ``Generator.spawn`` into independent streams for the
optimiser, the walker start and emcee's proposals, so changing one stage
(e.g. a user start) does not change the random numbers of the others.
Importance sampling (``sampler="importance"`` or ``"auto"``) draws from a
fifth stream, so a run that falls back to the chain gives the chain of
``sampler="mcmc"`` with the same seed.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import SetupError
from ..model.assembly import Configuration, ConfigurationStack
from ..model.natural_frequencies import NATURAL_FREQUENCY_RULE, natural_frequency
from ..params.forward import ForwardModel
from ..params.model import ParameterModel
from ..stats.weights import MIN_ESS_INTERVAL_END, PARETO_K_MAX
from . import results as R
from .band import band_mask, band_peak_warning
from .checkpoint import Checkpoint
from .deterministic import DeterministicFit, fit_deterministic
from .fingerprint import resume_state, run_fingerprint
from .importance import ImportanceResult, importance_posterior
from .likelihood import residual_correlation_length
from .posterior import LogPosterior
from .problem import Problem
from .sampler import ChainResult, Optimum, SamplerSettings, find_optimum, initial_ensemble, run_ensemble

__all__ = [
    "IdentificationResult",
    "identify",
    "posterior_stiffness",
    "predict_frf",
    "sampling_labels",
    "MAX_DRAWS",
    "SAMPLERS",
    "check_sampler",
]

MAX_DRAWS = 4000  # kept posterior draws (after burn-in and tau-based thinning) stored and summarised
#: How the posterior is sampled: "mcmc" the emcee chain; "importance" importance sampling around the optimum
#: (:mod:`.importance`), falling back to the chain with a warning when its diagnostics refuse it; "auto" the same,
#: but the fall-back is a note (summary.json's ``sampler`` block), not a warning, and a resume continues the chain.
SAMPLERS = ("mcmc", "importance", "auto")


@dataclass(frozen=True)
class IdentificationResult:
    """Everything :func:`identify` found.

    Attributes
    ----------
    problem : Problem
    summary : dict
        The content of summary.json.
    theta : (n_chains, n_draws, ndim)
        Kept draws in sampling coordinates (walkers as chains); a
        deterministic fit has one chain with one draw.
    log_prob : (n_chains, n_draws) or None
    natural_frequency : (n_chains, n_draws, n_all_measurements)
        Predicted dominant natural frequency (Hz) of every setup measurement.
    chain : ChainResult or None
        The emcee run (None for the deterministic method and for accepted importance sampling).
    deterministic : DeterministicFit or None
    optimum : Optimum or None
    tempering : float
    residual_correlation : float
    seed : int
    evaluations : int
        Log-posterior evaluations (walker-parameter sets) in this process.
    wall_time : float
        Seconds of this process's work.
    warnings : tuple of str
    importance : ImportanceResult or None
        The importance-sampling attempt (``sampler`` "importance" or "auto"), accepted or not.
    """

    problem: Problem
    summary: dict
    theta: np.ndarray
    log_prob: np.ndarray | None
    natural_frequency: np.ndarray
    chain: ChainResult | None = None
    deterministic: DeterministicFit | None = None
    optimum: Optimum | None = None
    tempering: float = 1.0
    residual_correlation: float = 1.0
    seed: int = 0
    evaluations: int = 0
    wall_time: float = 0.0
    warnings: tuple = field(default_factory=tuple)
    importance: ImportanceResult | None = None

    @property
    def bayesian(self) -> bool:
        """Posterior draws (a chain or accepted importance sampling), not a deterministic fit."""
        return self.log_prob is not None

    @property
    def flat_theta(self) -> np.ndarray:
        """(n_chains * n_draws, ndim)"""
        return self.theta.reshape(-1, self.theta.shape[-1])

    def values(self) -> dict[str, np.ndarray]:
        """Physical values of all parameters per kept draw, ``{name: (n,)}``."""
        return self.problem.parameters.values(self.flat_theta)


def sampling_labels(parameters: ParameterModel) -> list[str]:
    """Axis labels of the sampling coordinates: ``log10`` / ``ln`` for log-scale priors, the printed symbol or
    name (``kxf``, ``noise scale of measurement 2``: :mod:`bayes_rcsa.vocabulary`), with units."""
    from ..vocabulary import parameter_name, parameter_symbol

    out = []
    for n in parameters.names:
        unit = parameters.unit(n)
        kind = parameters.priors[n].kind
        prefix = {"log-uniform": "log10 ", "log-normal": "ln "}.get(kind, "")
        shown = parameter_symbol(n) or parameter_name(n, parameters[n].label, symbol=False)
        out.append(f"{prefix}{shown}" + (f" [{unit}]" if unit and unit != "1" else ""))
    return out


def corner_columns(parameters: ParameterModel) -> list[int]:
    """Sampling-coordinate columns a corner plot shows: every sampled parameter but the noise scales.

    The noise scales (one per measurement; eight for the bundled example) are nuisance parameters, nearly
    independent of the model's and summarised by their intervals in summary.json and the report; a corner of
    all twelve coordinates of the example was a 25-inch grid of 144 panels, unreadable at screen size and
    half of identify's run time.  When only noise scales are sampled, all of them are shown.
    """
    noise = set(parameters.noise_names)
    cols = [i for i, n in enumerate(parameters.names) if n not in noise]
    return cols or list(range(len(parameters.names)))


# -- posterior transfer ----------------------------------------------------


def posterior_stiffness(result: IdentificationResult, lengths) -> tuple[np.ndarray, np.ndarray]:
    """Contact stiffness draws at clamping lengths.

    Returns
    -------
    k_xf, k_thetaM : each (n_draws, n_lengths), N/m and N m/rad
    """
    lengths = np.atleast_1d(np.asarray(lengths, dtype=float))
    pm = result.problem.parameters
    if pm.growth.has_growth:
        pm.growth.check_lengths(lengths, "prediction clamping length")
    c = pm.contact(pm.values(result.flat_theta), lengths)
    return c.k_xf, c.k_thetaM


def predict_frf(result: IdentificationResult, configuration: Configuration, frequency_hz, max_draws: int | None = None,
                rng: np.random.Generator | None = None) -> np.ndarray:
    """Tool-point FRF draws for a (possibly unmeasured) configuration.

    Parameters
    ----------
    configuration : Configuration
    frequency_hz : (n_freq,) Hz
    max_draws : int, optional
        Use a random subset of this many draws (needs ``rng``).

    Returns
    -------
    (n_draws, n_freq) complex, m/N
    """
    theta = result.flat_theta
    if max_draws is not None and theta.shape[0] > max_draws:
        if rng is None:
            raise SetupError("predict_frf: a subset of draws needs an explicit rng")
        theta = theta[rng.choice(theta.shape[0], max_draws, replace=False)]
    pm = result.problem.parameters
    if pm.growth.has_growth:
        pm.growth.check_lengths([configuration.clamping_length], "prediction clamping length")
    model = result.problem.model
    stack = ConfigurationStack([model.precompute(configuration, frequency_hz)])
    return ForwardModel(pm, stack, model).frf_theta(theta)


# -- the workflow ------------------------------------------------------------


@dataclass(frozen=True)
class _Startup:
    """Results of the start-up stage: optimum, walker centre and tempering."""

    optimum: Optimum
    x0: np.ndarray
    beta: float
    tau_r: float


def _startup(problem: Problem, lp_full: LogPosterior, state) -> _Startup:
    """Step 2 (step 1 is :func:`.fingerprint.resume_state`): global optimum, walker centre and tempering (or the stored ones when resuming)."""
    start = _check_start(problem)
    if state is not None:
        meta = state.meta
        optimum = Optimum(np.array(meta["optimum"]), float(meta["optimum_log_posterior"]), 0, True, "from checkpoint")
        beta, tau_r = float(meta["tempering"]), float(meta["residual_correlation"])
    else:
        optimum = find_optimum(lp_full)
        z = problem.likelihood.normalised_residuals(optimum.x)
        tau_r = residual_correlation_length(z, problem.likelihood.stack.slices)
        t = problem.options.tempering
        beta = 1.0 / tau_r if t == "auto" else float(t)
    x0 = optimum.x.copy()
    for j, value in start.items():
        x0[j] = value
    return _Startup(optimum, x0, beta, tau_r)


def _sample(problem: Problem, lp: LogPosterior, startup: _Startup, settings: SamplerSettings, n_walkers: int,
            fingerprint: dict, ckpt: Checkpoint | None, state, rng_init, rng_mcmc, moves=None) -> ChainResult:
    """Step 3: the emcee run, new or continued.

    A checkpoint with no stored step (killed right after the start-up) is
    continued as a new run from its stored start-up results, which gives the
    same chain as an uninterrupted run.
    """
    from .diagnostics import chain_diagnostics

    initial = None
    if state is None or state.iteration == 0:
        initial = initial_ensemble(lp, startup.x0, rng_init, n_walkers)
        if ckpt is not None and state is None:
            ckpt.create(n_walkers, problem.parameters.ndim, {
                "fingerprint": fingerprint, "tempering": startup.beta, "residual_correlation": startup.tau_r,
                "optimum": startup.optimum.x.tolist(), "optimum_log_posterior": startup.optimum.log_posterior,
            })
        state = None
    chain = run_ensemble(lp, settings, initial=initial, rng=rng_mcmc, checkpoint=ckpt, resume_state=state,
                         diagnose=chain_diagnostics, moves=moves)
    if ckpt is not None:
        ckpt.finish()
    return chain


def _thin(chain: ChainResult, max_draws: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Step 4: burn-in, tau-based thinning and a further even thinning to at most ``max_draws``.

    Returns
    -------
    theta : (n_walkers, n_draws, ndim), log_prob : (n_walkers, n_draws), extra : int (the further thinning)
    """
    kept = chain.chain[chain.burn :: chain.thin]  # (n_keep, n_walkers, ndim)
    kept_lp = chain.log_prob[chain.burn :: chain.thin]
    extra = max(1, math.ceil(kept.shape[0] * kept.shape[1] / max_draws))
    theta = np.ascontiguousarray(kept[::extra].transpose(1, 0, 2))
    log_prob = np.ascontiguousarray(kept_lp[::extra].T)
    return theta, log_prob, extra


def _evaluation_stack(problem: Problem):
    """Band lines of every setup measurement, and the measured natural frequencies."""
    caches, measured, bands = [], [], []
    for cfg, frf in problem.all_measurements:
        band = problem.band_of(frf)
        mask = band_mask(frf, band)
        f = frf.frequency_hz[mask]
        caches.append(problem.model.precompute(cfg, f))
        measured.append(float(natural_frequency(f, frf.values[mask])))
        bands.append(band)
    return ConfigurationStack(caches), np.array(measured), bands


def _predicted_natural_frequencies(problem: Problem, stack: ConfigurationStack, theta: np.ndarray, batch: int = 256,
                                   spindle_samples=None, rng: np.random.Generator | None = None) -> np.ndarray:
    """(n, n_all) predicted natural frequencies for flat draws theta (n, ndim).

    With ``spindle_samples`` (:class:`bayes_rcsa.spindle.SpindleSamples`) every
    draw is evaluated with its own spindle sample (balanced random
    assignment from ``rng``), so the intervals include the spindle uncertainty.
    """
    pm = problem.parameters
    forward = ForwardModel(pm, stack, problem.model, spindle_samples=spindle_samples)
    out = np.empty((theta.shape[0], len(problem.all_measurements)))
    assignment = None
    if spindle_samples is not None:
        from ..spindle.uncertainty import assign_samples

        assignment = assign_samples(theta.shape[0], spindle_samples.n_samples, rng)
    for a in range(0, theta.shape[0], batch):
        h = forward.frf(pm.values(theta[a : a + batch]), None if assignment is None else assignment[a : a + batch])
        for j, (part, cache) in enumerate(zip(stack.split(h), stack.caches)):
            out[a : a + batch, j] = natural_frequency(cache.frequency_hz, part)
    return out


def _model_on_measurements(problem: Problem, theta: np.ndarray) -> list[tuple]:
    """(frf, lines, model FRF (n_lines,)) of every used measurement at one parameter vector, on its own lines.

    The lines are the measurement's inside the spindle data (where the model exists).
    """
    pm = problem.parameters
    values = pm.values(np.atleast_2d(theta)[:1])
    out = []
    for cfg, frf in problem.measurements:
        sf = problem.model.spindle_receptance(cfg.direction).frequency_hz
        keep = (frf.frequency_hz >= sf[0]) & (frf.frequency_hz <= sf[-1])
        f = frf.frequency_hz[keep]
        if f.size < 3:
            continue
        stack = ConfigurationStack([problem.model.precompute(cfg, f)])
        out.append((frf, keep, ForwardModel(pm, stack, problem.model).frf(values)[0]))
    return out


def _fit_checks(problem: Problem, theta: np.ndarray) -> tuple[list[str], dict[int, str]]:
    """Band-peak warnings and likely causes of a gross misfit (units, sign) at the optimum ``theta``.

    Returns
    -------
    warnings : list of str
        :func:`.band.band_peak_warning` of every used measurement.
    causes : dict measurement index -> str
        :func:`bayes_rcsa.io.checks.likely_cause` of the measurement against the model at ``theta``.
    """
    from ..io.checks import likely_cause

    warnings, causes = [], {}
    index = {id(frf): j for j, (_, frf) in enumerate(problem.measurements)}
    for frf, keep, h in _model_on_measurements(problem, theta):
        j = index[id(frf)]
        peak = float(frf.frequency_hz[keep][int(np.argmax(np.abs(h)))])
        w = band_peak_warning(frf, problem.observations[j].band, peak)
        if w:
            warnings.append(w)
        cause = likely_cause(frf.values[keep], h)
        if cause:
            causes[j] = cause
    return warnings, causes


def _common_summary(problem: Problem, seed: int) -> dict:
    g = problem.growth
    return {
        "method": problem.method,
        "seed": int(seed),
        "parameter_names": list(problem.parameters.names),
        "fixed_parameters": dict(problem.parameters.fixed),
        "priors": problem.priors.describe(),
        "model_terms": [t.describe() for t in problem.parameters.terms],
        "parameter_model": problem.parameters.to_dict(),
        "reference_clamping_length": g.l_a,
        "feasible_range": [g.l_a, g.l_b] if g.has_growth else None,
        "growth_bound": g.growth_bound,
        "growth_law": "k(l) = k(l_ref) * (1 + g * (l - l_a) / (l_b - l_a)), 0 <= g <= Q" if g.has_growth
        else "k constant (single clamping length)",
        "measurements_used": [
            {"clamping_length": o.configuration.clamping_length, "direction": o.configuration.direction,
             "tool": o.configuration.tool, "source": o.source, "band": o.band.as_dict(), "n_lines": o.n_lines,
             "n_low_coherence_lines": o.n_low_coherence, "noise_parameter": problem.parameters.noise_name(j)}
            for j, o in enumerate(problem.observations)
        ],
        "natural_frequency_rule": NATURAL_FREQUENCY_RULE,
    }


def _stiffness_and_frequencies(problem: Problem, theta_flat: np.ndarray, nat: np.ndarray, measured_nat: np.ndarray):
    used_lengths = {round(o.configuration.clamping_length, 12) for o in problem.observations}
    lengths = sorted({round(c.clamping_length, 12) for c, _ in problem.all_measurements})
    pm = problem.parameters
    c = pm.contact(pm.values(theta_flat), lengths)
    kx, kt = c.k_xf, c.k_thetaM
    stiffness = [R.stiffness_entry(l, kx[:, i], kt[:, i], l in used_lengths) for i, l in enumerate(lengths)]
    used_cfg = {(o.configuration, o.source) for o in problem.observations}
    freqs = [
        R.natural_frequency_entry(cfg, measured_nat[j], nat[:, j], (cfg, frf.source) in used_cfg)
        for j, (cfg, frf) in enumerate(problem.all_measurements)
    ]
    return stiffness, freqs


def _check_start(problem: Problem) -> dict[int, float]:
    """Sampling coordinates of the user's ``[sampler] start`` values, checked against the prior."""
    start = problem.options.start or {}
    names = problem.parameters.names
    unknown = set(start) - set(names)
    if unknown:
        raise SetupError(f"sampler.start: unknown parameter(s) {sorted(unknown)}; sampled parameters: {list(names)}")
    out = {}
    for name, value in start.items():
        prior = problem.priors[name]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = float(prior.to_sampling(value))
        if not prior.in_support(u):
            raise SetupError(
                f"walker start (sampler.start): parameter {name} = {value:.6g} lies outside its prior support "
                f"{prior.describe()}"
            )
        out[names.index(name)] = u
    return out


def check_sampler(sampler: str, resume: bool) -> None:
    """Refuse an unknown ``sampler`` (:data:`SAMPLERS`) and a resume with "importance" (it keeps no checkpoint).

    Raises
    ------
    SetupError
    """
    if sampler not in SAMPLERS:
        raise SetupError(f"--sampler {sampler!r}: expected one of {', '.join(SAMPLERS)}")
    if resume and sampler == "importance":
        raise SetupError("--resume continues an MCMC checkpoint: use --sampler mcmc or auto (importance sampling "
                         "keeps no checkpoint)")


def identify(
    problem: Problem,
    seed: int = 0,
    settings: SamplerSettings = SamplerSettings(),
    checkpoint_path=None,
    resume: bool = False,
    max_draws: int = MAX_DRAWS,
    spindle_samples=None,
    moves=None,
    sampler: str = "auto",
    importance_options: dict | None = None,
) -> IdentificationResult:
    """Run the identification.

    Steps: resume check and fingerprint
    (:func:`.fingerprint.run_fingerprint`, :func:`.fingerprint.resume_state`), then functions of this module:
    start-up optimum and
    tempering (``_startup``), sampling (``_sample``), thinning (``_thin``),
    summary (``_summarise``).

    Parameters
    ----------
    problem : Problem
    seed : int
        Seed of the run's random generator (same seed, same result).
    settings : SamplerSettings
    checkpoint_path : path, optional
        HDF5 checkpoint (Bayesian methods).
    resume : bool
        Continue the run in ``checkpoint_path``.
    max_draws : int
        Kept draws are thinned further (evenly) to at most this many.
    spindle_samples : SpindleSamples, optional
        Flange-receptance samples (``bayes-rcsa spindle``); the predicted
        natural-frequency intervals then mix the posterior draws with them.
    moves : emcee moves, optional
        Passed to :func:`.sampler.run_ensemble` (default: differential
        evolution with ``settings.snooker_fraction`` snooker moves).  Not part
        of the resume fingerprint: resume with the moves of the original run.
    sampler : {"auto", "importance", "mcmc"}
        :data:`SAMPLERS` (default "auto").  With "importance" or "auto" the posterior is first importance-sampled around the
        optimum (:func:`.importance.importance_posterior`); accepted draws (Pareto k <= 0.7, ESS >= 1000) become
        the result, refused ones give way to the chain (summary.json's ``sampler`` block says why).  A resume
        continues the chain ("auto") or is refused ("importance": there is no checkpoint to continue).
    importance_options : dict, optional
        Keywords of :func:`.importance.importance_posterior` (e.g. ``proposal_shrink``, ``max_proposals``).

    Raises
    ------
    SetupError
        Resuming without a checkpoint or with one from a different run (the
        message names what changed); a walker start outside the prior; an unknown ``sampler``; a resume with
        ``sampler="importance"``.
    """
    t_start = time.perf_counter()
    check_sampler(sampler, resume)
    # each further child leaves the earlier streams (and so earlier results) unchanged
    rng_opt, rng_init, rng_mcmc, rng_spindle, rng_is = np.random.default_rng(seed).spawn(5)
    if problem.method == "deterministic":
        return _identify_deterministic(problem, seed, rng_opt, t_start)

    lp_full = problem.log_posterior()
    n_walkers = settings.walkers(problem.parameters.ndim)
    fingerprint = run_fingerprint(problem, seed, settings, n_walkers)
    ckpt = Checkpoint(checkpoint_path) if checkpoint_path is not None else None
    state = resume_state(ckpt, checkpoint_path, fingerprint) if resume else None
    startup = _startup(problem, lp_full, state)
    lp = problem.log_posterior(startup.beta)
    imp = None
    if sampler != "mcmc" and state is None:
        imp = importance_posterior(lp, startup.optimum.x, problem.priors.optimisation_bounds(), rng_is, max_draws,
                                   **(importance_options or {}))
    run = _Run(sampler, imp, settings, n_walkers)
    if imp is not None and imp.accepted:
        return _summarise(problem, seed, spindle_samples, rng_spindle, t_start, lp_full, lp, startup, run,
                          imp.theta[None], imp.log_prob[None])
    run.chain = _sample(problem, lp, startup, settings, n_walkers, fingerprint, ckpt, state, rng_init, rng_mcmc, moves)
    theta, log_prob, run.extra = _thin(run.chain, max_draws)
    return _summarise(problem, seed, spindle_samples, rng_spindle, t_start, lp_full, lp, startup, run, theta,
                      log_prob)


@dataclass
class _Run:
    """How the posterior was sampled: the requested sampler, the importance attempt, the chain and its thinning."""

    requested: str
    importance: ImportanceResult | None
    settings: SamplerSettings
    n_walkers: int
    chain: ChainResult | None = None
    extra: int = 1

    def sampler_block(self) -> dict:
        """summary.json's ``sampler``: mode, requested, importance diagnostics, fall-back reason."""
        imp = self.importance
        out = {"mode": "mcmc" if self.chain is not None else "importance", "requested": self.requested,
               "fallback_reason": None}
        if imp is not None:
            out.update(imp.describe())
            if not imp.accepted:
                out["fallback_reason"] = imp.reason
        elif self.requested == "auto":
            out["fallback_reason"] = "resumed: the checkpointed chain is continued"
        return out

    def diagnostics(self, names) -> tuple[dict, list[str], dict]:
        """Per-parameter (R-hat, bulk ESS, tail ESS), convergence warnings and the summary's convergence fields.

        Importance sampling has no chain: R-hat is None, both ESS are the weights' Kish ESS, and convergence is
        the acceptance rule (Pareto k and ESS) instead of R-hat and tau.
        """
        imp, chain, settings = self.importance, self.chain, self.settings
        if chain is None:
            per = {n: (None, imp.ess, imp.ess) for n in names}
            fields = {"converged": True, "stop_reason": f"importance sampling accepted: Pareto k = "
                      f"{imp.pareto_k:.2f} <= {PARETO_K_MAX:g}, ESS {imp.ess:.0f} >= {MIN_ESS_INTERVAL_END} (no chain: R-hat "
                      "and tau do not apply)",
                      "tau": None, "n_steps": None, "burn_in": None, "thin": None, "acceptance_fraction": None,
                      "n_walkers": None}
            return per, [], fields
        diag = chain.diagnostics or {}
        get = lambda key, j: float(diag[key][j]) if key in diag else None  # noqa: E731
        per = {n: (get("rhat", j), get("ess_bulk", j), get("ess_tail", j)) for j, n in enumerate(names)}
        warnings = []
        if imp is not None and not imp.accepted and self.requested == "importance":
            warnings.append(f"{imp.reason}; the emcee chain was run instead")
        if not chain.converged:
            warnings.append(f"not converged: {chain.reason}")
        if diag:
            for j, n in enumerate(names):
                if not diag["rhat"][j] < settings.rhat_max:
                    warnings.append(f"{n}: R-hat = {diag['rhat'][j]:.4f} >= {settings.rhat_max}")
                if not diag["ess_bulk"][j] >= settings.ess_min:
                    warnings.append(f"{n}: bulk ESS = {diag['ess_bulk'][j]:.0f} < {settings.ess_min:g}")
        fields = {"converged": bool(chain.converged), "stop_reason": chain.reason, "tau": R.tau_dict(names, chain.tau),
                  "n_steps": chain.n_steps, "burn_in": chain.burn, "thin": chain.thin * self.extra,
                  "acceptance_fraction": float(np.mean(chain.acceptance_fraction)), "n_walkers": self.n_walkers}
        return per, warnings, fields

    def timing(self, wall: float, per: dict, evals: int) -> dict:
        """summary.json's ``timing`` (s; ``per`` from :meth:`diagnostics`; ``evals`` log-posterior evaluations)."""
        ess = [v[1] for v in per.values() if v[1] is not None]
        chain = self.chain
        return {"wall_time_s": wall, "sampling_time_s": self.importance.wall_time if chain is None else chain.wall_time,
                "new_steps": None if chain is None else chain.n_new_steps, "log_posterior_evaluations": evals,
                "evaluations_per_second": evals / wall if wall > 0 else None,
                "min_ess_bulk_per_second": float(np.min(ess)) / wall if ess and wall > 0 else None,
                # the importance attempt's own time, also when the chain ran after it (a fall-back)
                "importance_time_s": None if self.importance is None else float(self.importance.wall_time)}


def _summarise(problem: Problem, seed: int, spindle_samples, rng_spindle, t_start: float, lp_full: LogPosterior,
               lp: LogPosterior, startup: _Startup, run: _Run, theta: np.ndarray,
               log_prob: np.ndarray) -> IdentificationResult:
    """Step 5: parameter, stiffness and natural-frequency summaries, warnings, timing."""
    flat = theta.reshape(-1, theta.shape[-1])
    beta, tau_r, optimum = startup.beta, startup.tau_r, startup.optimum
    stack, measured_nat, _ = _evaluation_stack(problem)
    nat = _predicted_natural_frequencies(problem, stack, flat, spindle_samples=spindle_samples, rng=rng_spindle)
    pm = problem.parameters
    values = pm.values(flat)
    names = pm.names
    per, warnings, convergence = run.diagnostics(names)
    params = {n: R.parameter_summary(values[n], *per[n], pm.unit(n)) for n in names}
    stiffness, freqs = _stiffness_and_frequencies(problem, flat, nat, measured_nat)
    # only sampled growth factors can pile up; a fixed g = 0 (one clamping length) is not a conflict
    growth_warnings = R.growth_bound_warnings({n: values[n] for n in names}, problem.growth.growth_bound)
    warnings += growth_warnings
    warnings += R.prior_bound_warnings(flat, pm, skip=[n for n in ("g_xf", "g_thetaM")
                                                      if any(w.startswith(n + ":") for w in growth_warnings)])
    band_warnings, causes = _fit_checks(problem, optimum.x)
    warnings += R.noise_scale_warnings(values, problem.observations, causes)
    warnings += band_warnings
    for e in freqs:
        if e["nan_fraction"] > 0:
            warnings.append(
                f"natural frequency at {e['clamping_length'] * 1e3:g} mm ({e['direction']}): "
                f"{100 * e['nan_fraction']:.1f} % of the draws peak on a band edge (left out of the quantiles)"
            )
    if tau_r > 3:
        # informative, not an error: large correlation lengths signal model discrepancy
        warnings.append(
            f"residuals are correlated over {tau_r:.1f} lines at the optimum: the likelihood is tempered by "
            f"beta = {beta:.3g} (model discrepancy or smooth measurement errors)"
        )

    wall = time.perf_counter() - t_start
    evals = lp_full.n_evaluations + lp.n_evaluations
    summary = _common_summary(problem, seed)
    if spindle_samples is not None:
        summary["spindle_uncertainty"] = spindle_samples.describe()
    summary.update({
        "converged": convergence["converged"],
        "stop_reason": convergence["stop_reason"],
        "sampler": run.sampler_block(),
        "parameters": params,
        "stiffness": stiffness,
        "natural_frequencies": freqs,
        **{k: convergence[k] for k in ("tau", "n_steps", "burn_in", "thin", "acceptance_fraction", "n_walkers")},
        "n_draws": int(flat.shape[0]),
        "likelihood": {
            "tempering": beta,
            "residual_correlation_lines": tau_r,
            "effective_lines": problem.likelihood.n_lines * beta,
            "n_lines": problem.likelihood.n_lines,
            "noise_floor": problem.likelihood.noise.floor,
            "min_coherence": problem.likelihood.noise.min_coherence,
        },
        "optimum": {n: float(v[0]) for n, v in pm.values(optimum.x[None, :]).items() if n in names},
        "timing": run.timing(wall, per, evals),
        "warnings": [w for w in warnings if w],
    })
    return IdentificationResult(
        problem=problem, summary=summary, theta=theta, log_prob=log_prob,
        natural_frequency=nat.reshape(theta.shape[0], theta.shape[1], -1), chain=run.chain, deterministic=None,
        optimum=optimum, tempering=beta, residual_correlation=tau_r, seed=int(seed), evaluations=evals, wall_time=wall,
        warnings=tuple(w for w in warnings if w), importance=run.importance,
    )


def _identify_deterministic(problem: Problem, seed: int, rng: np.random.Generator, t_start: float) -> IdentificationResult:
    from .search import grid_candidates

    start = grid_candidates(problem.likelihood, problem.priors, n_best=1)[0]
    fit = fit_deterministic(problem.likelihood, rng, x0=start)
    theta = fit.theta[None, None, :]
    stack, measured_nat, _ = _evaluation_stack(problem)
    nat = _predicted_natural_frequencies(problem, stack, fit.theta[None, :])
    params = {n: R.parameter_summary(np.array([v]), unit=problem.parameters.unit(n)) for n, v in fit.values.items()}
    stiffness, freqs = _stiffness_and_frequencies(problem, fit.theta[None, :], nat, measured_nat)
    warnings = []
    if not fit.success:
        warnings.append(f"optimiser: {fit.message}")
    q = problem.growth.growth_bound
    on_growth_bound = []
    for n in ("g_xf", "g_thetaM"):
        if n in fit.values and q > 0 and fit.values[n] > 0.99 * q:
            on_growth_bound.append(n)
            warnings.append(f"{n} = {fit.values[n]:.4g} sits on the growth bound Q = {q:g}: the fit wants more growth "
                            f"than Q allows (prior-data conflict) or {n} is poorly determined by the data")
    warnings += R.prior_bound_warnings(fit.theta[None, :], problem.parameters,
                                       skip=on_growth_bound + list(problem.parameters.noise_names))
    band_warnings, causes = _fit_checks(problem, fit.theta)
    warnings += band_warnings
    # the deterministic objective has no noise scale to absorb a gross misfit: name the likely cause directly
    for j, cause in sorted(causes.items()):
        warnings.append(f"{problem.observations[j].source}: the fitted model does not match the measurement "
                        f"(objective {fit.objective:.3g} %); likely cause: {cause}")
    wall = time.perf_counter() - t_start
    summary = _common_summary(problem, seed)
    summary.update({
        "converged": bool(fit.success),
        "stop_reason": fit.message,
        "objective_percent": fit.objective,
        "parameters": params,
        "stiffness": stiffness,
        "natural_frequencies": freqs,
        "timing": {"wall_time_s": wall, "objective_evaluations": fit.n_evaluations},
        "warnings": warnings,
    })
    return IdentificationResult(
        problem=problem, summary=summary, theta=theta, log_prob=None, natural_frequency=nat[None],
        deterministic=fit, seed=int(seed), evaluations=fit.n_evaluations, wall_time=wall, warnings=tuple(warnings),
    )
