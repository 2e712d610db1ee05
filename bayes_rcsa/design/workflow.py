"""Which test next?  The design workflow (posterior mode and no-data planning mode).

Posterior mode (:func:`run_design`)
    Rank candidate hammer tests by the expected 90 % width of a target
    after each (:mod:`.estimators`), using the posterior's parameter model
    and model terms, the noise level the fit found (geometric mean of the
    posterior medians of the relative noise scales ``sigma_j``), the
    likelihood's noise floor and the tempering the fit used, so that a
    simulated test is worth what a real one was worth.  A single-length
    posterior gets the growth law's prior uncertainty first
    (:func:`bayes_rcsa.posterior.growth_prior.with_growth_prior`).

No-data mode (:func:`run_planning`)
    Without a posterior, draws from the prior: which *two* clamping lengths
    minimise the expected 90 % width of the dominant natural frequency,
    averaged over the feasible range (the "transfer uncertainty"), by the
    Laplace / Fisher estimator (importance weights of prior draws collapse
    for data this informative).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from ..errors import DataError, SetupError
from ..model.assembly import Configuration, ConfigurationStack
from ..model.natural_frequencies import natural_frequency
from ..params.forward import ForwardModel
from ..posterior.draws import PosteriorDraws, load_posterior
from ..posterior.growth_prior import feasible_growth_law, needs_growth_prior, with_growth_prior
from . import estimators as E
from .targets import Candidate, Target, TargetEvaluator, design_direction, design_tool, frequency_lines

__all__ = ["WORTH_IT_FRACTION", "DEFAULT_DRAWS", "DEFAULT_TRUTHS", "CandidateResult", "DesignResult",
           "PlanningResult", "noise_level", "posterior_attributes", "run_design", "design_from_draws", "run_planning"]

#: A test is worth doing when it is expected to shrink the target's 90 % width by at least this fraction
#: of the current width (and by more than twice its Monte Carlo error).
WORTH_IT_FRACTION = 1.0 / 3.0
DEFAULT_DRAWS = 1500
DEFAULT_TRUTHS = 120
#: Growth-prior draws combined with each draw of a single-length posterior.
GROWTH_REPLICATES = 16
#: Steps of the central differences, in posterior (or prior) standard deviations of each coordinate: of the FRF,
#: and of the target.  The target's step is small because the natural-frequency rule (parabola through three
#: lines) has a local slope that varies within a line spacing, and the width after a test (tenths of a Hz on
#: 8-Hz lines) is set by the slope at the truth, not by its average over a line.
FD_STEP = 0.01
FD_STEP_TARGET = 0.002
#: Relative noise scale and tempering assumed in the no-data mode (no fit to take them from).
PLANNING_NOISE = 0.02
PLANNING_TEMPERING = 1.0


@dataclass(frozen=True)
class CandidateResult:
    candidate: Candidate
    estimate: E.WidthEstimate
    importance: E.WidthEstimate | None
    laplace: E.WidthEstimate | None
    n_lines: int
    band_hz: tuple[float, float]

    def as_dict(self, current: float) -> dict:
        c = self.candidate.configuration
        e = self.estimate
        out = {
            "test": self.candidate.label, "input": self.candidate.text,
            "clamping_length": c.clamping_length, "direction": c.direction, "tool": c.tool,
            "expected_width": e.expected_width, "mc_error": e.mc_error,
            "width_range_90": list(e.width_range),
            "width_interval_95": list(e.prediction_interval),
            "expected_gain": current - e.expected_width,
            "relative_gain": (current - e.expected_width) / current if current > 0 else None,
            "method": e.method, "band_lo_hz": self.band_hz[0], "band_hi_hz": self.band_hz[1], "n_lines": self.n_lines,
        }
        if self.importance is not None:
            out["importance"] = {"expected_width": self.importance.expected_width, "mc_error": self.importance.mc_error,
                                 "ess_median": self.importance.ess_median, "ess_min": self.importance.ess_min,
                                 "collapsed": self.importance.collapsed}
        if self.laplace is not None:
            out["laplace"] = {"expected_width": self.laplace.expected_width, "mc_error": self.laplace.mc_error}
        return out


@dataclass(frozen=True)
class DesignResult:
    target: Target
    current_width: float
    candidates: tuple  # CandidateResult, best first
    noise: E.NoiseLevel
    n_draws: int
    n_truths: int
    nan_fraction: float
    notes: tuple = ()
    provenance: dict = field(default_factory=dict)

    @property
    def best(self) -> CandidateResult:
        return self.candidates[0]

    def worth_it(self) -> bool:
        b = self.best.estimate
        gain = self.current_width - b.expected_width
        return bool(gain >= WORTH_IT_FRACTION * self.current_width and gain > 2.0 * b.mc_error)

    def as_dict(self) -> dict:
        t = self.target
        b = self.best
        worth = self.worth_it()
        gain = self.current_width - b.estimate.expected_width
        verdict = (f"measure {b.candidate.label}: expected to shrink the 90 % width of {t.text} from "
                   f"{self.current_width:.4g} to {b.estimate.expected_width:.4g} {t.unit}" if worth else
                   f"more tests are not worth it: the best candidate ({b.candidate.label}) is expected to shrink the "
                   f"90 % width of {t.text} by {gain:.3g} {t.unit} ({100 * gain / self.current_width:.3g} %), less "
                   f"than {100 * WORTH_IT_FRACTION:.0f} % of the current {self.current_width:.4g} {t.unit}")
        collapsed = [c.candidate.label for c in self.candidates if c.importance is not None and c.importance.collapsed]
        return {
            "mode": "posterior",
            "target": t.text, "target_kind": t.kind, "target_clamping_length": t.clamping_length, "unit": t.unit,
            "width_definition": "90 % central credible interval (5 % to 95 % quantile); mean over speeds for lobes",
            "current_width": self.current_width,
            "candidates": [c.as_dict(self.current_width) for c in self.candidates],
            "best": {"test": b.candidate.label, "clamping_length": b.candidate.clamping_length,
                     "direction": b.candidate.configuration.direction, "tool": b.candidate.configuration.tool,
                     "expected_width": b.estimate.expected_width, "mc_error": b.estimate.mc_error},
            "expected_gain": gain, "relative_gain": gain / self.current_width if self.current_width > 0 else None,
            "worth_it": worth,
            "worth_it_rule": f"expected width reduction >= {WORTH_IT_FRACTION:.3g} x current width and > 2 MC errors",
            "verdict": verdict,
            "method": {"estimator": "nested Monte Carlo with importance re-weighting of posterior draws "
                                    "(Laplace/Fisher approximation where the weights collapse)",
                       "draws": self.n_draws, "simulated_measurements": self.n_truths, "ess_min_rule": E.ESS_MIN,
                       "collapsed": collapsed},
            "noise": {"relative_scale": self.noise.scale, "floor": self.noise.floor, "tempering": self.noise.tempering},
            "target_nan_fraction": self.nan_fraction,
            "notes": list(self.notes),
            **self.provenance,
        }


def posterior_attributes(path) -> dict:
    """Attributes of a ``posterior.nc`` (method, tempering, growth law, ...), merged over its groups."""
    from ..store import read_posterior

    idata = read_posterior(path, option=None, arrays=True)
    return {k: v for group in idata.groups() for k, v in getattr(idata, group).attrs.items()}


def noise_level(draws: PosteriorDraws, floor: float, tempering: float) -> E.NoiseLevel:
    """The fit's noise: geometric mean of the posterior medians of the relative noise scales."""
    names = [n for n in draws.parameters.noise_names if n in draws.values]
    if not names:
        raise DataError(f"{draws.source}: the posterior holds no noise scales (sigma_j); cannot simulate a test "
                        f"with the fit's noise level")
    med = np.array([np.median(draws.values[n]) for n in names])
    if not np.all(np.isfinite(med) & (med > 0)):
        raise DataError(f"{draws.source}: noise-scale draws must be finite and positive")
    if not (0 < tempering <= 1):
        raise DataError(f"{draws.source}: tempering = {tempering!r}, expected 0 < beta <= 1")
    return E.NoiseLevel(float(np.exp(np.mean(np.log(med)))), float(floor), float(tempering))


