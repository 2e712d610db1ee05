"""Forward-model benchmark: batched tool-point FRFs after caching.

Case of issue 2: 64 contact parameter sets x 2 clamping lengths x 800
frequency lines.  Prints median times and ratios against a naive loop (one
parameter set and one frequency at a time, numpy.linalg.inv per 2x2 block),
measured in the same run.  Then (issue 41) the spindle samples as an input
of the forward model: ``posterior.predict`` of 300 draws at 3 clamping
lengths with and without 50 spindle samples, and ``ForwardModel.frf`` of
the same draws on a 3-length stack.  Run: ``python benchmarks/forward.py``.
"""

from __future__ import annotations

import numpy as np

from _bench_setup import example_model, median_time
from bayes_rcsa.model import Configuration, ConfigurationStack, PointReceptance
from bayes_rcsa.params import ForwardModel, GrowthLaw, LogUniform, ParameterModel, Uniform
from bayes_rcsa.posterior import PosteriorDraws, PredictionTarget, predict
from bayes_rcsa.spindle import SpindleSamples, assign_samples

N_SETS, N_FREQ, LENGTHS = 64, 800, (0.025, 0.040)


def naive(caches, kx, kt, cx, ct):
    """One parameter set and one frequency at a time, general 2x2 algebra with numpy.linalg.inv."""
    out = np.empty((kx.shape[0], sum(c.frequency_hz.size for c in caches)), complex)
    for s in range(kx.shape[0]):
        col = 0
        for ci, c in enumerate(caches):
            t = c.tool
            for j, w in enumerate(c.omega):
                K = np.diag([kx[s, ci] + 1j * w * cx, kt[s, ci] + 1j * w * ct])
                D = c.holder_tip[j] + t.r11[j] + np.linalg.inv(K)
                out[s, col] = (t.r22[j] - t.r21[j] @ np.linalg.inv(D) @ t.r12[j])[0, 0]
                col += 1
    return out


def main() -> None:
    model = example_model()
    freq = np.linspace(300.0, 4000.0, N_FREQ)
    rng = np.random.default_rng(20261122)
    kx = rng.uniform(1e6, 4e6, (N_SETS, len(LENGTHS)))
    kt = rng.uniform(1e5, 1e6, (N_SETS, len(LENGTHS)))
    cx, ct = 10.0, 5e-4

    t_pre = median_time(lambda: model.precompute(Configuration(LENGTHS[0]), freq), repeats=5)
    caches = [model.precompute(Configuration(cl), freq) for cl in LENGTHS]
    stack = ConfigurationStack(caches)
    stack.frf(kx, kt, cx, ct)  # compile / warm up

    t_kernel = median_time(lambda: stack.frf(kx, kt, cx, ct), repeats=15, number=20)
    t_numpy = median_time(lambda: stack.frf_numpy(kx, kt, cx, ct), repeats=9, number=5)
    few = 4  # the naive loop is slow: time 4 sets and scale to 64
    t_naive = median_time(lambda: naive(caches, kx[:few], kt[:few], cx, ct), repeats=3) * N_SETS / few

    ref = naive(caches, kx[:few], kt[:few], cx, ct)
    err = np.max(np.abs(stack.frf(kx, kt, cx, ct)[:few] - ref)) / np.max(np.abs(ref))

    print(f"Tool-point FRF: {N_SETS} parameter sets x {len(LENGTHS)} clamping lengths x {N_FREQ} lines")
    print(f"{'path':<44}{'median':>14}{'vs naive':>12}")
    print(f"{'precompute per clamping length':<44}{t_pre * 1e3:>11.2f} ms{'':>12}")
    print(f"{'ConfigurationStack.frf (compiled kernel)':<44}{t_kernel * 1e3:>11.3f} ms{t_naive / t_kernel:>11.0f}x")
    print(f"{'ConfigurationStack.frf_numpy':<44}{t_numpy * 1e3:>11.3f} ms{t_naive / t_numpy:>11.0f}x")
    print(f"{'naive loop (set x line, np.linalg.inv)':<44}{t_naive * 1e3:>11.1f} ms{1:>11.0f}x")
    print(f"max relative difference kernel vs naive: {err:.1e}")
    print(f"target: <= 2 ms for the batched evaluation -> {'met' if t_kernel <= 2e-3 else 'NOT met'}")

    # the parameter model's forward evaluation: no terms, and the tip-mass term
    growth = GrowthLaw(LENGTHS[0], LENGTHS[1], 0.5)
    priors = {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e4, 1e8), "g_xf": Uniform(0, 0.5),
              "g_thetaM": Uniform(0, 0.5)}
    fixed = {"c_xf": cx, "c_thetaM": ct}
    values = {"k_xf": kx[:, 0], "k_thetaM": kt[:, 0], "g_xf": rng.uniform(0, 0.5, N_SETS),
              "g_thetaM": rng.uniform(0, 0.5, N_SETS), "c_xf": np.full(N_SETS, cx), "c_thetaM": np.full(N_SETS, ct)}
    base = ForwardModel(ParameterModel.from_priors(growth, priors, fixed), stack, model)
    tip = ForwardModel(ParameterModel.from_priors(growth, priors, fixed, terms=["tip_mass"]), stack, model)
    v_tip = {**values, "tip_mass_kg": rng.uniform(0.001, 0.01, N_SETS)}
    base.frf(values), tip.frf(v_tip)  # warm up
    t_base = median_time(lambda: base.frf(values), repeats=15, number=20)
    t_tip = median_time(lambda: tip.frf(v_tip), repeats=15, number=10)
    print()
    print(f"{'ForwardModel.frf, no terms':<44}{t_base * 1e3:>11.3f} ms{t_base / t_kernel:>11.2f}x of the kernel")
    print(f"{'ForwardModel.frf, tip_mass term':<44}{t_tip * 1e3:>11.3f} ms{t_tip / t_base:>11.2f}x of no terms")
    print(f"target: tip mass within 3x of no terms -> {'met' if t_tip <= 3 * t_base else 'NOT met'}")
    spindle_samples_section(model)


