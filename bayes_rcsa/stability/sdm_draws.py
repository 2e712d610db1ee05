"""The "sdm" stability method: semi-discretisation on modal fits of every FRF draw, batched.

Each direction's receptances get one full modal fit
(:func:`~bayes_rcsa.stability.modal_fit.fit_modal_model`, BIC mode count) of
the draws' mean FRF; every draw is then refined from it at once by
:func:`~bayes_rcsa.stability.modal_fit.refit_modal_models` (batched
Levenberg-Marquardt, same mode count; draws differ far less than their modes'
spacing), and only a draw whose refit is clearly worse than the typical
draw's gets the full mode-count search (counted in ``info["modal_refits"]``).
Then the limit
depth of every (draw, speed) pair is found at once by
:func:`~bayes_rcsa.stability.sdm.sdm_depth_limits_batch`: one batched
spectral-radius evaluation per bracketing or secant step over all pairs
still open, started from the zero-order limit of the same draw (the two
methods agree within a few per cent where the ZOA is accurate, so the
bracket is usually found in one or two steps).  No depth grid is scanned.

Many draws (the measured FRFs' 500 realisations): a surrogate from exact draws.
At 2.5 ms of CPU per (draw, speed) pair, 500 realisations at 400 speeds took
minutes.  The realisations of a measured FRF differ by its random error, far
less than the modes' spacing, and so do their SDM limits; what SDM adds to the
zero-order limit (the intermittent cutting force's effect, flip lobes) is a
property of the cut and the modes, which the realisations share.  So with
more than :data:`SURROGATE_MIN_DRAWS` draws of an equal-pitch cutter,
:data:`EXACT_DRAWS` draws spread evenly over the set (realisations are
exchangeable) get the full SDM, and every other draw's limit is its own
zero-order limit times the exact draws' median ratio SDM / ZOA at that speed,
the zero-order limits taken of each draw's FRF smoothed onto the modes of the
draws' mean (:func:`_smoothed`), as SDM sees it through its modal fit.
The surrogate is checked where it is used: each exact draw is predicted from
the others (leave one out) and the relative error's 95 % point is reported in
``info["surrogate"]``; above :data:`SURROGATE_TOLERANCE` every draw is computed
exactly instead (with a warning of the time).  ``MethodOptions(exact=True)``
(``lobes --sdm-exact``) always computes every draw.

When is SDM needed?  The zero-order approximation averages the directional
matrix over a revolution; at low radial immersion (roughly below 0.2-0.3)
the cutting force is strongly intermittent and SDM finds additional
flip (period-doubling) lobes and shifted lobe minima that ZOA misses.  At
moderate to full immersion the two agree within a few per cent
(tests/test_stability_acceptance.py) and ZOA suffices.
"""

from __future__ import annotations

import numpy as np

from .. import messages
from ..errors import SetupError
from .methods import STABILITY_METHODS, MethodResult
from .zoa import zoa_lobes

# .modal_fit (scipy.optimize) and .sdm (the compiled kernel) are imported where used: registering the method
# must not cost a ZOA run their import time

__all__ = ["SDMMethod"]

#: Draws above which an equal-pitch cutter's SDM limits come from the surrogate (module docstring).
SURROGATE_MIN_DRAWS = 48
#: Draws computed exactly for the surrogate: 12 x 400 speeds x 2.5 ms is 12 s of CPU (500 exact draws: 500 s);
#: a median of 11 ratios per speed (leave one out) is stable to a few tenths of a per cent where the draws agree.
EXACT_DRAWS = 12
#: Largest 95 % point of the surrogate's leave-one-out relative error (over exact draws and speeds with finite
#: limits) at which it is used.  benchmarks/sdm_surrogate.py on the bundled files (500 realisations, 100 speeds):
#: at 95 % and 30 % immersion the 95 % point was 0.4 % and 0.8 %, the P = 0.95 contour moved 0.3-0.5 % (median)
#: and the recommendation was the exact one's within 0.4 %; at 10 % immersion (flip lobes) it was 1.9 %, and the
#: recommended depth came out 1.7 % above the exact one's, on the unsafe side.  1.5 % keeps the surrogate where it
#: was right and sends cases like the last one to the exact computation (that run, seed 6101, set it; the check on
#: fresh realisations, seed 6102, is the table in docs/stability.md).
SURROGATE_TOLERANCE = 0.015