def _candidate_lines(setup, model, parameters, values, cfg: Configuration, rule: dict):
    """Lines of a candidate test and the draws' FRFs there.

    The identification takes its band from the measured FRF (the default
    rule: the dominant peak and those reaching ``rel_height`` of it, widened
    by ``ratio``).  Where the candidate's peak lies is uncertain before the
    test, so the band here spans the 5 %-95 % range of the draws' dominant
    peak frequencies, widened by ``ratio`` (a median ``|H|`` would smear an
    uncertain peak until a sharper, minor mode looked dominant).
    """
    f = frequency_lines(setup, cfg.direction)
    fwd = ForwardModel(parameters, ConfigurationStack([model.precompute(cfg, f)]), model)
    h = fwd.frf(values)
    mag = np.abs(h)
    peaks = f[np.argmax(mag, axis=1)]
    ratio = float(rule.get("ratio", 1.25))
    lo, hi = np.quantile(peaks, [0.05, 0.95])
    lo, hi = max(lo / ratio, f[0]), min(hi * ratio, f[-1])
    mask = (f >= lo) & (f <= hi)
    if np.count_nonzero(mask) < 3:
        raise SetupError(f"candidate {cfg.label()}: fewer than 3 lines in its band {lo:g}-{hi:g} Hz")
    # eps max|H_meas| of the noise floor: the typical (median) peak height of the draws
    return h[:, mask], (float(lo), float(hi)), float(np.median(np.max(mag[:, mask], axis=1)))


