"""Global search for the posterior optimum: a likelihood grid per clamping length.

Why not a plain differential evolution
--------------------------------------
The likelihood of a lightly damped FRF is a narrow ridge: only contact
stiffnesses that put the model's tool mode within its half-power bandwidth
(a few per cent in frequency, about 0.01-0.04 decades in k) fit at all, and
everywhere else it is a plateau (wrong peak position, noise scale near
100 %).  Over prior ranges of four or five decades a population of a few
dozen random points often misses the ridge, and differential evolution
then converges on the plateau.

The search
----------
1. For each clamping length ``L`` the profile log-likelihood (noise scales
   maximised analytically, ``-N_j ln Q_j`` summed over that length's
   measurements) is evaluated on a grid of ``(log10 k_xf(L), log10
   k_thetaM(L))``.  The ``k_xf`` step is a third of the narrowest measured
   half-power bandwidth (in decades of stiffness), so the ridge cannot fall
   between grid lines; ``k_thetaM``, which moves the peak less, gets twice
   that step.  The model's structure makes this cheap: per line, ``A``
   depends only on ``k_xf`` and ``B`` only on ``k_thetaM`` (see
   :mod:`bayes_rcsa.model.assembly`), and at most ``max_lines`` lines per
   measurement, evenly spread over the band, are used.
2. With the growth law, every growth pair ``(g_xf, g_thetaM)`` on a grid of
   the same resolution shifts each length's map by ``log10(1 + g x_L)``;
   the sum of the shifted maps (plus the log prior) is the profile
   posterior of ``(k_xf(l_a), k_thetaM(l_a), g_xf, g_thetaM)``.
3. The best few well-separated grid points are polished by L-BFGS-B on the
   full log posterior (noise scales starting at their profile values); the
   best polished point is the optimum.
4. The maps of step 1 weight the residuals by the *measured* ``|H|``
   (``Q_j = sum_n |r_n|^2 / v_n(measured)``), a proxy for the likelihood's
   model variance that holds while the noise is small against the signal.
   When a noise scale at the polished optimum exceeds
   :data:`EXACT_PROFILE_NOISE`, :func:`.sampler.find_optimum` searches the
   grid again with the likelihood's own profile (``exact=True``: the model's
   variance, its ``ln v_n`` term and each noise scale maximised within its
   prior bounds; :meth:`.ForwardModel.grid_profile_sums` without forming the FRFs, the chunked forward path
   where a model term makes the FRF more than the joint formula)
   and polishes its best points too.  With noise twice the signal the proxy
   ranked a wrong resonance (a soft joint with a larger noise scale) first,
   40-300 log units below the mode that generated the data
   (docs/calibration.md).
5. When the noise scale at the optimum is still above
   :data:`EXACT_PROFILE_NOISE` and the model samples the parameters of a
   model term, the grid is searched again with those parameters held at
   their prior's 10, 50 and 90 % points instead of the baseline (:func:`term_levels`),
   and the best of those candidates are polished too: a large tip mass
   moves the tool mode off the ridge the term-free grid finds.

Sampled damping is held at the centre of its prior during the grid stage
and freed in the polish.  Sampled model-term parameters are held at their
baseline (where the term vanishes) when the prior allows it, else at the
centre of their prior; the grid evaluates the full forward model (terms
included) through :class:`bayes_rcsa.params.ForwardModel`.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConvergenceError
from .likelihood import FRFLikelihood, noise_variance, weighted_sums
from ..params.priors import PriorSet

__all__ = ["grid_candidates", "polish", "peak_bandwidth", "profile_noise", "optimum_noise_scale", "term_levels",
           "EXACT_PROFILE_NOISE", "TERM_QUANTILES", "MAX_TERM_COMBINATIONS"]

#: Relative noise scale above which :func:`.sampler.find_optimum` searches the grid again with the likelihood's
#: own profile (``grid_candidates(..., exact=True)``).  The fast path's weights ``1 / |H_meas|^2`` stand for the
#: likelihood's ``1 / |H_model|^2``; with ``H_meas = H_model (1 + s z)``, ``z`` unit complex Gaussian, they are off
#: by about ``2 s`` per line (20 % at ``s = 0.1``) and the likelihood's ``ln v`` term, which they drop, starts to
#: decide between resonances (docs/calibration.md: with noise above the signal the fast grid ranked a wrong
#: resonance first).  Below it the two grids rank the same mode first.
EXACT_PROFILE_NOISE = 0.1
#: Prior quantiles (sampling coordinate) of each sampled model-term parameter at which the grid is searched again
#: when the optimum's noise scale stays above :data:`EXACT_PROFILE_NOISE` (:func:`term_levels`).  Near the box's
#: ends, not at its quartiles: a 17 g tip mass at the offset's bound (10 mm) was out of reach of the quartiles'
#: polish (886 log units below the data's mode), and found from the 0.9 level (docs/calibration.md).
TERM_QUANTILES = (0.1, 0.5, 0.9)
#: Most combinations of term-parameter levels searched (two parameters at three levels each).
MAX_TERM_COMBINATIONS = 9


def peak_bandwidth(frequency_hz: np.ndarray, values: np.ndarray) -> float:
    """Relative half-power bandwidth ``df / f`` of the largest peak of ``|values|``.

    Falls back to 0.05 when the -3 dB points are not both inside the data.
    """
    mag = np.abs(values)
    i = int(np.argmax(mag))
    level = mag[i] / math.sqrt(2.0)
    left = np.nonzero(mag[:i] < level)[0]
    right = np.nonzero(mag[i:] < level)[0]
    if left.size == 0 or right.size == 0:
        return 0.05
    f_lo = frequency_hz[left[-1]]
    f_hi = frequency_hz[i + right[0]]
    return float((f_hi - f_lo) / frequency_hz[i])


def _length_maps(likelihood: FRFLikelihood, log_kx: np.ndarray, log_kt: np.ndarray, held: dict[str, float],
                 max_lines: int, chunk_sets: int = 1024,
                 noise_bounds: list[tuple[float, float]] | None = None) -> dict[float, np.ndarray]:
    """Profile log-likelihood map ``(n_x, n_t)`` of each distinct clamping length.

    The model is evaluated on at most ``max_lines`` lines per measurement
    (a subsampled stack), every grid point being one parameter set with the
    stiffness of the grid at every length (no growth) and the other
    parameters at the ``held`` values (physical units).  ``chunk_sets`` grid points are evaluated per call:
    the maps are the same for any chunk, but (chunk, lines) temporaries that stay in cache are faster (bundled
    example, 182,000 points x 512 lines: 4.2 s in chunks of 16,384, 3.1-3.4 s in chunks of 1024).

    ``noise_bounds`` None: the data-weighted map ``-N_j ln Q_j``, ``Q_j = sum_n |r_n|^2 / v_n(measured)`` (the
    fast path).  ``noise_bounds`` ``[(lo_j, hi_j)]`` (relative noise scales, one pair per measurement): the
    likelihood's own profile (:func:`_profile_log_likelihood`), with the model's variance and each noise scale maximised
    within its bounds (:meth:`.ForwardModel.grid_profile_sums`, or the chunked forward model where that declines:
    2.8 times slower on the bundled example's grid, benchmarks/grid_search.py).
    """
    from ..model.assembly import ConfigurationStack
    from ..params.forward import ForwardModel

    obs_all = likelihood.observations
    caches, data, weight, coherence, n_used = [], [], [], [], []
    for j, obs in enumerate(obs_all):
        idx = np.unique(np.linspace(0, obs.n_lines - 1, min(obs.n_lines, max_lines)).round().astype(int))
        caches.append(likelihood.model.precompute(obs.configuration, obs.frequency_hz[idx]))
        data.append(obs.values[idx])
        sl = likelihood.stack.slices[j]
        weight.append(likelihood.weight[sl][idx])
        coherence.append(likelihood.coherence[sl][idx])
        n_used.append(idx.size)
    sub = ConfigurationStack(caches)
    forward = ForwardModel(likelihood.parameters, sub, likelihood.model)
    d = np.concatenate(data)
    w2 = np.repeat(np.concatenate(weight), 2)
    float_slices = [slice(2 * sl.start, 2 * sl.stop) for sl in sub.slices]
    ii, kk = np.meshgrid(np.arange(log_kx.size), np.arange(log_kt.size), indexing="ij")
    kx_all = 10.0 ** log_kx[ii.ravel()]
    kt_all = 10.0 ** log_kt[kk.ravel()]
    values = _grid_values(held, kx_all, kt_all)
    if noise_bounds is not None:
        eps2 = float(likelihood.noise.floor) ** 2
        coh = np.concatenate(coherence)
        sums = forward.grid_profile_sums(values, log_kx.size, log_kt.size, d, coh, eps2)
        if sums is None:
            q, lv = _chunked_profile_sums(forward, kx_all, kt_all, held, d, coh, sub.slices, eps2, chunk_sets)
        else:
            q, lv = (a.reshape(kx_all.size, len(obs_all)) for a in sums)
        ll = _profile_log_likelihood(q, lv, np.asarray(n_used, dtype=float), noise_bounds)
    else:
        # one configuration per observation in ``sub``, so the per-configuration sums are the per-measurement ones
        q = forward.grid_sums(values, log_kx.size, log_kt.size, d, np.concatenate(weight))
        if q is not None:
            q = q.reshape(kx_all.size, len(obs_all))
        else:
            q = _chunked_sums(forward, kx_all, kt_all, held, d, w2, float_slices, chunk_sets)
        with np.errstate(divide="ignore"):
            ll = -np.asarray(n_used)[None, :] * np.log(q)  # (n_points, n_meas)
    groups: dict[float, np.ndarray] = {}
    for j, obs in enumerate(obs_all):
        length = round(obs.configuration.clamping_length, 12)
        groups[length] = groups.get(length, 0.0) + ll[:, j].reshape(log_kx.size, log_kt.size)
    return groups


def _grid_values(held: dict[str, float], kx: np.ndarray, kt: np.ndarray) -> dict[str, np.ndarray]:
    """Physical parameter values of grid points: contact stiffnesses ``kx``, ``kt`` (n,) N/m and N m/rad, no
    growth, every other parameter at its ``held`` value."""
    values = {n: np.full(kx.size, v) for n, v in held.items()}
    values.update({"k_xf": kx, "k_thetaM": kt, "g_xf": np.zeros(kx.size), "g_thetaM": np.zeros(kx.size)})
    return values


def _chunked_profile_sums(forward, kx_all, kt_all, held, d, coherence, slices, eps2: float,
                          chunk_sets: int) -> tuple[np.ndarray, np.ndarray]:
    """``Q = sum |r|^2 / v`` and ``L = sum ln v`` per grid point and measurement through the full forward model,
    chunk by chunk, (n_points, n_meas) each: the exact grid where :meth:`.ForwardModel.grid_profile_sums` does
    not apply (a structural or FRF model term is active)."""
    n_meas = len(slices)
    q = np.empty((kx_all.size, n_meas))
    lv = np.empty((kx_all.size, n_meas))
    for a in range(0, kx_all.size, chunk_sets):
        kx = kx_all[a : a + chunk_sets]
        values = _grid_values(held, kx, kt_all[a : a + chunk_sets])
        h = forward.frf(values)  # (chunk, n_lines) complex m/N
        v_all = noise_variance(h.real**2 + h.imag**2, coherence, eps2, slices)
        r2 = np.abs(h - d) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            for j, sl in enumerate(slices):
                v = v_all[:, sl]
                q[a : a + chunk_sets, j] = np.sum(r2[:, sl] / v, axis=1)
                lv[a : a + chunk_sets, j] = np.sum(np.log(v), axis=1)
    return q, lv


def _profile_log_likelihood(q: np.ndarray, lv: np.ndarray, n_per: np.ndarray, noise_bounds) -> np.ndarray:
    """The likelihood's own log-likelihood per grid point and measurement, noise scales profiled: (n_points, n_meas).

    Per measurement ``j`` with model variance ``v_n = (|H_n|^2 + eps2 max_band |H|^2) / gamma_n`` ((m/N)^2, as
    :class:`.likelihood.FRFLikelihood`), ``Q_j = sum_n |r_n|^2 / v_n`` and ``L_j = sum_n ln v_n``: the
    log-likelihood ``-Q_j / s^2 - N_j ln s^2 - L_j`` (constants dropped) at ``s^2 = Q_j / N_j`` clipped to
    ``[lo_j^2, hi_j^2]``.  Unlike the data-weighted sums this keeps the ``ln v_n`` term and the model's weights,
    which matter once the noise is comparable with the signal (the measured ``|H|`` is then no proxy for the
    model's).  Non-finite values (a zero variance) rank as ``-inf``.
    """
    lo2 = np.array([b[0] for b in noise_bounds], dtype=float) ** 2
    hi2 = np.array([b[1] for b in noise_bounds], dtype=float) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        s2 = np.clip(q / n_per, lo2, hi2)
        out = -q / s2 - n_per * np.log(s2) - lv
    return np.where(np.isfinite(out), out, -np.inf)


def _chunked_sums(forward, kx_all, kt_all, held, d, w2, float_slices, chunk_sets) -> np.ndarray:
    """The grid's sums through the full forward model (terms that are not a plain joint), chunk by chunk."""
    q = np.empty((kx_all.size, len(float_slices)))
    for a in range(0, kx_all.size, chunk_sets):
        kx = kx_all[a : a + chunk_sets]
        values = _grid_values(held, kx, kt_all[a : a + chunk_sets])
        r = forward.frf(values)
        r -= d
        q[a : a + chunk_sets] = weighted_sums(r, w2, float_slices)
    return q


def _interp_rows(m: np.ndarray, pos: np.ndarray, axis: int) -> np.ndarray:
    """``m`` at fractional indices ``pos`` along ``axis`` (linear; -inf outside the grid)."""
    n = m.shape[axis]
    i0 = np.floor(pos).astype(int)
    frac = pos - i0
    ok = (i0 >= 0) & ((i0 + 1 <= n - 1) | ((frac == 0) & (i0 <= n - 1)))
    a = np.take(m, np.clip(i0, 0, n - 1), axis=axis)
    b = np.take(m, np.clip(i0 + 1, 0, n - 1), axis=axis)
    shape = [1] * m.ndim
    shape[axis] = pos.size
    f = frac.reshape(shape)
    with np.errstate(invalid="ignore"):
        return np.where(ok.reshape(shape), (1 - f) * a + f * b, -np.inf)


def _separated_top(values: np.ndarray, n: int, min_sep: tuple[int, ...]) -> list[tuple[int, ...]]:
    """Indices of up to ``n`` largest finite entries, pairwise apart by more than ``min_sep`` in some axis."""
    order = np.argsort(values, axis=None)[::-1]
    out: list[tuple[int, ...]] = []
    for f in order:
        if not np.isfinite(values.ravel()[f]):
            break
        idx = np.unravel_index(int(f), values.shape)
        if all(any(abs(idx[d] - c[d]) > min_sep[d] for d in range(len(idx))) for c in out):
            out.append(tuple(int(v) for v in idx))
            if len(out) == n:
                break
    return out


def grid_candidates(likelihood: FRFLikelihood, priors: PriorSet, max_lines: int = 64, n_best: int = 3,
                    exact: bool = False, held_values=None) -> list[np.ndarray]:
    """Best well-separated grid points of the profile posterior, best first.

    Two stages keep the search cheap on priors spanning several decades:
    first ``k_thetaM`` is maximised out of each length's map separately
    (relaxing its growth law) and ``(k_xf(l_a), g_xf)`` is searched on the
    resulting one-dimensional profiles; then, for the best few of those,
    ``(k_thetaM(l_a), g_thetaM)`` is searched exactly.

    Parameters
    ----------
    likelihood : FRFLikelihood
    priors : PriorSet
    max_lines : int
        Lines per measurement used by the grid (evenly spread over the band).
    n_best : int
    exact : bool
        The likelihood's own profile instead of the measured-``|H|`` weights (step 4 of the module docstring).
    held_values : mapping name -> physical value, optional
        Values of parameters the grid does not search (model-term parameters), instead of their baselines
        (:func:`term_levels`).

    Returns
    -------
    list of (ndim,) sampling vectors (noise coordinates at their profile values)
    """
    pm = likelihood.parameters
    names = pm.names
    growth = pm.growth
    lengths = sorted({round(o.configuration.clamping_length, 12) for o in likelihood.observations})
    x_of = {L: ((L - growth.l_a) / (growth.l_b - growth.l_a) if growth.has_growth else 0.0) for L in lengths}

    def phys(name, u):
        return float(priors[name].to_physical(u))

    def log_bounds(name):
        lo, hi = priors[name].optimisation_bounds()
        return math.log10(phys(name, lo)), math.log10(phys(name, hi))

    def g_values(name, step_decades):
        if name not in names:
            return np.array([float(pm.fixed[name])])
        lo, hi = (phys(name, v) for v in priors[name].optimisation_bounds())
        # the shift log10(1 + g x) changes by about one stiffness step per growth step
        n = int(min(61, max(2, math.ceil(0.4343 * (hi - lo) / step_decades) + 1)))
        return np.linspace(lo, hi, n)

    def ln_prior(name, value):
        if name not in names:
            return np.zeros(np.shape(value))
        p = priors[name]
        return p.ln_prob(p.to_sampling(np.asarray(value, dtype=float)))

    def centre(name):
        if name in names:
            lo, hi = priors[name].optimisation_bounds()
            return phys(name, 0.5 * (lo + hi))
        return float(pm.fixed[name])

    def held_value(name):
        """Start of a parameter the grid does not search: a term's baseline if inside the prior, else the centre."""
        p = pm[name]
        if name in names and p.baseline is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                u = priors[name].to_sampling(p.baseline)
            if priors[name].in_support(u):
                return float(p.baseline)
        return centre(name)

    searched = {"k_xf", "k_thetaM", "g_xf", "g_thetaM"}
    held = {n: held_value(n) for n in pm.all_names if n not in searched and n not in pm.noise_names}
    held.update(held_values or {})

    # ridge width in log10 k is about log10(1 + 2 df/f); three grid points across it
    rel = min(peak_bandwidth(o.frequency_hz, o.values) for o in likelihood.observations)
    s_x = float(np.clip(math.log10(1 + 2 * rel) / 3, 0.002, 0.02))
    s_t = 3 * s_x  # k_thetaM moves the peak less; the polish resolves it
    gx = g_values("g_xf", s_x)
    gt = g_values("g_thetaM", s_t)
    (x_lo, x_hi), (t_lo, t_hi) = log_bounds("k_xf"), log_bounds("k_thetaM")
    ext_x = math.log10(1 + max(0.0, gx.max())) if growth.has_growth else 0.0
    ext_t = math.log10(1 + max(0.0, gt.max())) if growth.has_growth else 0.0
    log_kx = np.arange(x_lo, x_hi + ext_x + 1.5 * s_x, s_x)
    log_kt = np.arange(t_lo, t_hi + ext_t + 1.5 * s_t, s_t)
    noise_bounds = None
    if exact:
        noise_bounds = [tuple(phys(n, u) for u in priors[n].optimisation_bounds()) for n in pm.noise_names]
    maps = _length_maps(likelihood, log_kx, log_kt, held, max_lines, noise_bounds=noise_bounds)
    n_x0 = int(np.searchsorted(log_kx, x_hi + 1e-9 * s_x))
    n_t0 = int(np.searchsorted(log_kt, t_hi + 1e-9 * s_t))
    lp_x = ln_prior("k_xf", 10.0 ** log_kx[:n_x0])
    lp_t = ln_prior("k_thetaM", 10.0 ** log_kt[:n_t0])
    lp_gx, lp_gt = ln_prior("g_xf", gx), ln_prior("g_thetaM", gt)

    # stage 1: (k_xf(l_a), g_xf) on the k_thetaM-maximised profiles
    prof = {L: m.max(axis=1) for L, m in maps.items()}
    t1 = np.empty((gx.size, n_x0))
    for a, g1 in enumerate(gx):
        t1[a] = lp_x + lp_gx[a]
        for L, pr in prof.items():
            t1[a] += _interp_rows(pr, np.arange(n_x0) + math.log10(1 + g1 * x_of[L]) / s_x, 0)
    stage1 = _separated_top(t1, 3 * n_best, (2, 4))
    if not stage1:
        raise ConvergenceError("grid search: no grid point has a finite posterior density")

    # stage 2: exact (k_thetaM(l_a), g_thetaM) for each stage-1 candidate
    refined = []
    for a, i in stage1:
        t2 = lp_t[None, :] + lp_gt[:, None]  # (n_gt, n_t0)
        for L, m in maps.items():
            row = _interp_rows(m, np.array([i + math.log10(1 + gx[a] * x_of[L]) / s_x]), 0)[0]  # (n_t,)
            pos = np.arange(n_t0)[None, :] + (np.log10(1 + gt * x_of[L]) / s_t)[:, None]
            t2 = t2 + _interp_rows(row, pos.ravel(), 0).reshape(pos.shape)
        b, k = np.unravel_index(int(np.argmax(t2)), t2.shape)
        refined.append((float(t2[b, k] + lp_x[i] + lp_gx[a]), i, int(k), a, int(b)))
    refined.sort(key=lambda t: -t[0])
    out = []
    for v, i, k, a, b in refined[:n_best]:
        if not np.isfinite(v):
            continue
        values = {**held, "k_xf": 10.0 ** log_kx[i], "k_thetaM": 10.0 ** log_kt[k], "g_xf": gx[a], "g_thetaM": gt[b]}
        theta = np.zeros(len(names))
        for j, n in enumerate(names):
            if n in values:
                theta[j] = float(priors[n].to_sampling(values[n]))
        out.append(profile_noise(likelihood, priors, theta, exact))
    if not out:
        raise ConvergenceError("grid search: no grid point has a finite posterior density")
    return out


def term_levels(likelihood: FRFLikelihood, priors: PriorSet, quantiles=TERM_QUANTILES,
                max_combinations: int = MAX_TERM_COMBINATIONS) -> list[dict[str, float]]:
    """Values of the sampled model-term parameters at which :func:`.sampler.find_optimum` searches the grid again.

    The grid holds a term's parameters at its baseline (the term off).  A large effect of the term (a 15 g tip
    mass lowers the tool mode by more than its half-power bandwidth) then puts the grid's best stiffnesses on
    another ridge, and the polish from there stops at a local mode hundreds of log units below the data's
    (simulation-based calibration, docs/calibration.md).  Each sampled parameter that has a baseline takes the
    prior's ``quantiles`` (in its sampling coordinate, within the optimisation bounds); the levels are every
    combination when there are at most ``max_combinations``, else none (a term with many coefficients, such as
    the statistical discrepancy, is centred on its baseline already).

    Returns
    -------
    list of {name: physical value}, empty when the model samples no term parameter
    """
    pm = likelihood.parameters
    names = [n for n in pm.names if n not in pm.noise_names and pm[n].baseline is not None
             and n not in ("k_xf", "k_thetaM", "g_xf", "g_thetaM")]
    if not names:
        return []
    axes = []
    for n in names:
        lo, hi = priors[n].optimisation_bounds()
        axes.append([float(priors[n].to_physical(lo + q * (hi - lo))) for q in quantiles])
    if math.prod(len(a) for a in axes) > max_combinations:
        return []
    grids = np.meshgrid(*axes, indexing="ij")
    return [{n: float(g.flat[i]) for n, g in zip(names, grids)} for i in range(grids[0].size)]


def profile_noise(likelihood: FRFLikelihood, priors: PriorSet, theta: np.ndarray, exact: bool = True) -> np.ndarray:
    """``theta`` (ndim,) with every sampled noise coordinate at its maximum-likelihood value, within its prior.

    ``exact``: with the likelihood's model variance (``s^2 = mean_n |r_n|^2 / v_n(theta)`` per measurement, the
    noise scales' profile of the likelihood itself; the discrepancy workflow's fits and the exact grid), else with
    the data-only weights of the grid's fast path.  The model is evaluated once, with the noise scales at the
    centres of their priors (they do not change the model FRF).
    """
    pm = likelihood.parameters
    names = pm.names
    theta = np.array(theta, dtype=float)
    for n in pm.noise_names:
        if n in names:
            lo, hi = priors[n].optimisation_bounds()
            theta[names.index(n)] = 0.5 * (lo + hi)
    h = likelihood.model_frf(theta[None, :])[0]
    if exact:
        q = np.abs(h - likelihood.data) ** 2 / likelihood.variance_of(h)[0]
    else:
        q = np.abs(h - likelihood.data) ** 2 * likelihood.weight
    for m, sl in enumerate(likelihood.stack.slices):
        name = pm.noise_names[m]
        if name not in names:
            continue
        p = priors[name]
        lo, hi = p.optimisation_bounds()
        # outside the prior support there is no mass: the bound is the constrained maximum, not a fudge
        theta[names.index(name)] = float(np.clip(p.to_sampling(math.sqrt(float(np.mean(q[sl])))), lo, hi))
    return theta


def optimum_noise_scale(log_post, x: np.ndarray) -> float:
    """Largest relative noise scale ``sigma_j`` (dimensionless, noise rms per model ``|H|``) at ``x`` (ndim,).

    ``log_post`` is a :class:`.problem.LogPosterior` (its likelihood's parameter model names the noise
    coordinates, its priors map them to physical values); NaN for a callable without them or without noise scales.
    """
    pm = getattr(getattr(log_post, "likelihood", None), "parameters", None)
    priors = getattr(log_post, "priors", None)
    scales = [float(priors[n].to_physical(x[pm.names.index(n)])) for n in (pm.noise_names if pm is not None else ())
              if priors is not None and n in pm.names]
    return max(scales) if scales else math.nan


def derivatives(log_post, x: np.ndarray, step: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Value, gradient and Hessian of ``-log_post`` by central differences, in one batched call.

    Parameters
    ----------
    log_post : callable, (n, ndim) -> (n,)
    x : (ndim,) evaluation point (must lie at least ``step`` inside the support)
    step : (ndim,) finite-difference steps

    Returns
    -------
    f : float, g : (ndim,), H : (ndim, ndim)
    """
    nd = x.size
    e = np.eye(nd) * step
    pts = [x]
    for i in range(nd):
        pts += [x + e[i], x - e[i]]
    for i in range(nd):
        for j in range(i + 1, nd):
            pts += [x + e[i] + e[j], x + e[i] - e[j], x - e[i] + e[j], x - e[i] - e[j]]
    f = -log_post(np.array(pts))
    f0 = f[0]
    g = np.array([(f[1 + 2 * i] - f[2 + 2 * i]) / (2 * step[i]) for i in range(nd)])
    h = np.zeros((nd, nd))
    for i in range(nd):
        h[i, i] = (f[1 + 2 * i] + f[2 + 2 * i] - 2 * f0) / step[i] ** 2
    k = 1 + 2 * nd
    for i in range(nd):
        for j in range(i + 1, nd):
            pp, pm, mp, mm = f[k : k + 4]
            h[i, j] = h[j, i] = (pp - pm - mp + mm) / (4 * step[i] * step[j])
            k += 4
    return float(f0), g, h


def polish(log_post, x0: np.ndarray, bounds, max_iter: int = 100) -> tuple[np.ndarray, float]:
    """Maximise ``log_post`` from ``x0`` within ``bounds`` by damped Newton steps.

    Levenberg-Marquardt damping on the finite-difference Hessian, with
    coordinates held on a bound while the gradient pushes outwards.  Every
    iteration is one batched call of the vectorised log posterior (the
    derivatives) plus one for the trial step.  (scipy's L-BFGS-B was the
    first choice; its per-iteration LAPACK calls are slowed by BLAS thread
    contention on small shared machines, and it evaluates one point at a
    time.)

    Returns
    -------
    x : (ndim,), value : float (log posterior at x)
    """
    lo, hi = np.array(bounds, dtype=float).T
    width = hi - lo
    step = 1e-5 * width
    x = np.clip(np.asarray(x0, dtype=float), lo, hi)
    f = float(-log_post(x[None, :])[0])
    if not np.isfinite(f):
        return x, -np.inf
    lam = 1e-3
    for _ in range(max_iter):
        xc = np.clip(x, lo + 2 * step, hi - 2 * step)
        _, g, h = derivatives(log_post, xc, step)
        if not (np.all(np.isfinite(g)) and np.all(np.isfinite(h))):
            break
        at_lo = (x <= lo + 2 * step) & (g > 0)
        at_hi = (x >= hi - 2 * step) & (g < 0)
        free = ~(at_lo | at_hi)
        if not np.any(free):
            break
        hf = h[np.ix_(free, free)]
        gf = g[free]
        scale = np.maximum(np.abs(np.diag(hf)), 1e-12 * np.max(np.abs(np.diag(hf))) + 1e-300)
        improved = False
        while lam < 1e12:
            a = hf + lam * np.diag(scale)
            try:
                d = np.linalg.solve(a, -gf)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            x_new = x.copy()
            x_new[free] = np.clip(x[free] + d, lo[free], hi[free])
            f_new = float(-log_post(x_new[None, :])[0])
            if np.isfinite(f_new) and f_new < f:
                improved = True
                converged = (f - f_new) < 1e-10 * max(1.0, abs(f)) and np.all(np.abs(x_new - x) < 1e-7 * width)
                x, f = x_new, f_new
                lam = max(lam / 5, 1e-9)
                break
            lam *= 5
        if not improved or converged:
            break
    return x, -f