# run-time model of estimate_seconds (s; see there)
_FIXED_S = 1.5
_NEIGHBOUR_S = 0.01
_PAIR_S = 0.0025


def _fit_seconds(n_freq: int) -> float:
    """Batched modal refits of one draw, both directions (s); linear in the lines."""
    return 0.02 * n_freq / 1500


class SDMMethod:
    """First-order semi-discretisation of modal fits of the FRF draws."""

    name = "sdm"
    summary = "semi-discretisation on modal fits of each draw (slower; needed at low radial immersion)"

    def check(self, options) -> None:
        if not (isinstance(options.max_modes, int) and options.max_modes >= 1):
            raise SetupError(f"max_modes={options.max_modes!r}: SDM needs a modal fit with at least 1 mode")
        if options.intervals is not None and options.intervals < 2:
            raise SetupError(f"intervals={options.intervals!r}: expected >= 2 per tooth period")

    def estimate_seconds(self, n_draws: int, n_speeds: int, n_freq: int, exact: bool = False) -> float:
        # measured on the bundled example (tip_x/tip_y_30mm.csv, 1501 lines, 3-4 modes per direction, 500 coherence
        # realisations, 2 shared and loaded cores): about 1.5 s fixed (imports, the full fits of the mean FRFs and
        # of the measured FRFs), 0.02 s per draw for the batched refits of both directions, 0.01 s per draw for the
        # limits next to the recommendation and 2.5 ms per (draw, speed) pair (5 speeds: 20 s CPU, 23 s wall,
        # estimate 23 s; 50 speeds: 48 s CPU, 72 s wall, estimate 79 s)
        # (with the surrogate: EXACT_DRAWS exact draws; the zero-order limits of the others cost milliseconds)
        surrogate = n_draws > SURROGATE_MIN_DRAWS and not exact
        return _exact_seconds(min(n_draws, EXACT_DRAWS) if surrogate else n_draws, n_speeds, n_freq)

    def depth_limits(self, frf_x, frf_y, frequency_hz, cutting, speeds_rpm, options, progress=None):
        self.check(options)
        gx = np.atleast_2d(frf_x)
        gy = np.atleast_2d(frf_y)
        f = np.asarray(frequency_hz, dtype=float)
        speeds = np.asarray(speeds_rpm, dtype=float)
        n_draws = gx.shape[0]
        if n_draws > SURROGATE_MIN_DRAWS and cutting.equal_pitch and not options.exact:
            result = _surrogate(self, gx, gy, f, cutting, speeds, options, progress)
            if result is not None:
                return result
        fit_share = _fit_seconds(f.size) / (_fit_seconds(f.size) + _PAIR_S * speeds.size)

        def report(x):
            if progress is not None:
                progress(x)

        fits_xy, notes = [], {}
        for k, (g, c) in enumerate(((gx, "X"), (gy, "Y"))):
            fit_list, notes[c.lower()] = _fit_draws(f, g, options.max_modes, c)
            fits_xy.append(fit_list)
            report(fit_share * (k + 1) / 2)
        fits = list(zip(*fits_xy))
        pairs = [(fx.model, fy.model) for fx, fy in fits]
        guess = _guesses(pairs, gx, gy, f, cutting, speeds)
        lim = _limits(pairs, gx, gy, f, cutting, speeds, guess, options,
                      None if progress is None else (lambda x: report(fit_share + (1 - fit_share) * x)))

        def limits_at(s):
            s = np.asarray(s, dtype=float)
            g = _guesses(pairs, gx, gy, f, cutting, s)
            return _limits(pairs, gx, gy, f, cutting, s, g, options, None)

        info = {"modal_fit_rms_relative_max": float(max(max(a.rms_relative, b.rms_relative) for a, b in fits)),
                "modal_refits": notes}
        return MethodResult(lim, fits, info, limits_at)