def design_from_draws(setup, draws: PosteriorDraws, target: Target, candidates: Sequence[Candidate],
                      noise: E.NoiseLevel, rng: np.random.Generator, n_truths: int = DEFAULT_TRUTHS,
                      method: str = "auto", cutting=None, band_rule: dict | None = None) -> DesignResult:
    """Rank candidate tests for ``draws`` (already subset and given the growth prior).

    Parameters
    ----------
    setup : Setup
    draws : PosteriorDraws
    target : Target
    candidates : sequence of Candidate
    noise : NoiseLevel
    rng : numpy.random.Generator
    n_truths : int
        M, simulated measurements per candidate.
    method : {"auto", "importance", "laplace"}
        ``auto``: importance re-weighting, Laplace where the weights collapse.
    cutting : CuttingConditions, optional (lobes target)
    band_rule : dict, optional
        ``ratio``, ``rel_height`` of the default band rule.

    Raises
    ------
    SetupError
        A target outside the feasible range, or one undefined for most draws.
    """
    if method not in ("auto", "importance", "laplace"):
        raise SetupError(f"--method {method!r}: expected auto, importance or laplace")
    model = setup.model()
    pm = draws.parameters
    growth = pm.growth
    if growth.has_growth:
        growth.check_lengths([target.clamping_length], "--target clamping length")
    elif abs(target.clamping_length - growth.l_a) > 1e-9:
        raise SetupError(f"--target {target.text!r}: the posterior was fitted at {growth.l_a * 1e3:.4g} mm only and "
                         f"the setup defines no feasible clamping range to carry it to {target.clamping_length * 1e3:.4g} mm "
                         f"([contact] clamping_range)")
    direction, tool = design_direction(setup), design_tool(setup)
    if direction not in setup.spindle:
        raise SetupError(f"--target {target.text!r}: no spindle receptance in direction {direction}")
    evaluator = TargetEvaluator(target, pm, model, setup, direction, tool, cutting, draws.values)
    t_all = evaluator(draws.values)
    ok = np.all(np.isfinite(t_all), axis=1)
    nan_fraction = float(1.0 - np.mean(ok))
    if np.count_nonzero(ok) < max(50, 0.5 * ok.size):
        raise SetupError(f"--target {target.text!r}: undefined for {100 * nan_fraction:.0f} % of the posterior draws "
                         f"(no resonance inside the mode band); the posterior cannot predict this target")
    draws = draws.take(np.flatnonzero(ok))
    values, t = draws.values, t_all[ok]
    current = E.unweighted_width(t)
    rule = dict(band_rule or {})
    names = list(pm.physical_names)
    u = E.sampling_coordinates(pm, values, names)
    cov = np.atleast_2d(np.cov(u, rowvar=False))
    sd = np.sqrt(np.diag(cov))
    step, step_t = FD_STEP * sd, FD_STEP_TARGET * sd
    bounds = np.array([pm.priors[n].bounds for n in names], dtype=float)  # support in sampling coordinates
    rng_is, rng_lp = rng.spawn(2)
    m = int(min(n_truths, draws.n_draws))
    truths = rng_lp.choice(draws.n_draws, m, replace=False)
    grad_t = None
    results = []
    for cand in candidates:  # a handful of tests
        h, band, hmax = _candidate_lines(setup, model, pm, values, cand.configuration, rule)
        floor2 = (noise.floor * hmax) ** 2
        imp = lap = None
        if method in ("auto", "importance"):
            imp = E.importance_widths(h, t, noise, floor2, m, rng_is)
        if method == "laplace" or (imp is not None and imp.collapsed) or method == "auto":
            if grad_t is None:
                grad_t = E.finite_difference_jacobian(
                    lambda uu: evaluator(E.with_sampling_coordinates(pm, values, names, uu, np.repeat(truths, 2 * len(names)))),
                    u[truths], step_t)
            cfg = cand.configuration
            f_band = frequency_lines(setup, cfg.direction)
            f_band = f_band[(f_band >= band[0]) & (f_band <= band[1])]
            fwd = ForwardModel(pm, ConfigurationStack([model.precompute(cfg, f_band)]), model)
            jac = E.finite_difference_jacobian(
                lambda uu: fwd.frf(E.with_sampling_coordinates(pm, values, names, uu, np.repeat(truths, 2 * len(names)))),
                u[truths], step)
            w = 1.0 / (noise.scale**2 * (np.abs(h[truths]) ** 2 + floor2))
            gt = np.nan_to_num(grad_t)
            lap = E.laplace_widths(jac, gt, cov, w, noise.tempering, u[truths], bounds, rng_lp)
        chosen = lap if (method == "laplace" or imp is None or imp.collapsed) else imp
        results.append(CandidateResult(cand, chosen, imp, lap, int(h.shape[1]), band))
    results.sort(key=lambda r: r.estimate.expected_width)
    notes = list(draws.notes)
    for r in results:
        if r.importance is not None and r.importance.collapsed:
            notes.append(f"{r.candidate.label}: importance weights collapsed (median ESS {r.importance.ess_median:.1f} "
                         f"< {E.ESS_MIN:g}); the Laplace/Fisher estimate is reported (or rerun with more --draws)")
    if target.kind == "frequency" and evaluator.band is not None:
        notes.append(f"target band {evaluator.band[0]:.6g}-{evaluator.band[1]:.6g} Hz (dominant mode of the current "
                     f"posterior-median |H| at {target.clamping_length * 1e3:.4g} mm, direction {direction})")
    return DesignResult(target, current, tuple(results), noise, draws.n_draws, m, nan_fraction, tuple(notes),
                        draws.provenance())


