"""The minimal Python API: load a setup, identify, save, reload, draw, predict.

The same steps as ``bayes-rcsa identify`` followed by ``bayes-rcsa predict``,
on the bundled example campaign (bayes_rcsa/data/example: 25-40 mm, X and Y):

1. :func:`bayes_rcsa.io.load_setup` reads the setup and its measurements;
2. :func:`bayes_rcsa.inference.build_problem_from_setup` and
   :func:`bayes_rcsa.inference.identify` fit the contact from 25 and 40 mm
   (Method II);
3. :func:`bayes_rcsa.inference.write_outputs` saves summary.json and
   posterior.nc (what ``bayes-rcsa identify --out`` writes);
4. :func:`bayes_rcsa.posterior.load_posterior` reads the draws back with
   their parameter model (growth law, model terms);
5. :meth:`PosteriorDraws.contact` gives the contact stiffness of every draw
   at any clamping length, and :func:`bayes_rcsa.posterior.predictive_frf`
   the tool-point FRF of every draw;
6. :func:`bayes_rcsa.posterior.run_prediction` makes the credible intervals
   of the natural frequencies that ``bayes-rcsa predict`` reports.

Run::

    python examples/posterior_sampling.py [--out DIR]     # converged fit, about a minute
    python examples/posterior_sampling.py --quick         # short chains (not converged), ~15 s

(``BAYES_RCSA_QUICK=1`` also selects the reduced run.)  Without ``--out`` the
files go to a temporary directory that is removed at the end.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from bayes_rcsa.data import example_setup
from bayes_rcsa.inference import IdentificationOptions, SamplerSettings, build_problem_from_setup, identify, write_outputs
from bayes_rcsa.io import load_setup
from bayes_rcsa.model import Configuration
from bayes_rcsa.posterior import load_posterior, predictive_frf, run_prediction


def quick_requested(argv=None) -> bool:
    """``--quick`` on the command line or ``BAYES_RCSA_QUICK=1`` in the environment."""
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK", "") not in ("", "0")


def fit_and_save(out_dir: Path, quick: bool, seed: int = 0) -> Path:
    """Steps 1-3: identify from 25 and 40 mm and write ``out_dir/posterior.nc``; returns its path."""
    setup = load_setup(example_setup())
    options = IdentificationOptions.from_setup(setup.extra, method="multi", lengths=(0.025, 0.040))
    settings = SamplerSettings(max_steps=80, check_every=80, progress=False) if quick else SamplerSettings(progress=False)
    result = identify(build_problem_from_setup(setup, options), seed=seed, settings=settings)
    used = ", ".join(f"{m['clamping_length'] * 1e3:g} mm {m['direction']}" for m in result.summary["measurements_used"])
    print(f"identified from {used}; converged: {result.summary['converged']}")
    write_outputs(result, out_dir, plots=False)
    return out_dir / "posterior.nc"


def main(quick: bool | None = None, out: Path | None = None, seed: int = 0) -> dict:
    """Run steps 1-6; returns {"posterior": path or None, "stiffness": ..., "frequencies": {(length, dir): q}}."""
    quick = quick_requested() if quick is None else quick
    if out is None and "--out" in sys.argv[1:-1]:
        out = Path(sys.argv[sys.argv.index("--out") + 1])
    with tempfile.TemporaryDirectory() as tmp:
        path = fit_and_save(Path(out) if out is not None else Path(tmp), quick, seed)

        draws = load_posterior(path)                       # step 4
        print(f"reloaded {draws.n_draws} draws of {', '.join(draws.parameters.names)} from {path.name}")

        lengths = [0.025, 0.030, 0.035, 0.040]               # step 5: contact at any clamping length
        kx, kt = draws.contact(lengths)[:2]
        stiffness = {}
        for j, length in enumerate(lengths):
            qx, qt = np.quantile(kx[:, j], [0.05, 0.5, 0.95]), np.quantile(kt[:, j], [0.05, 0.5, 0.95])
            stiffness[length] = (qx, qt)
            print(f"  {length * 1e3:4.0f} mm: k_xf {qx[1]:.4g} [{qx[0]:.4g}, {qx[2]:.4g}] N/m, "
                  f"k_thetaM {qt[1]:.4g} [{qt[0]:.4g}, {qt[2]:.4g}] N m/rad")
        setup = load_setup(example_setup())
        sub = draws.subset(200, np.random.default_rng(seed))
        f = np.linspace(600.0, 1400.0, 401)                # Hz
        h = predictive_frf(sub, setup.model(), Configuration(0.030, "x"), f)
        print(f"FRF draws at 30 mm, X: array {h.shape} (draws x lines), median peak |H| "
              f"{np.median(np.abs(h).max(axis=1)):.3g} m/N")

        run = run_prediction(setup, path, [0.030, 0.035], seed=seed)   # step 6
        freqs = {}
        for mode in run.prediction.modes:
            if mode.dominant:
                q, c = mode.natural_frequency_hz, mode.configuration
                freqs[(c.clamping_length, c.direction)] = q
                print(f"  {c.clamping_length * 1e3:.0f} mm {c.direction}: natural frequency {q['q50']:.1f} Hz "
                      f"[{q['q05']:.1f}, {q['q95']:.1f}] (90 %), measured {mode.measured_hz:.1f} Hz")
        return {"posterior": path if out is not None else None, "stiffness": stiffness, "frequencies": freqs}


if __name__ == "__main__":
    main()