def _exact_seconds(n_draws: int, n_speeds: int, n_freq: int) -> float:
    """Run time of SDM on ``n_draws`` draws computed exactly (s; model of :meth:`SDMMethod.estimate_seconds`)."""
    return _FIXED_S + n_draws * (_fit_seconds(n_freq) + _NEIGHBOUR_S + _PAIR_S * n_speeds)


def _ratio_median(exact_lim, zoa_lim):
    """Median over the exact draws of SDM / ZOA per speed, (n_speed,); NaN where no draw has both finite."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(np.isfinite(exact_lim) & np.isfinite(zoa_lim) & (zoa_lim > 0), exact_lim / zoa_lim, np.nan)
    out = np.full(ratio.shape[1], np.nan)
    some = np.any(np.isfinite(ratio), axis=0)
    out[some] = np.nanmedian(ratio[:, some], axis=0)
    return out


def _from_ratio(zoa_lim, ratio, exact_lim):
    """Surrogate limits (n, n_speed): ZOA x ratio; where the ratio or the ZOA limit is not finite, the exact draws'
    median limit at that speed (+inf where they found none)."""
    fallback = np.median(exact_lim, axis=0)  # inf-aware: a median of +inf values is +inf
    approx = zoa_lim * ratio[None, :]
    return np.where(np.isfinite(approx), approx, fallback[None, :])


def _smoothed(f, g, max_modes, label):
    """The draws' FRFs (n, n_freq) on the modes of their mean's modal fit: residues (and a residual compliance)
    refitted per draw by one linear least-squares solve over all draws, poles fixed.

    SDM sees each draw through its modal fit, which averages out the measured FRF's line-to-line random error; the
    zero-order limit of the raw lines does not (it reads the lines near the chatter frequency one by one), so
    the ratio SDM / ZOA of raw draws carries that noise.  The zero-order limit of these smooth FRFs follows what a
    modal fit keeps of each draw (mostly the modes' amplitudes) and its ratio to SDM stays steady between draws.
    """
    from .modal_fit import fit_modal_model

    nominal = fit_modal_model(f, g.mean(axis=0), max_modes=max_modes, source=f"mean of the FRF draws {label}").model
    r = f[:, None] / nominal.natural_frequency_hz
    basis = np.concatenate([1.0 / (1.0 - r**2 + 2j * nominal.damping_ratio * r), np.ones((f.size, 1))], axis=1)
    a = np.concatenate([basis.real, basis.imag])  # (2 n_freq, n_modes + 1), real coefficients
    b = np.concatenate([g.real.T, g.imag.T])  # (2 n_freq, n_draws)
    coef = np.linalg.lstsq(a, b, rcond=None)[0]
    return (basis @ coef).T


def _surrogate(method, gx, gy, f, cutting, speeds, options, progress):
    """SDM limits of many draws from :data:`EXACT_DRAWS` exact ones (module docstring); None when the leave-one-out
    check fails (the caller then computes every draw)."""
    import warnings
    from dataclasses import replace

    n_draws = gx.shape[0]
    sub = np.unique(np.round(np.linspace(0, n_draws - 1, EXACT_DRAWS)).astype(int))
    sx, sy = _smoothed(f, gx, options.max_modes, "X"), _smoothed(f, gy, options.max_modes, "Y")
    zoa_all = np.atleast_2d(zoa_lobes(sx, sy, f, cutting, speeds).depth_limit_m)
    exact = method.depth_limits(gx[sub], gy[sub], f, cutting, speeds, replace(options, exact=True), progress)
    ex_lim = np.atleast_2d(exact.depth_limit_m)
    # leave one out: each exact draw predicted from the others' median ratio and its own ZOA limit
    errors = []
    for k in range(sub.size):  # EXACT_DRAWS (12) small median computations, not a loop over the draws
        others = np.delete(np.arange(sub.size), k)
        pred = _from_ratio(zoa_all[sub[k]][None, :], _ratio_median(ex_lim[others], zoa_all[sub[others]]),
                           ex_lim[others])[0]
        ok = np.isfinite(pred) & np.isfinite(ex_lim[k]) & (ex_lim[k] > 0)
        errors.append(np.abs(pred[ok] - ex_lim[k][ok]) / ex_lim[k][ok])
    err = np.concatenate(errors) if errors else np.zeros(0)
    q95 = float(np.quantile(err, 0.95)) if err.size else 0.0
    check = {"exact_draws": int(sub.size), "draws": int(n_draws), "tolerance": SURROGATE_TOLERANCE,
             "loo_relative_error": {"median": float(np.median(err)) if err.size else 0.0, "q95": q95,
                                    "max": float(err.max()) if err.size else 0.0},
             "rule": (f"{sub.size} draws spread evenly over the {n_draws} computed with SDM; every other draw's "
                      "limit is its zero-order limit (of its FRF smoothed onto the mean's modes) times their median ratio "
                      "SDM / ZOA at that speed; used when "
                      f"the leave-one-out relative error's 95 % point is <= {SURROGATE_TOLERANCE:g}")}
    if q95 > SURROGATE_TOLERANCE:
        messages.warn(f"SDM surrogate not accurate enough for these FRFs (leave-one-out error 95 % point "
                      f"{100 * q95:.1f} % > {100 * SURROGATE_TOLERANCE:g} %): every one of the {n_draws} draws is "
                      f"computed with SDM (about {_exact_seconds(n_draws, speeds.size, f.size):.0f} s)",
                      stacklevel=3)
        return None
    ratio = _ratio_median(ex_lim, zoa_all[sub])
    lim = _from_ratio(zoa_all, ratio, ex_lim)
    lim[sub] = ex_lim

    def limits_at(s):
        s = np.asarray(s, dtype=float)
        z = np.atleast_2d(zoa_lobes(sx, sy, f, cutting, s).depth_limit_m)
        e = np.atleast_2d(exact.limits_at(s))
        out = _from_ratio(z, _ratio_median(e, z[sub]), e)
        out[sub] = e
        return out

    info = dict(exact.info)
    info["surrogate"] = check
    return MethodResult(lim, exact.modal_fits, info, limits_at)


def _fit_draws(f, g, max_modes, label):
    """Modal fits of all draws of one direction: the full BIC fit of the draws' mean FRF once, then a batched
    refinement of every draw from it (same mode count), and the full fit again only for draws whose refit is
    clearly worse than the others' (median-based, so one odd draw cannot hide among them).

    Parameters
    ----------
    f : (n_freq,) Hz
    g : (n_draws, n_freq) complex m/N
    max_modes : int
    label : str, "X" or "Y"

    Returns
    -------
    fits : list of ModalFit, one per draw
    note : dict, the nominal mode count, how many draws were refined from the nominal fit, how many needed the
        full fit (``full_fit``) or kept their refit because the full fit was no better or failed
        (``kept_refit``), and how many have a mode on the edge of the fit's bounds (``at_bound``)
    """
    from ..errors import ConvergenceError
    from .modal_fit import fit_modal_model, refit_modal_models

    nominal = fit_modal_model(f, g.mean(axis=0), max_modes=max_modes, source=f"mean of the FRF draws {label}")
    if g.shape[0] == 1:
        return [nominal], {"nominal_modes": nominal.model.n_modes, "refined": 0, "full_fit": 1, "kept_refit": 0}
    fits = refit_modal_models(f, g, nominal, source=f"FRF draws {label}")
    rms = np.array([x.rms_relative for x in fits])
    # a refit can only lower a draw's misfit from the nominal modes'; one well above the typical draw's means
    # the draw needs another mode count (posterior draws far from the mean), as in the per-draw fit before
    worse = np.nonzero(rms > 1.5 * np.median(rms) + 1e-3)[0]
    full = kept = 0
    for d in worse:  # rare: only draws the batched refit could not serve
        try:
            alt = fit_modal_model(f, g[d], max_modes=max_modes, source=f"FRF draw {d} {label}")
        except ConvergenceError:
            kept += 1
            continue
        if alt.rms_relative < fits[d].rms_relative:
            fits[d], full = alt, full + 1
        else:
            kept += 1
    return fits, {"nominal_modes": nominal.model.n_modes, "refined": int(g.shape[0] - full), "full_fit": full,
                  "kept_refit": kept, "at_bound": _at_bound(g, fits)}


def _at_bound(g, fits) -> int:
    """Draws whose fit has a mode with ζ or k (scaled units) on the edge of the fit's box: a mode the FRF does
    not determine (reported, not hidden; the lobes use it as fitted)."""
    from .modal_fit import _LN_K_BOUNDS, _LN_ZETA_BOUNDS

    scale = np.sqrt(np.mean(np.abs(g) ** 2, axis=1))
    n = 0
    for x, s in zip(fits, scale):  # per draw: a few comparisons on (n_modes,) arrays
        lk, lz = np.log(x.model.stiffness * s), np.log(x.model.damping_ratio)
        n += bool(np.any(np.minimum(lk - _LN_K_BOUNDS[0], _LN_K_BOUNDS[1] - lk) < 1e-6)
                  or np.any(np.minimum(lz - _LN_ZETA_BOUNDS[0], _LN_ZETA_BOUNDS[1] - lz) < 1e-6))
    return n


def _limits(pairs, gx, gy, f, cutting, speeds, guess, options, progress):
    from .sdm import sdm_depth_limits_batch

    n_draws = len(pairs)
    index = np.repeat(np.arange(n_draws), speeds.size)
    return sdm_depth_limits_batch(pairs, index, cutting, np.tile(speeds, n_draws), guess.ravel(),
                                  intervals=options.intervals, progress=progress).reshape(n_draws, speeds.size)


def _guesses(pairs, gx, gy, f, cutting, speeds):
    """First guesses (n_draws, n_speed): the zero-order limits of the same FRFs, else the draw's largest finite one."""
    n_draws = len(pairs)
    guess = np.atleast_2d(zoa_lobes(gx, gy, f, cutting, speeds).depth_limit_m) if cutting.equal_pitch \
        else _mean_force_guess(pairs, cutting, speeds)
    finite = np.where(np.isfinite(guess), guess, np.nan)
    fallback = np.nanmax(finite, axis=1) if np.any(np.isfinite(finite)) else np.zeros(n_draws)
    fallback = np.where(np.isfinite(fallback) & (fallback > 0), fallback, 1e-4)
    return np.where(np.isfinite(guess), guess, fallback[:, None])


def _mean_force_guess(pairs, cutting, speeds):
    """Variable pitch (no ZOA): the single-mode lobe-minimum estimate 2 k ζ / (N K_t) as a start, (n_draws, n_speed)."""
    out = np.empty((len(pairs), speeds.size))
    for d, (mx, my) in enumerate(pairs):
        kz = [m.stiffness * m.damping_ratio for m in (mx, my) if m is not None]
        out[d] = 2 * float(np.min(np.concatenate(kz))) / (cutting.flutes * cutting.kt)
    return out


STABILITY_METHODS.register(SDMMethod.name, SDMMethod())