def run_design(setup, posterior_path, target: Target, candidates: Sequence[Candidate], n_draws: int = DEFAULT_DRAWS,
               n_truths: int = DEFAULT_TRUTHS, seed: int = 0, method: str = "auto", cutting=None,
               growth_replicates: int = GROWTH_REPLICATES) -> DesignResult:
    """:func:`design_from_draws` for a ``posterior.nc`` and its setup (posterior mode of ``bayes-rcsa design``).

    ``growth_replicates``: for a single-length posterior, each of the ``n_draws`` draws is combined with this
    many independent growth-prior draws (see the comment in the code).
    """
    from ..inference.problem import IdentificationOptions

    attrs = posterior_attributes(posterior_path)
    draws = load_posterior(posterior_path, setup)
    opts = IdentificationOptions.from_setup(setup.extra)
    rng_sub, rng_growth, rng_design = np.random.default_rng(seed).spawn(3)
    draws = draws.subset(n_draws, rng_sub)
    feasible = feasible_growth_law(setup, attrs)
    if needs_growth_prior(draws, feasible) and growth_replicates > 1:
        # In the current posterior the growth factors are independent of everything else (their prior), so
        # each posterior draw combined with several growth draws is still a draw from it.  The first test at
        # a new length pins the growth ~100 times tighter than its prior; without the replicates the
        # importance weights would collapse onto a handful of draws.
        draws = draws.take(np.repeat(np.arange(draws.n_draws), growth_replicates))
    draws = with_growth_prior(draws, feasible, rng_growth, setup.extra.get("priors"))
    if "tempering" not in attrs:
        raise DataError(f"{posterior_path}: attribute 'tempering' missing (rerun 'bayes-rcsa identify')")
    noise = noise_level(draws, opts.noise_floor, float(attrs["tempering"]))
    return design_from_draws(setup, draws, target, candidates, noise, rng_design, n_truths, method, cutting,
                             {"ratio": opts.band_ratio, "rel_height": opts.band_rel_height})


