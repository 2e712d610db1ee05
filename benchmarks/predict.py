"""Posterior-prediction benchmark: 1000 draws x 4 clamping lengths x 800 lines.

Times :func:`bayes_rcsa.posterior.predict` (precompute, batched FRFs of all
draws, |H|/Re/Im quantile bands, mode detection, per-mode natural frequency,
peak magnitude and dynamic stiffness intervals, parameter influence) against
a naive implementation measured in the same run: one draw at a time through
``CachedConfiguration.frf`` (numpy), ``numpy.quantile`` along the draw axis,
and the natural frequency of each draw computed separately.  Target of the
issue: at most 2 s.  Run: ``python benchmarks/predict.py``.
"""

from __future__ import annotations

import numpy as np

from _bench_setup import example_model, median_time
from bayes_rcsa.params import GrowthLaw, LogUniform, ParameterModel, Uniform
from bayes_rcsa.model import Configuration
from bayes_rcsa.posterior import PosteriorDraws, PredictionTarget, natural_frequency, predict

N_DRAWS, N_FREQ, LENGTHS = 1000, 800, (0.025, 0.030, 0.035, 0.040)
LIMIT_S = 2.0


def draws(rng: np.random.Generator) -> PosteriorDraws:
    """A correlated, posterior-like cloud around the reference paper's identified contact."""
    z = rng.standard_normal((N_DRAWS, 2))
    lkx = np.log10(1.8e6) + 3e-4 * z[:, 0]
    lkt = np.log10(4.5e5) + 0.05 * (-0.98 * z[:, 0] + 0.2 * z[:, 1])
    values = {
        "k_xf": 10**lkx, "k_thetaM": 10**lkt,
        "g_xf": rng.uniform(0.44, 0.46, N_DRAWS), "g_thetaM": rng.uniform(0.0, 0.5, N_DRAWS),
        "c_xf": np.full(N_DRAWS, 10.0), "c_thetaM": np.full(N_DRAWS, 5e-4),
    }
    priors = {"k_xf": LogUniform(1e5, 1e8), "k_thetaM": LogUniform(1e4, 1e7), "g_xf": Uniform(0.0, 0.5),
              "g_thetaM": Uniform(0.0, 0.5)}
    pm = ParameterModel.from_priors(GrowthLaw(0.025, 0.040, 0.5), priors, {"c_xf": 10.0, "c_thetaM": 5e-4})
    return PosteriorDraws(pm, values, "multi")


def naive(model, d: PosteriorDraws, targets) -> list:
    """One draw at a time, numpy quantiles on the strided axis, one natural frequency per draw."""
    out = []
    for t in targets:
        cache = model.precompute(t.configuration, t.frequency_hz)
        kx, kt, cx, ct = d.contact([t.configuration.clamping_length])[:4]
        h = np.empty((d.n_draws, t.frequency_hz.size), complex)
        for i in range(d.n_draws):
            h[i] = cache.frf(kx[i, 0], kt[i, 0], cx[i, 0], ct[i, 0])
        q = np.quantile(np.abs(h), [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
        np.quantile(h.real, [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
        np.quantile(h.imag, [0.05, 0.25, 0.5, 0.75, 0.95], axis=0)
        fn = np.array([natural_frequency(t.frequency_hz, h[i]) for i in range(d.n_draws)])
        out.append((q, np.quantile(fn, [0.05, 0.5, 0.95])))
    return out


def main() -> None:
    model = example_model()
    freq = np.linspace(300.0, 4000.0, N_FREQ)
    d = draws(np.random.default_rng(20261122))
    targets = [PredictionTarget(Configuration(cl), freq) for cl in LENGTHS]
    predict(d, model, targets)  # compile / warm up

    t_full = median_time(lambda: predict(d, model, targets), repeats=7)
    t_noinfl = median_time(lambda: predict(d, model, targets, influence=False), repeats=7)
    t_naive = median_time(lambda: naive(model, d, targets), repeats=3)

    p = predict(d, model, targets)
    ref = naive(model, d, targets)
    err = max(float(np.max(np.abs(b.magnitude - r[0]) / r[0])) for b, r in zip(p.bands, ref))

    print(f"Posterior prediction: {N_DRAWS} draws x {len(LENGTHS)} clamping lengths x {N_FREQ} lines")
    print(f"{'path':<52}{'median':>12}{'vs naive':>12}")
    print(f"{'predict() incl. parameter influence':<52}{t_full:>10.3f} s{t_naive / t_full:>11.1f}x")
    print(f"{'predict(influence=False)':<52}{t_noinfl:>10.3f} s{t_naive / t_noinfl:>11.1f}x")
    print(f"{'naive (draw loop, numpy quantiles, per-draw f_n)':<52}{t_naive:>10.3f} s{1:>11.1f}x")
    print(f"max relative difference of the |H| quantile bands vs naive: {err:.2e}")
    print(f"target <= {LIMIT_S:g} s: {'PASS' if t_full <= LIMIT_S else 'FAIL'}")


if __name__ == "__main__":
    main()
