"""Global optimum, walker initialisation and the one emcee driver of the package.

:func:`run_ensemble` is the only place where :class:`emcee.EnsembleSampler`
is built: identify (:mod:`.identify`), the tool library's stage 2 and joint
check (:mod:`bayes_rcsa.library.hierarchy`, :mod:`bayes_rcsa.library.joint`)
and the MCMC fallback of the cut update (:mod:`bayes_rcsa.cuts.mcmc`) all run
through it, with one burn-in rule, one convergence rule and the same
reported diagnostics.

Determinism without global seeding
----------------------------------
Everything random takes an explicit :class:`numpy.random.Generator`.
emcee 3 draws its proposals from a private ``numpy.random.RandomState``;
:func:`run_ensemble` seeds it with an integer drawn from the caller's
Generator and hands it to emcee as the ``random_state`` of the initial
:class:`emcee.State` (emcee then calls ``set_state`` on its own generator,
never touching numpy's global one).  The same seed therefore gives the same
chain bit for bit, and the generator state saved with every checkpoint
batch makes a resumed run continue exactly as the uninterrupted one would.

Two modes
---------
*converge* (``SamplerSettings.n_steps = None``, identify's and stage 2's):
the run stops at the first check at which it is converged, or at
``max_steps`` (then reported as not converged).  Checks are at steps
``check_every, 2 check_every, ...``, spaced out so that each is at least
10 % further than the previous one (the checks cost O(N) each; the schedule
depends only on the absolute step number, so that a resumed run checks at
the same places).

*fixed-steps* (``n_steps`` given, the cut update's and the library joint
check's): exactly ``n_steps`` steps are run; the autocorrelation time is
recorded at the same schedule, and at the last step the convergence rule
below is evaluated once and reported (converged or not, with the reason),
never assumed.

Burn-in rule
------------
``burn = ceil(3 max tau)`` steps, at most half the chain; in fixed-steps
mode a caller may fix it instead (``n_burn``, e.g. to keep a set number of
draws), and then ``burn = n_burn``.  The samples kept are thinned by
``thin = max(1, floor(min tau / 2))`` (:func:`burn_and_thin`).

Convergence rule
----------------
``tau`` is the integrated autocorrelation time of each parameter, estimated
from the whole chain (emcee's estimator, :func:`_tau`).  A run is converged
iff

* ``tau`` is finite and the chain is longer than ``tau_factor`` (50) times
  the largest ``tau`` (a shorter chain cannot measure its ``tau``),
* the burn-in is at least ``3 max tau`` (implied by the previous point in
  converge mode; a fixed ``n_burn`` must satisfy it),
* every ``tau`` changed by less than ``tau_rtol`` since the previous check
  (a fixed-steps run compares its last step with the last scheduled check
  before it; without one it is not converged),
* after the burn-in and thinning by ``thin``, the rank-normalised split
  R-hat (walkers as chains) is below ``rhat_max`` and the bulk ESS at least
  ``ess_min`` for every parameter (computed by :mod:`.diagnostics`;
  thinning by half the smallest tau leaves the ESS essentially unchanged
  and makes the check cheap).  A converge-mode run without ``diagnose``
  skips this point (a burn-in run); a fixed-steps run always computes it.

With ``store_every = k > 1`` only every k-th step is kept in memory; the
chain, ``tau``, ``burn`` and ``thin`` of the result are then in kept rows
(multiply by k for steps).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from ..errors import ConvergenceError, SetupError
from .checkpoint import Checkpoint, CheckpointState
from .posterior import LogPosterior
from .search import derivatives

__all__ = [
    "SamplerSettings",
    "LogDensity",
    "ChainResult",
    "Optimum",
    "find_optimum",
    "initial_ensemble",
    "run_ensemble",
    "burn_and_thin",
    "check_schedule",
    "MOVES",
    "default_moves",
    "snooker_move",
]


MOVES = ("differential", "stretch")


@dataclass(frozen=True)
class SamplerSettings:
    """Options of the ensemble run (defaults suit identify with up to about 8 parameters).

    Attributes
    ----------
    n_walkers : int
        Even, at least ``2 * ndim + 2``; ``None`` picks ``max(32, 4 ndim)``.
    max_steps : int
        Converge mode: cap on the number of steps (not converged if reached).
    check_every : int
        Steps between convergence checks (spaced out by :func:`check_schedule`).
    tau_factor : float
        Required chain length in units of the largest autocorrelation time.
    tau_rtol : float
        Required relative stability of tau between two checks.
    rhat_max, ess_min : float
        Required R-hat and bulk ESS of every parameter.
    checkpoint_interval : float
        Seconds between checkpoint writes.
    progress : bool
        Progress line on stderr.
    snooker_fraction : float
        Probability of a snooker move (:func:`snooker_move`; the rest are DEMoves) of the
        ``"differential"`` moves.
    n_steps : int or None
        ``None``: converge mode.  A number: fixed-steps mode, exactly this many steps (burn-in included).
    n_burn : int
        Fixed-steps mode only: the burn-in in steps, fixed by the caller; 0 applies the tau rule
        (module docstring).
    store_every : int
        Keep every k-th step in memory (bounds the memory of long chains; no checkpoint then).
    move : {"differential", "stretch"}
        emcee's moves: differential evolution with ``snooker_fraction`` snooker moves, or the stretch move.
    """

    n_walkers: int | None = None
    max_steps: int = 20000
    check_every: int = 250
    tau_factor: float = 50.0
    tau_rtol: float = 0.05
    rhat_max: float = 1.01
    ess_min: float = 400.0
    checkpoint_interval: float = 2.0
    progress: bool = True
    snooker_fraction: float = 0.2
    n_steps: int | None = None
    n_burn: int = 0
    store_every: int = 1
    move: str = "differential"

    def walkers(self, ndim: int) -> int:
        n = self.n_walkers if self.n_walkers is not None else max(32, 4 * ndim)
        if n < 2 * ndim + 2 or n % 2:
            raise SetupError(f"n_walkers = {n}: expected an even number >= {2 * ndim + 2} for {ndim} parameters")
        return n

    @property
    def fixed(self) -> bool:
        """Fixed-steps mode (``n_steps`` given)."""
        return self.n_steps is not None

    @property
    def total_steps(self) -> int:
        """Steps of a complete run: ``n_steps`` (fixed-steps mode) or the cap ``max_steps``."""
        return self.n_steps if self.n_steps is not None else self.max_steps

    def __post_init__(self) -> None:
        if self.max_steps < 1 or self.check_every < 1:
            raise SetupError(f"max_steps = {self.max_steps}, check_every = {self.check_every}: expected positive integers")
        if self.n_steps is not None and self.n_steps < 2:
            raise SetupError(f"n_steps = {self.n_steps}: expected an integer >= 2 (or None to run until converged)")
        if self.n_burn < 0 or (self.n_burn and (self.n_steps is None or self.n_burn >= self.n_steps)):
            raise SetupError(f"n_burn = {self.n_burn}: expected 0, or a number of steps below n_steps = "
                             f"{self.n_steps} (fixed-steps mode only)")
        if self.store_every < 1:
            raise SetupError(f"store_every = {self.store_every}: expected a positive integer")
        if self.move not in MOVES:
            raise SetupError(f"move = {self.move!r}: expected one of {MOVES}")


class LogDensity(Protocol):
    """What :func:`run_ensemble` samples: a :class:`.posterior.LogPosterior`, or another vectorised density
    (e.g. the coupled stage-2 hyperparameters of a tool library, :mod:`bayes_rcsa.library.hierarchy`).

    Attributes
    ----------
    ndim : int, sampling coordinates
    """

    ndim: int

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        """(n,) unnormalised log density of theta (n, ndim); ``-inf`` outside the support."""

    def check_inside(self, theta: np.ndarray, what: str) -> None:
        """Raise :class:`SetupError` naming the first row of theta (n, ndim) outside the support."""


@dataclass(frozen=True)
class Optimum:
    """Result of the global optimisation of the log posterior.

    Attributes
    ----------
    x : (ndim,) sampling coordinates of the optimum
    log_posterior : float
    n_evaluations : int
    success : bool
    message : str
    """

    x: np.ndarray
    log_posterior: float
    n_evaluations: int
    success: bool
    message: str


@dataclass(frozen=True)
class ChainResult:
    """Output of :func:`run_ensemble`.

    Attributes
    ----------
    chain : (n_steps, n_walkers, ndim) all stored steps (sampling coordinates)
    log_prob : (n_steps, n_walkers)
    accepted : (n_walkers,) accepted proposals
    tau : (ndim,) integrated autocorrelation times at the end (steps)
    converged : bool
    reason : str
        Why the run stopped.
    burn, thin : int
    diagnostics : dict
        ``{"rhat": (ndim,), "ess_bulk": (ndim,), "ess_tail": (ndim,)}`` of
        the kept part (may be empty if too short to compute).
    tau_history : list of (step, max tau)
    wall_time : float
        Seconds spent sampling in this process.
    n_new_steps : int
        Steps computed in this process (the rest came from the checkpoint).
    store_every : int
        Steps per stored row (``SamplerSettings.store_every``); chain, tau, burn and thin are in rows.
    steps_run : int
        Steps run in total (``n_steps`` when every step is stored).
    """

    chain: np.ndarray
    log_prob: np.ndarray
    accepted: np.ndarray
    tau: np.ndarray
    converged: bool
    reason: str
    burn: int
    thin: int
    diagnostics: dict
    tau_history: list = field(default_factory=list)
    wall_time: float = 0.0
    n_new_steps: int = 0
    store_every: int = 1
    steps_run: int | None = None

    @property
    def n_steps(self) -> int:
        """Stored rows of the chain (steps when ``store_every`` is 1)."""
        return int(self.chain.shape[0])

    @property
    def acceptance_fraction(self) -> np.ndarray:
        """(n_walkers,) accepted proposals per step."""
        return self.accepted / max(self.n_steps if self.steps_run is None else self.steps_run, 1)


# -- optimisation and start ------------------------------------------------


def find_optimum(log_post: LogPosterior, n_candidates: int = 3, max_lines: int = 64) -> Optimum:
    """Global maximum of the log posterior: likelihood grid, then L-BFGS-B polish.

    See :mod:`.search` for why a grid over the stiffness (and growth) is used
    instead of a population optimiser.  The best ``n_candidates``
    well-separated grid points are polished; the best result wins.

    The grid's fast path weights the residuals by the *measured* ``|H|``, a
    proxy for the likelihood's model variance that holds only while the
    noise is small against the signal.  When a noise scale at the polished
    optimum exceeds :data:`.search.EXACT_PROFILE_NOISE` (a relative noise
    of 0.1), the grid is searched again with the likelihood's own profile
    (:func:`.search.grid_candidates` with ``exact=True``), its best points
    are polished too, and the best of all wins: with noise as large as the
    signal the data-weighted grid ranks a wrong resonance (a far softer or
    stiffer contact with a larger noise scale) first, 40-300 log units
    below the mode that generated the data (simulation-based calibration,
    docs/calibration.md).  When the noise scale stays above that limit and
    the model samples a term's parameters (a tip mass), the grid is also
    searched with those parameters at their prior's 10, 50 and 90 % points
    (:func:`.search.term_levels`) and the best of those candidates are
    polished.

    Parameters
    ----------
    log_post : LogPosterior
        Untempered.
    n_candidates : int
    max_lines : int
        Lines per measurement in the grid stage.
    """
    from .search import EXACT_PROFILE_NOISE, grid_candidates, optimum_noise_scale, polish, term_levels

    n0 = log_post.n_evaluations
    bounds = log_post.priors.optimisation_bounds()
    best_x, best_v = None, -np.inf
    for x0 in grid_candidates(log_post.likelihood, log_post.priors, max_lines, n_candidates):
        x, v = polish(log_post, x0, bounds)
        if v > best_v:
            best_x, best_v = x, v
    if best_x is None or not np.isfinite(best_v):
        raise ConvergenceError("the optimiser found no point with a finite posterior density")
    message = f"grid search + L-BFGS-B polish of {n_candidates} candidates"
    noise = optimum_noise_scale(log_post, best_x)
    if noise > EXACT_PROFILE_NOISE:
        for x0 in grid_candidates(log_post.likelihood, log_post.priors, max_lines, n_candidates, exact=True):
            x, v = polish(log_post, x0, bounds)
            if v > best_v:
                best_x, best_v = x, v
        message += (f"; noise scale {noise:.2g} > {EXACT_PROFILE_NOISE:g}: grid searched again with the "
                    f"likelihood's own profile, {n_candidates} more candidates polished")
        noise = optimum_noise_scale(log_post, best_x)
        levels = term_levels(log_post.likelihood, log_post.priors) if noise > EXACT_PROFILE_NOISE else []
        if levels:
            cands = np.array([x0 for held in levels for x0 in grid_candidates(
                log_post.likelihood, log_post.priors, max_lines, n_candidates, held_values=held)])
            values = np.asarray(log_post(cands), dtype=float)
            for j in np.argsort(-values)[:n_candidates]:
                x, v = polish(log_post, cands[j], bounds)
                if v > best_v:
                    best_x, best_v = x, v
            message += (f"; still {noise:.2g}: grid searched at {len(levels)} levels of the model terms' "
                        f"parameters, the best {min(n_candidates, len(cands))} polished")
    return Optimum(best_x, float(best_v), log_post.n_evaluations - n0, True, message)


def initial_ensemble(log_post: LogPosterior, x0: np.ndarray, rng: np.random.Generator, n_walkers: int) -> np.ndarray:
    """Walkers spread around ``x0`` by the local (Laplace) covariance of the posterior.

    The covariance is the inverse finite-difference Hessian of ``-log_post``
    at ``x0``.  Where the Hessian is not positive definite (the optimum on
    a prior bound, a flat direction), the spread in each coordinate falls
    back to ``1/sqrt(H_ii)``, and each standard deviation is kept within
    ``[1e-4, 0.1]`` times the prior width so that the ball neither collapses
    nor spills over the whole prior.  Draws outside the support (or with a
    non-finite posterior) are redrawn.

    Returns
    -------
    (n_walkers, ndim)
    """
    nd = x0.size
    lo, hi = np.array(log_post.priors.optimisation_bounds()).T
    width = hi - lo
    step = 1e-4 * width
    # stay inside the support for the finite differences
    x_fd = np.clip(x0, lo + 2 * step, hi - 2 * step)
    _, _, h = derivatives(log_post, x_fd, step)
    cov = None
    if np.all(np.isfinite(h)):
        try:
            np.linalg.cholesky(h)
            cov = np.linalg.inv(h)
        except np.linalg.LinAlgError:
            cov = None
    sd_lo, sd_hi = 1e-4 * width, 0.1 * width
    if cov is None:
        diag = np.diag(h) if np.all(np.isfinite(h)) else np.full(nd, np.nan)
        with np.errstate(divide="ignore", invalid="ignore"):
            sd = np.where(diag > 0, 1.0 / np.sqrt(diag), sd_hi)
        sd = np.clip(sd, sd_lo, sd_hi)
        cov = np.diag(sd**2)
    else:
        sd = np.sqrt(np.diag(cov))
        scale = np.clip(sd, sd_lo, sd_hi) / sd
        cov = cov * np.outer(scale, scale)
    chol = np.linalg.cholesky(cov + np.diag((1e-12 * width) ** 2))
    out = np.empty((0, nd))
    for _ in range(100):
        z = x0 + rng.standard_normal((2 * n_walkers, nd)) @ chol.T
        ok = np.isfinite(log_post(z))
        out = np.vstack([out, z[ok]])
        if out.shape[0] >= n_walkers:
            return out[:n_walkers]
    raise ConvergenceError(
        f"could not place {n_walkers} walkers with finite posterior around the optimum {x0.tolist()}"
    )


# -- running ---------------------------------------------------------------


def check_schedule(check_every: int, max_steps: int) -> set[int]:
    """Steps at which convergence is checked: multiples of ``check_every``, each >= 1.1 x the previous."""
    out, step = set(), check_every
    while step <= max_steps:
        out.add(step)
        step = max(step + check_every, check_every * math.ceil(1.1 * step / check_every))
    return out


def burn_and_thin(tau: np.ndarray, n_steps: int, n_burn: int = 0) -> tuple[int, int]:
    """The burn-in rule of the module docstring and the thinning ``max(1, floor(min tau / 2))``.

    Parameters
    ----------
    tau : (ndim,) autocorrelation times (steps, or rows of a chain stored every k steps)
    n_steps : int, length of the chain (same unit)
    n_burn : int, a burn-in fixed by the caller (same unit); 0 for ``ceil(3 max tau)`` bounded by half the chain

    Returns
    -------
    burn, thin : int
    """
    tau = np.asarray(tau, dtype=float)
    if not np.all(np.isfinite(tau)):
        return (n_burn if n_burn > 0 else n_steps // 2), 1
    burn = n_burn if n_burn > 0 else min(int(math.ceil(3 * tau.max())), n_steps // 2)
    thin = max(1, int(tau.min() // 2))
    return burn, thin


def _tau(chain: np.ndarray, c: float = 5.0) -> np.ndarray:
    """Integrated autocorrelation time of every parameter, (ndim,) steps.

    The estimator of :func:`emcee.autocorr.integrated_time` (autocorrelation
    function averaged over walkers, Sokal's window with ``c = 5``), computed
    with one batched FFT over all walkers and parameters instead of one per
    walker and parameter (emcee's loop dominated the convergence checks).
    """
    n, nw, nd = chain.shape
    if n < 2:
        return np.full(nd, np.nan)
    x = chain - chain.mean(axis=0, keepdims=True)
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    # the transforms along the contiguous last axis (about 40 % faster than along the chain's step axis, the same
    # numbers: each 1-D transform is computed alike), then back to (n, nw, nd) for the walker mean, whose summation
    # order depends on the layout
    f = np.fft.rfft(np.ascontiguousarray(np.moveaxis(x, 0, -1)), n=nfft, axis=-1)  # (nw, nd, nfft // 2 + 1)
    # f * conj(f), not in place: numpy's in-place complex product rounds differently
    acf = np.ascontiguousarray(np.moveaxis(np.fft.irfft(f * np.conj(f), n=nfft, axis=-1)[..., :n], -1, 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        acf = acf / acf[0:1]
        # a stuck walker's acf is 0 / 0: nanmean leaves it out; without one, mean gives the same sums faster
        rho = np.nanmean(acf, axis=1) if np.isnan(acf).any() else np.mean(acf, axis=1)  # (n, nd)
    taus = 2.0 * np.cumsum(rho, axis=0) - 1.0
    out = np.empty(nd)
    m = np.arange(n)
    for j in range(nd):
        window = m < c * taus[:, j]
        k = int(np.argmin(window)) if not np.all(window) else n - 1
        out[j] = taus[k, j]
    return out


class _Progress:
    """A minimal progress line on stderr (no dependency on tqdm).

    On a terminal the line is redrawn in place (carriage return) at most every 0.25 s and at every convergence
    check.  On any other stream (a log file, a pipe) nothing is written while sampling; :meth:`close` writes the
    last state as one line, the same rule as :class:`bayes_rcsa.io.progress.Heartbeat` (a log of a 20000-step
    run held 80 ``sampling [###---]`` lines before).
    """

    def __init__(self, enabled: bool, total: int, stream=None):
        self.enabled = enabled
        self.total = total
        self.stream = sys.stderr if stream is None else stream
        try:
            self.tty = enabled and bool(self.stream.isatty())
        except (AttributeError, ValueError, OSError):
            self.tty = False
        self.last = 0.0
        self.line = ""

    def update(self, step: int, extra: str = "", force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and (not self.tty or now - self.last < 0.25):
            return
        self.last = now
        frac = step / self.total
        bar = "#" * int(30 * frac) + "-" * (30 - int(30 * frac))
        self.line = f"sampling [{bar}] {step}/{self.total} {extra}".rstrip()
        if self.tty:
            self.stream.write("\r" + self.line[:120].ljust(120))
            self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write("\n")
            self.stream.flush()
        elif self.enabled and self.line:
            self.stream.write(self.line + "\n")  # not a terminal: the final state, once
            self.stream.flush()


@dataclass
class _Start:
    """Where a run starts: walker positions, their log posterior, emcee's generator state, stored steps."""

    coords: np.ndarray
    log_prob: np.ndarray
    random_state: tuple
    done: int
    chain: np.ndarray
    chain_log_prob: np.ndarray
    accepted: np.ndarray


def _start(log_post: LogDensity, initial, rng, resume_state) -> _Start:
    """Step 1: the state to start from, new (checked walkers, seeded proposal generator) or resumed."""
    nd = log_post.ndim
    if resume_state is not None and resume_state.iteration > 0:
        return _Start(resume_state.chain[-1], resume_state.log_prob[-1], resume_state.random_state,
                      resume_state.iteration, resume_state.chain, resume_state.log_prob,
                      resume_state.accepted.astype(float).copy())
    if initial is None or rng is None:
        raise SetupError("a new run needs initial walker positions and a random generator")
    coords0 = np.asarray(initial, dtype=float)
    log_post.check_inside(coords0, "walker start")
    lp0 = log_post(coords0)
    if not np.all(np.isfinite(lp0)):
        i = int(np.argmax(~np.isfinite(lp0)))
        raise SetupError(f"walker start {i} has a non-finite log posterior ({lp0[i]!r})")
    if coords0.ndim != 2 or coords0.shape[1] != nd:
        raise SetupError(f"walker positions have shape {coords0.shape}, expected (n_walkers, {nd})")
    from emcee.ensemble import walkers_independent

    if not walkers_independent(coords0):
        raise SetupError("the walker starts are not linearly independent (a degenerate initial ensemble)")
    rstate = np.random.RandomState(int(rng.integers(0, 2**32 - 1))).get_state()
    n_walkers = coords0.shape[0]
    return _Start(coords0, lp0, rstate, 0, np.empty((0, n_walkers, nd)), np.empty((0, n_walkers)), np.zeros(n_walkers))


class _Convergence:
    """Step 2: the convergence rule of the module docstring, evaluated at the scheduled steps (converge mode,
    :meth:`__call__`) or once at the last step (fixed-steps mode, :meth:`final`)."""

    def __init__(self, settings: SamplerSettings, diagnose):
        self.settings = settings
        self.diagnose = diagnose
        self.last_diag = 0
        # a fixed burn-in in stored rows: those of the stored steps at or before step n_burn
        k, p = settings.store_every, _store_phase(settings) or settings.store_every
        self.n_burn = (settings.n_burn - p) // k + 1 if settings.n_burn >= p else 0

    def _length_and_burn(self, tau: np.ndarray, n: int) -> tuple[bool, bool, int, int]:
        burn, thin = burn_and_thin(tau, n, self.n_burn)
        finite = bool(np.all(np.isfinite(tau)))
        ok_len = finite and n > self.settings.tau_factor * tau.max()
        ok_burn = finite and burn >= math.ceil(3 * tau.max())
        return ok_len, ok_burn, burn, thin

    def _stable(self, tau: np.ndarray, prev_tau) -> bool:
        return prev_tau is not None and bool(np.all(np.abs(tau - prev_tau) < self.settings.tau_rtol * tau))

    def _passes(self, diag: dict) -> bool:
        s = self.settings
        return bool(np.all(diag["rhat"] < s.rhat_max) and np.all(diag["ess_bulk"] >= s.ess_min))

    def __call__(self, chain_now: np.ndarray, prev_tau):
        n = chain_now.shape[0]
        tau = _tau(chain_now)
        ok_len, ok_burn, burn, thin = self._length_and_burn(tau, n)
        ok_stable = self._stable(tau, prev_tau)
        diag = {}
        ok_diag = False
        # R-hat/ESS cost grows with the chain: evaluate them on the tau-thinned chain, and again
        # only once the chain has grown by 10 % (they cannot change much in between).
        if ok_len and ok_stable and n >= 1.1 * self.last_diag:
            self.last_diag = n
            if self.diagnose is None:
                ok_diag = True
            else:
                diag = self.diagnose(chain_now[burn::thin])
                ok_diag = self._passes(diag)
        return tau, bool(ok_len and ok_burn and ok_stable and ok_diag), diag

    def final(self, chain: np.ndarray, prev_tau, prev_step: int | None) -> tuple[np.ndarray, bool, dict, list[str]]:
        """Every criterion at the end of a fixed-steps run, R-hat and ESS always computed.

        Returns
        -------
        tau, converged, diagnostics, failures (one phrase per criterion not met, in steps)
        """
        s, k = self.settings, self.settings.store_every
        n = chain.shape[0]
        steps = s.total_steps if k > 1 else n
        tau = _tau(chain)
        ok_len, ok_burn, burn, thin = self._length_and_burn(tau, n)
        failures = []
        if not np.all(np.isfinite(tau)):
            failures.append("the autocorrelation time could not be estimated")
        else:
            if not ok_len:
                failures.append(f"the chain of {steps} steps is not longer than {s.tau_factor:g} autocorrelation "
                                f"times ({s.tau_factor * tau.max() * k:.0f} steps): too short to measure tau")
            if not ok_burn:
                failures.append(f"the burn-in of {s.n_burn or burn * k} steps is shorter than 3 autocorrelation times "
                                f"({3 * tau.max() * k:.0f} steps)")
        if prev_tau is None:
            failures.append("no earlier check to compare tau with (check_every >= n_steps)")
        elif not self._stable(tau, prev_tau):
            failures.append(f"tau changed by more than {100 * s.tau_rtol:g} % since step {prev_step}")
        diag: dict = {}
        if (n - burn) // thin >= 4:
            diagnose = self.diagnose
            if diagnose is None:
                from .diagnostics import chain_diagnostics as diagnose
            diag = diagnose(chain[burn::thin])
            if not np.all(diag["rhat"] < s.rhat_max):
                failures.append(f"R-hat {float(np.max(diag['rhat'])):.4f} >= {s.rhat_max:g}")
            if not np.all(diag["ess_bulk"] >= s.ess_min):
                failures.append(f"bulk ESS {float(np.min(diag['ess_bulk'])):.0f} < {s.ess_min:g}")
        else:
            failures.append("fewer than 4 kept draws per walker for R-hat and ESS")
        return tau, not failures, diag, failures


def _replay(start: _Start, settings: SamplerSettings, decide: _Convergence, schedule: set[int]):
    """Step 3 (resumed runs): the tau history of the checks already passed, and whether the run had converged."""
    chain, done = start.chain, start.done
    tau_history: list = []
    prev_tau = None
    for step in sorted(x for x in schedule if x <= done):
        prev_tau = _tau(chain[:step])
        tau_history.append((step, float(prev_tau.max())))
    converged, reason, diag = False, "", {}
    if settings.fixed:
        return tau_history, prev_tau, converged, reason, diag  # decided at the last step
    if done >= settings.max_steps:
        reason = f"max_steps = {settings.max_steps} reached (checkpoint has {done} steps)"
    elif tau_history:
        # a previous process may have stopped at a converged check
        _, converged, diag = decide(chain[: tau_history[-1][0]],
                                    _tau(chain[: tau_history[-2][0]]) if len(tau_history) > 1 else None)
        if converged and tau_history[-1][0] == done:
            reason = "converged (found in checkpoint)"
        else:
            converged = False
    return tau_history, prev_tau, converged, reason, diag


def _store_phase(settings: SamplerSettings) -> int:
    """Stored steps are those ``step % store_every == phase``: a fixed-steps run stores its last step (and so,
    after a fixed burn-in of ``n_burn`` and ``n x store_every`` more steps, every ``store_every``-th step after
    the burn-in)."""
    return settings.total_steps % settings.store_every if settings.fixed else 0


_BATCHED: dict = {}  # emcee move class -> its _batched subclass (one per class of emcee's moves used here)


def _batched(base):
    """``base``, an emcee ``RedBlueMove`` class, with the accept step of a walker subset done in one call.

    emcee's ``RedBlueMove.propose`` accepts walker by walker, ``f + lp_new - lp_old > log(random.rand())`` in a
    Python loop (16-32 scalar draws and logarithms a step, about a third of a step's cost outside the density on
    the test problems).  Here the subset's uniforms are one ``random.rand(n)`` at the same point of the stream
    (the same doubles in the same order as n calls of ``rand()``) and the comparisons one array operation (the
    same float64 sums and logarithms), so the chain is the one emcee's own ``propose`` draws, bit for bit
    (tests/test_inference_fastpaths.py).  The rest of the step is emcee's, unchanged: splits, proposal, update.
    """
    cls = _BATCHED.get(base)
    if cls is None:
        from emcee import State

        class _Batched(base):
            def propose(self, model, state):
                nwalkers, ndim = state.coords.shape
                if nwalkers < 2 * ndim and not self.live_dangerously:
                    raise RuntimeError("It is unadvisable to use a red-blue move with fewer walkers than twice the "
                                       "number of dimensions.")
                self.setup(state.coords)
                accepted = np.zeros(nwalkers, dtype=bool)
                inds = np.arange(nwalkers) % self.nsplits
                if self.randomize_split:
                    model.random.shuffle(inds)
                for split in range(self.nsplits):
                    subset = inds == split
                    sets = [state.coords[inds == j] for j in range(self.nsplits)]
                    q, factors = self.get_proposal(sets[split], sets[:split] + sets[split + 1:], model.random)
                    new_log_probs, new_blobs = model.compute_log_prob_fn(q)
                    lnpdiff = factors + new_log_probs - state.log_prob[subset]
                    accepted[subset] = lnpdiff > np.log(model.random.rand(lnpdiff.size))
                    state = self.update(state, State(q, log_prob=new_log_probs, blobs=new_blobs), accepted, subset)
                return state, accepted

        _Batched.__name__ = _Batched.__qualname__ = base.__name__
        cls = _BATCHED[base] = _Batched
    return cls


def snooker_move(gamma: float = 1.7):
    """The differential-evolution snooker move of ter Braak & Vrugt (2008), in detailed balance.

    emcee's own :class:`emcee.moves.DESnookerMove` (up to 3.1.6) is not: it scales the direction ``x - z`` by
    ``1 / sqrt(|x - z|)`` instead of ``1 / |x - z|`` (the jump then grows with the distance from ``z``, a
    multiplicative move whose Jacobian it omits) and raises the distance ratio to ``(d - 1) / 2`` instead of
    ``d - 1`` (fixed upstream in emcee pull request 531, not released).  The chain it drives is not stationary
    on the posterior: it under-samples a long one-sided tail while R-hat, tau and ESS pass
    (``benchmarks/sampler_tail.py``, docs/identification.md "Sampler moves and the tails").  This move is the
    published one: for each walker ``x`` of the current half, ``z, z1, z2`` from the other walkers (one from each of
    three of the four splits, emcee's scheme), the jump ``gamma (z1 - z2) . e`` along the unit vector
    ``e = (x - z) / |x - z|``, accepted with the extra factor ``(|x' - z| / |x - z|)^(d - 1)``.

    Parameters
    ----------
    gamma : float, the jump's scale (1.7, the reference's value)

    Returns
    -------
    emcee.moves.RedBlueMove
    """
    from emcee.moves.red_blue import RedBlueMove

    class _Snooker(_batched(RedBlueMove)):
        def __init__(self):
            super().__init__(nsplits=4)

        def get_proposal(self, s, c, random):
            ns, nd = s.shape
            # one walker of each of the three other splits per walker, in random order
            w = np.stack([c[j][random.randint(len(c[j]), size=ns)] for j in range(3)], axis=1)  # (ns, 3, nd)
            order = np.argsort(random.rand(ns, 3), axis=1)
            w = w[np.arange(ns)[:, None], order]
            z, z1, z2 = w[:, 0], w[:, 1], w[:, 2]
            delta = s - z
            # Euclidean norms as np.linalg.norm evaluates them for real rows, without its argument handling
            norm = np.sqrt(np.add.reduce(delta * delta, axis=1))
            with np.errstate(invalid="ignore", divide="ignore"):
                e = delta / norm[:, None]
                q = s + gamma * e * np.sum(e * (z1 - z2), axis=1, keepdims=True)
                dq = q - z
                factor = (nd - 1.0) * (np.log(np.sqrt(np.add.reduce(dq * dq, axis=1))) - np.log(norm))
            bad = ~np.isfinite(factor)  # a walker on top of z: no direction, stay
            if bad.any():
                q[bad], factor[bad] = s[bad], 0.0
            return q, factor

    return _Snooker()


def default_moves(move: str = "differential", snooker_fraction: float = 0.2) -> list:
    """emcee's weighted moves of :attr:`SamplerSettings.move` (what :func:`run_ensemble` uses without ``moves``).

    ``"differential"``: :class:`emcee.moves.DEMove` with probability ``1 - snooker_fraction`` and the snooker move
    (:func:`snooker_move`, not emcee's) with ``snooker_fraction``; ``"stretch"``: the stretch move alone.  Each
    accepts a walker subset's proposals in one batched step (the chain of emcee's own ``propose``, bit for bit).
    """
    import emcee

    if move == "stretch":
        return [(_batched(emcee.moves.StretchMove)(), 1.0)]
    out = [(_batched(emcee.moves.DEMove)(), 1.0 - snooker_fraction)]
    return out + [(snooker_move(), snooker_fraction)] if snooker_fraction > 0 else out


def _moves(settings: SamplerSettings):
    """emcee's moves of ``settings.move``."""
    return default_moves(settings.move, settings.snooker_fraction)


_QUIET_SAMPLER = None


def _quiet_sampler_class():
    """:class:`emcee.EnsembleSampler` that copies its generator's state only when the driver stores it.

    emcee assigns ``state.random_state = sampler.random_state`` after every step, a ``get_state()`` copy of the
    Mersenne twister's 624 words (about 130-160 us a step, more than a third of a walker half's likelihood on
    the test problems); the driver needs the state only when it writes a checkpoint batch.  Here that property
    reads ``None`` and :meth:`exact_random_state` gives the state itself: nothing draws between emcee's
    assignment and the yield of the step, so at the yield it is the state emcee would have copied.  The draws,
    and so the chain, are emcee's own (only reading the state is skipped; setting it is emcee's setter).  Built on
    first use, as emcee is imported only when a chain runs (it imports scipy.stats).
    """
    global _QUIET_SAMPLER
    if _QUIET_SAMPLER is None:
        import emcee

        class _QuietEnsembleSampler(emcee.EnsembleSampler):
            @property
            def random_state(self):
                return None

            @random_state.setter
            def random_state(self, state):
                emcee.EnsembleSampler.random_state.fset(self, state)

            def exact_random_state(self) -> tuple:
                """The generator's state now (``numpy.random.RandomState.get_state()``)."""
                return emcee.EnsembleSampler.random_state.fget(self)

        _QUIET_SAMPLER = _QuietEnsembleSampler
    return _QUIET_SAMPLER


def run_ensemble(
    log_post: LogDensity,
    settings: SamplerSettings,
    *,
    initial: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
    checkpoint: Checkpoint | None = None,
    resume_state: CheckpointState | None = None,
    diagnose: Callable[[np.ndarray], dict] | None = None,
    moves=None,
) -> ChainResult:
    """Run emcee's EnsembleSampler until converged or ``settings.max_steps`` (converge mode), or for
    ``settings.n_steps`` steps (fixed-steps mode); the rules are those of the module docstring.

    Steps: the start state (``_start``), the convergence rule
    (``_Convergence``), the replay of a resumed run's checks (``_replay``),
    the sampling loop with batched checkpoint writes (``_sample_loop``), the
    final burn-in, thinning and diagnostics.

    Parameters
    ----------
    log_post : LogDensity
        A :class:`.posterior.LogPosterior` or any density of the :class:`LogDensity` protocol; called with
        whole walker batches (``vectorize=True``).
    settings : SamplerSettings
    initial : (n_walkers, ndim), optional
        Start of a new run; every walker must lie inside the support (``log_post.check_inside``), have a
        finite log density, and the walkers must be linearly independent (repeated rows are allowed as long
        as the distinct ones span the space).
    rng : numpy.random.Generator
        Seeds emcee's proposal generator for a new run (one integer drawn from it).
    checkpoint : Checkpoint, optional
        Where steps are appended (created beforehand by the caller); not with ``store_every > 1``.
    resume_state : CheckpointState, optional
        Continue this run instead of starting from ``initial``; a state
        with no stored step counts as a new run (``initial`` and ``rng``
        are then needed).
    diagnose : callable, optional
        ``diagnose(chain (n, n_walkers, ndim)) -> {"rhat", "ess_bulk", "ess_tail"}``.  Converge mode
        without it: only the tau criteria decide.  Fixed-steps mode: default
        :func:`.diagnostics.chain_diagnostics`.
    moves : emcee moves, optional
        emcee's ``moves`` argument, replacing those of ``settings.move``.  A resumed run must use the moves
        of the original run to continue it exactly.

    Returns
    -------
    ChainResult
        In fixed-steps mode ``converged`` and ``reason`` give the rule's verdict at the last step (the
        criteria not met, in steps), ``diagnostics`` R-hat and ESS of the kept part.

    Raises
    ------
    SetupError
        A walker start outside the support or with a non-finite log
        density, walkers that are not linearly independent, a checkpoint
        with ``store_every > 1``.
    """
    import emcee

    if settings.store_every > 1 and (checkpoint is not None or resume_state is not None):
        raise SetupError(f"store_every = {settings.store_every}: a checkpointed run stores every step")
    start = _start(log_post, initial, rng, resume_state)
    n_walkers, nd = start.coords.shape
    sampler = _quiet_sampler_class()(n_walkers, nd, log_post, moves=_moves(settings) if moves is None else moves,
                                     vectorize=True)
    decide = _Convergence(settings, diagnose)
    # fixed-steps mode: tau is recorded at the scheduled steps before the last one, which is decided after the loop
    schedule = check_schedule(settings.check_every, settings.total_steps - (1 if settings.fixed else 0))
    tau_history, prev_tau, converged, reason, diag = _replay(start, settings, decide, schedule)

    chain, log_prob, accepted = start.chain, start.chain_log_prob, start.accepted
    t0 = time.perf_counter()
    n_new = 0
    if not reason:
        chain, log_prob, accepted, n_new, converged, reason, diag, prev_tau = _sample_loop(
            sampler, start, settings, decide, schedule, checkpoint, tau_history, prev_tau)
    wall = time.perf_counter() - t0

    if settings.fixed:
        tau, converged, diag, failures = decide.final(chain, prev_tau, tau_history[-1][0] if tau_history else None)
        reason = (f"n_steps = {settings.n_steps} run: " + ("converged" if converged else
                                                             "not converged: " + "; ".join(failures)))
    elif tau_history and tau_history[-1][0] == start.done + n_new and prev_tau is not None:
        # the run stopped at a check (converged, or max_steps on a check step): the chain is the one that check
        # measured, so its tau is the same numbers (an FFT over the whole chain, not repeated)
        tau = prev_tau
    else:
        tau = _tau(chain) if chain.shape[0] > 1 else np.full(nd, np.nan)
    burn, thin = burn_and_thin(tau, chain.shape[0], decide.n_burn)
    if not converged and not settings.fixed and diagnose is not None and (chain.shape[0] - burn) // thin >= 4:
        diag = diagnose(chain[burn::thin])
    return ChainResult(
        chain=chain, log_prob=log_prob, accepted=accepted, tau=tau, converged=converged, reason=reason,
        burn=burn, thin=thin, diagnostics=diag, tau_history=tau_history, wall_time=wall, n_new_steps=n_new,
        store_every=settings.store_every, steps_run=start.done + n_new,
    )


def _sample_loop(sampler, start: _Start, settings: SamplerSettings, decide: _Convergence, schedule: set[int],
                 checkpoint: Checkpoint | None, tau_history: list, prev_tau):
    """Step 4: emcee steps until converged or ``max_steps`` (converge mode) or ``n_steps`` (fixed-steps mode);
    checkpoint batches and convergence checks (in fixed-steps mode only tau is recorded).

    Returns
    -------
    chain, log_prob, accepted, n_new, converged, reason, diag, prev_tau
    """
    import emcee

    chain, log_prob, accepted = start.chain, start.chain_log_prob, start.accepted
    done = start.done
    n_walkers = start.coords.shape[0]
    k, phase = settings.store_every, _store_phase(settings)
    converged, reason, diag = False, "", {}
    total = settings.total_steps
    progress = _Progress(settings.progress, total)
    n_new = 0
    remaining = total - done
    state = emcee.State(start.coords, log_prob=start.log_prob, random_state=start.random_state)
    buf_c, buf_l = [], []
    acc_batch = np.zeros(n_walkers)
    prev_coords = start.coords.copy()
    last_flush = time.monotonic()
    new_c, new_l = [], []

    def flush() -> None:
        nonlocal buf_c, buf_l, acc_batch, last_flush
        if checkpoint is not None and buf_c:
            # the state after the batch's last step: read here, at the yield of that step (see _quiet_sampler_class)
            checkpoint.append(np.array(buf_c), np.array(buf_l), acc_batch, sampler.exact_random_state())
        buf_c, buf_l = [], []
        acc_batch = np.zeros(n_walkers)
        last_flush = time.monotonic()

    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for state in sampler.sample(state, iterations=remaining, store=False, progress=False,
                                    skip_initial_state_check=True):
            step = done + n_new + 1
            n_new += 1
            # DE and stretch proposals move an accepted walker with probability one
            acc = np.any(state.coords != prev_coords, axis=1)
            prev_coords = state.coords.copy()
            accepted += acc
            acc_batch += acc
            if step % k == phase:
                buf_c.append(prev_coords)
                buf_l.append(state.log_prob.copy())
                new_c.append(buf_c[-1])
                new_l.append(buf_l[-1])
            if time.monotonic() - last_flush > settings.checkpoint_interval:
                flush()
            if step in schedule:
                flush()
                if new_c:
                    chain = np.concatenate([chain, np.array(new_c)])
                    log_prob = np.concatenate([log_prob, np.array(new_l)])
                new_c, new_l = [], []
                if settings.fixed:
                    tau = _tau(chain)
                else:
                    tau, converged, diag = decide(chain, prev_tau)
                prev_tau = tau
                tau_history.append((step, float(tau.max())))
                progress.update(step, f"tau_max={tau.max() * k:.1f} acc={accepted.mean() / step:.2f}", force=True)
                if converged:
                    reason = f"converged after {step} steps"
                    break
            else:
                progress.update(step)
        flush()
    if new_c:
        chain = np.concatenate([chain, np.array(new_c)])
        log_prob = np.concatenate([log_prob, np.array(new_l)])
    if not reason and not settings.fixed:
        reason = f"max_steps = {settings.max_steps} reached before convergence"
    progress.close()
    return chain, log_prob, accepted, n_new, converged, reason, diag, prev_tau