# -- no-data planning -----------------------------------------------------------


@dataclass(frozen=True)
class PlanningResult:
    pairs: tuple  # ((l1, l2), WidthEstimate), best first
    prior_width: float
    target_lengths: np.ndarray
    candidate_lengths: np.ndarray
    noise: E.NoiseLevel
    n_truths: int
    direction: str
    notes: tuple = ()

    def as_dict(self) -> dict:
        (l1, l2), best = self.pairs[0]

        def label(a, b):
            return f"{self.direction} {a * 1e3:.4g} mm + {self.direction} {b * 1e3:.4g} mm"

        return {
            "mode": "prior",
            "target": (f"transfer uncertainty: 90 % width of the dominant natural frequency (direction "
                       f"{self.direction}) averaged over clamping lengths {[round(v * 1e3, 4) for v in self.target_lengths]} mm"),
            "unit": "Hz",
            "current_width": self.prior_width,
            "candidates": [{"test": label(a, b), "clamping_lengths": [a, b], "clamping_length": b,
                            "expected_width": e.expected_width, "mc_error": e.mc_error, "method": e.method}
                           for (a, b), e in self.pairs],
            "best": {"test": label(l1, l2), "clamping_lengths": [l1, l2], "clamping_length": l2,
                     "expected_width": best.expected_width, "mc_error": best.mc_error},
            "candidate_lengths": list(map(float, self.candidate_lengths)),
            "method": {"estimator": "Laplace/Fisher approximation at prior draws (two tests, Gaussian prior "
                                    "approximation in sampling coordinates)", "simulated_measurements": self.n_truths},
            "noise": {"relative_scale": self.noise.scale, "floor": self.noise.floor, "tempering": self.noise.tempering},
            "notes": list(self.notes),
        }


