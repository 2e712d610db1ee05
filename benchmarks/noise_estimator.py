"""Bias and spread of the two relative-noise estimators on simulated FRFs (issue #41: one noise estimator).

Two model-free estimators of the relative noise ``sigma`` (``E|e|^2 = sigma^2 |H|^2``, circular complex Gaussian)
existed: second differences normalised by the centre line's magnitude (``discrepancy/noise.py``, the one that
survives as :func:`bayes_rcsa.stats.noise.relative_noise_scale`) and third differences normalised by the
differenced magnitudes (the former ``spindle/noise.py::estimate_relative_noise``, kept here as
:func:`third_differences` for the comparison).  Both take the median over the lines.

FRFs (noise-free, then ``REPS`` noise realisations with fixed seeds):

* ``1 mode``: one lightly damped mode (1500 Hz, zeta 0.01) in 500-3500 Hz;
* ``2 modes``: the spindle unit test's FRF (700 Hz / 0.02 and 2100 Hz / 0.01) in 200-4000 Hz;
* ``6 modes``: a dense flange-like FRF, six modes 450-3600 Hz, zeta 0.01-0.03, residues of alternating sign
  (antiresonances between the modes), 200-4000 Hz;
* ``tool point``: the synthetic bench's true tool-point FRF (clamping length 40 mm, X) in 500-3500 Hz;
* ``flange``: the synthetic bench's true spindle flange receptance h11 (X) in 200-4000 Hz;

each on 200, 500, 1000, 2000 and 3801 equally spaced lines (3801: the spindle workflow's grid, the synthetic
  artifact's default 200-4000 Hz in 1-Hz steps), at 0.5 % and 2 % relative noise.  Printed per case:
the mean of estimate / true sigma minus one (bias, %) and the standard deviation of that ratio (spread, %).

Run: ``python3 -m benchmarks.noise_estimator`` (about a minute on one core).
"""

from __future__ import annotations

import math

import numpy as np

from bayes_rcsa.stats.noise import relative_noise_scale

REPS = 200
LINES = (200, 500, 1000, 2000, 3801)
RELATIVE = (0.005, 0.02)


def third_differences(values: np.ndarray) -> float:
    """The retired spindle estimator: median of |D_k| / sqrt(sum_j c_j^2 |H_{k+j}|^2) / sqrt(ln 2), c = (-1, 3, -3, 1)."""
    c = np.array([-1.0, 3.0, -3.0, 1.0])
    h = np.asarray(values, dtype=complex)
    d = np.convolve(h, c[::-1], mode="valid")
    scale = np.sqrt(np.convolve(np.abs(h) ** 2, c[::-1] ** 2, mode="valid"))
    ok = scale > 0
    return float(np.median(np.abs(d[ok]) / scale[ok]) / math.sqrt(math.log(2.0)))


def modal(f: np.ndarray, modes) -> np.ndarray:
    """Sum of ``a / (wr^2 - w^2 + 2 j zeta wr w)`` over ``modes`` (fr Hz, zeta, a), (n,) complex."""
    w = 2 * np.pi * f
    h = np.zeros(f.size, complex)
    for fr, zeta, a in modes:
        wr = 2 * np.pi * fr
        h += a / (wr**2 - w**2 + 2j * zeta * wr * w)
    return h


def cases():
    """(name, band (lo, hi) Hz, function of the grid (n,) Hz -> (n,) complex noise-free FRF)."""
    from bayes_rcsa.model import Configuration
    from bayes_rcsa.synthetic.bench import true_spindle_receptance, true_tool_point_frf
    from bayes_rcsa.synthetic.config import default_bench_config

    bench = default_bench_config()
    six = [(450.0, 0.02, 1.0), (900.0, 0.015, -0.6), (1400.0, 0.01, 0.8), (2000.0, 0.03, -0.5),
           (2800.0, 0.015, 0.7), (3600.0, 0.02, -0.4)]
    return [
        ("1 mode", (500.0, 3500.0), lambda f: modal(f, [(1500.0, 0.01, 1.0)])),
        ("2 modes", (200.0, 4000.0), lambda f: modal(f, [(700.0, 0.02, 1.0), (2100.0, 0.01, 0.5)])),
        ("6 modes", (200.0, 4000.0), lambda f: modal(f, six)),
        ("tool point", (500.0, 3500.0), lambda f: true_tool_point_frf(bench, Configuration(0.04, "x", "tool"), f)),
        ("flange", (200.0, 4000.0), lambda f: true_spindle_receptance(bench, "x", f).block[:, 0, 0]),
    ]


def main() -> None:
    print(f"estimate / true relative noise - 1 over {REPS} realisations: mean (bias) and sd (spread), in %")
    print(f"{'FRF':<11}{'lines':>6}{'sigma':>7} | {'2nd diff bias':>13}{'spread':>8} | {'3rd diff bias':>13}{'spread':>8}")
    for ci, (name, (lo, hi), frf) in enumerate(cases()):
        for n in LINES:
            f = np.linspace(lo, hi, n)
            h = frf(f)
            for ri, rel in enumerate(RELATIVE):
                rng = np.random.default_rng([ci, n, ri])
                z = rng.standard_normal((REPS, 2, n))
                noisy = h + rel * np.abs(h) * (z[:, 0] + 1j * z[:, 1]) / math.sqrt(2.0)
                r2 = np.array([relative_noise_scale(y) for y in noisy]) / rel - 1.0
                r3 = np.array([third_differences(y) for y in noisy]) / rel - 1.0
                print(f"{name:<11}{n:>6}{rel:>7.3f} | {100 * r2.mean():>13.1f}{100 * r2.std():>8.1f} | "
                      f"{100 * r3.mean():>13.1f}{100 * r3.std():>8.1f}")


if __name__ == "__main__":
    main()