def spindle_samples_section(model, n_draws: int = 300, n_samples: int = 50,
                            lengths=(0.025, 0.0325, 0.040)) -> None:
    """predict and ForwardModel.frf with and without spindle samples (issue 41: one forward path)."""
    rng = np.random.default_rng(41)
    f = model.spindle["x"].frequency_hz
    nominal = model.spindle["x"].interpolate(f)
    # samples: the flange modes moved by a relative 2 % sd (stiffer / softer bearings)
    blocks = np.stack([PointReceptance(f, nominal).interpolate(np.clip(f / (1 + e), f[0], f[-1]))
                       for e in 0.02 * rng.standard_normal(n_samples)])
    samples = SpindleSamples(f, {"x": nominal}, {"x": blocks}, source="benchmark samples")
    growth = GrowthLaw(0.025, 0.040, 0.5)
    priors = {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e4, 1e8), "g_xf": Uniform(0, 0.5),
              "g_thetaM": Uniform(0, 0.5)}
    pm = ParameterModel.from_priors(growth, priors, {"c_xf": 10.0, "c_thetaM": 5e-4})
    values = {"k_xf": 1.8e6 * np.exp(0.01 * rng.standard_normal(n_draws)),
              "k_thetaM": 4.5e5 * np.exp(0.05 * rng.standard_normal(n_draws)),
              "g_xf": rng.uniform(0.4, 0.5, n_draws), "g_thetaM": rng.uniform(0.0, 0.5, n_draws)}
    draws = PosteriorDraws(pm, values, "multi", (0.025, 0.040))
    freq = np.linspace(300.0, 4000.0, N_FREQ)
    targets = [PredictionTarget(Configuration(l), freq) for l in lengths]
    plain = lambda: predict(draws, model, targets)  # noqa: E731
    mixed = lambda: predict(draws, model, targets, spindle_samples=samples, rng=np.random.default_rng(0))  # noqa: E731
    plain(), mixed()  # warm up
    t_plain = median_time(plain, repeats=5)
    t_mixed = median_time(mixed, repeats=5)
    stack = ConfigurationStack([model.precompute(Configuration(l), freq) for l in lengths])
    assignment = assign_samples(n_draws, n_samples, rng)
    fm_plain = ForwardModel(pm, stack, model)
    v = draws.values
    t_fm_plain = median_time(lambda: fm_plain.frf(v), repeats=9, number=5)
    # a new model each time: the per-sample stacks (coupling and coefficients) are built once per model
    t_fm_first = median_time(lambda: ForwardModel(pm, stack, model, spindle_samples=samples).frf(v, assignment),
                             repeats=5)
    fm_mixed = ForwardModel(pm, stack, model, spindle_samples=samples)
    fm_mixed.frf(v, assignment)
    t_fm_cached = median_time(lambda: fm_mixed.frf(v, assignment), repeats=9, number=5)
    print()
    print(f"Spindle samples: {n_draws} draws x {len(lengths)} clamping lengths x {N_FREQ} lines, {n_samples} samples")
    print(f"{'predict, setup spindle':<44}{t_plain * 1e3:>11.1f} ms")
    print(f"{'predict, spindle samples':<44}{t_mixed * 1e3:>11.1f} ms{t_mixed / t_plain:>11.2f}x")
    print(f"{'ForwardModel.frf (3-length stack), plain':<44}{t_fm_plain * 1e3:>11.2f} ms")
    print(f"{'  with samples, stacks built (first call)':<44}{t_fm_first * 1e3:>11.2f} ms"
          f"{t_fm_first / t_fm_plain:>11.2f}x")
    print(f"{'  with samples, stacks cached':<44}{t_fm_cached * 1e3:>11.2f} ms{t_fm_cached / t_fm_plain:>11.2f}x")


if __name__ == "__main__":
    main()