def run_planning(setup, candidate_lengths: Sequence[float] | None = None, n_truths: int = DEFAULT_TRUTHS,
                 seed: int = 0, noise_scale: float = PLANNING_NOISE, tempering: float = PLANNING_TEMPERING,
                 n_target_lengths: int = 7) -> PlanningResult:
    """Which two clamping lengths minimise the expected transfer uncertainty over the feasible range (no data yet).

    Parameters
    ----------
    setup : Setup
        Its ``[contact]`` priors and feasible range, ``[priors]``, ``[model]``.
    candidate_lengths : sequence of float, m, optional
        Default: 7 lengths evenly over the feasible range.
    n_truths : int
        Prior draws at which the Fisher information is evaluated.
    noise_scale, tempering : float
        Relative noise and likelihood power assumed for the future tests.
    n_target_lengths : int
        Lengths over the feasible range at which the width is averaged.

    Raises
    ------
    SetupError
        No feasible clamping range, fewer than two candidate lengths.
    """
    from ..inference.problem import IdentificationOptions, build_parameter_model

    growth = feasible_growth_law(setup)
    if growth is None or not growth.has_growth:
        raise SetupError(f"{getattr(setup, 'path', 'setup')}: [contact] clamping_range must span a range "
                         f"(l_a < l_b) to plan two clamping lengths")
    lengths = (np.linspace(growth.l_a, growth.l_b, 7) if candidate_lengths is None
               else np.array(sorted(set(float(v) for v in candidate_lengths))))
    growth.check_lengths(lengths, "--candidates length")
    if lengths.size < 2:
        raise SetupError("--candidates: the no-data mode needs at least two distinct clamping lengths")
    opts = IdentificationOptions.from_setup(setup.extra)
    model = setup.model()
    pm = build_parameter_model(model, setup.contact, growth, opts, 1)
    direction, tool = design_direction(setup), design_tool(setup)
    noise = E.NoiseLevel(float(noise_scale), opts.noise_floor, float(tempering))
    rng = np.random.default_rng(seed)
    names = list(pm.physical_names)
    n_prior = 20000
    theta = pm.priors.sample(rng, n_prior)
    values = pm.values(theta)
    u_all = E.sampling_coordinates(pm, values, names)
    cov = np.atleast_2d(np.cov(u_all, rowvar=False))
    sd = np.sqrt(np.diag(cov))
    step, step_t = FD_STEP * sd, FD_STEP_TARGET * sd
    bounds = np.array([pm.priors[n].bounds for n in names], dtype=float)
    f = frequency_lines(setup, direction)
    targets = np.linspace(growth.l_a, growth.l_b, n_target_lengths)
    fwd_t = ForwardModel(pm, ConfigurationStack([model.precompute(Configuration(float(l), direction, tool), f)
                                                 for l in targets]), model)
    idx = rng.choice(n_prior, min(4 * n_truths, n_prior), replace=False)
    # prior draws whose dominant mode lies inside the grid at every target length
    h0 = fwd_t.frf({k: v[idx] for k, v in values.items()}).reshape(idx.size, targets.size, f.size)
    fn0 = natural_frequency(f, h0)
    keep = idx[np.all(np.isfinite(fn0), axis=1)][:n_truths]
    notes = [f"{idx.size - np.count_nonzero(np.all(np.isfinite(fn0), axis=1))} of {idx.size} screened prior draws "
             f"have their dominant mode on the edge of the {f[0]:g}-{f[-1]:g} Hz grid at some length and were skipped"]
    if keep.size < 10:
        raise SetupError("fewer than 10 prior draws have a resonance inside the frequency grid at every clamping "
                         "length; the priors or the frequency range do not fit together")
    u = u_all[keep]
    rep = np.repeat(keep, 2 * len(names))

    def target_fn(uu):
        h = fwd_t.frf(E.with_sampling_coordinates(pm, values, names, uu, rep))
        return natural_frequency(f, h.reshape(uu.shape[0], targets.size, f.size))

    grad = np.nan_to_num(E.finite_difference_jacobian(target_fn, u, step_t))  # (M, K, p)
    jacs, weights = [], []
    for length in lengths:  # candidate lengths, not draws
        fwd = ForwardModel(pm, ConfigurationStack([model.precompute(Configuration(float(length), direction, tool), f)]),
                           model)
        h = fwd.frf({k: v[keep] for k, v in values.items()})
        jac = E.finite_difference_jacobian(lambda uu: fwd.frf(E.with_sampling_coordinates(pm, values, names, uu, rep)),
                                           u, step)
        # the default band rule around each draw's dominant peak (ratio 1.25)
        fd = f[np.argmax(np.abs(h), axis=1)]
        inband = (f[None, :] >= fd[:, None] / opts.band_ratio) & (f[None, :] <= fd[:, None] * opts.band_ratio)
        floor2 = (noise.floor * np.max(np.abs(h), axis=1, keepdims=True)) ** 2
        weights.append(inband / (noise.scale**2 * (np.abs(h) ** 2 + floor2)))
        jacs.append(jac)
    prior_width = E.laplace_current_width(grad, cov)
    pairs = []
    for i, j in itertools.combinations(range(lengths.size), 2):
        est = E.laplace_widths([jacs[i], jacs[j]], grad, cov, [weights[i], weights[j]], [tempering, tempering],
                               u, bounds, np.random.default_rng([seed, i, j]))
        pairs.append(((float(lengths[i]), float(lengths[j])), est))
    pairs.sort(key=lambda p: p[1].expected_width)
    return PlanningResult(tuple(pairs), prior_width, targets, lengths, noise, int(keep.size), direction, tuple(notes))
