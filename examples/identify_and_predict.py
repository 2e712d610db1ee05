"""Python API: identify the contact from two clamping lengths, predict two more.

The same steps as ``bayes-rcsa identify`` and ``bayes-rcsa predict``, kept in
memory: Method II (25 and 40 mm), then credible intervals of the first
natural frequency at the held-out 30 and 35 mm, compared with the bundled
measurements.  Takes about half a minute.
Run: ``python examples/identify_and_predict.py``; ``--quick`` (or
``BAYES_RCSA_QUICK=1``) stops the chains after 80 steps (not converged; the
medians are already settled), as the test suite does.
"""

import os
import sys

import numpy as np

from bayes_rcsa.data import example_setup
from bayes_rcsa.inference.identify import identify
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
from bayes_rcsa.inference.sampler import SamplerSettings
from bayes_rcsa.io import load_setup
from bayes_rcsa.model import Configuration
from bayes_rcsa.posterior import PredictionTarget, predict
from bayes_rcsa.posterior.draws import draws_from_result


def quick_requested(argv=None) -> bool:
    """``--quick`` on the command line or ``BAYES_RCSA_QUICK=1`` in the environment."""
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK", "") not in ("", "0")


def main(seed: int = 0, quick: bool | None = None) -> dict:
    quick = quick_requested() if quick is None else quick
    setup = load_setup(example_setup())
    options = IdentificationOptions.from_setup(setup.extra, method="multi", lengths=(0.025, 0.040))
    problem = build_problem_from_setup(setup, options)
    settings = SamplerSettings(max_steps=80, check_every=80, progress=False) if quick else SamplerSettings(progress=False)
    result = identify(problem, seed=seed, settings=settings)
    s = result.summary
    # importance sampling (the default) has no chain: no R-hat, and the ESS is the weights' effective sample size
    how = s["sampler"]
    print(f"converged: {s['converged']} ({how['mode']}); warnings: {s['warnings'] or 'none'}")
    for name, p in s["parameters"].items():
        rhat = "" if p["rhat"] is None else f"  R-hat {p['rhat']:.3f}"
        print(f"  {name:9s} median {p['q50']:.4g} [{p['q05']:.4g}, {p['q95']:.4g}]{rhat}  ESS {p['ess_bulk']:.0f}")

    draws = draws_from_result(result).subset(1000, np.random.default_rng(seed))
    model = setup.model()
    out = {}
    for m in setup.measurements:
        if m.direction != "x" or m.clamping_length not in (0.030, 0.035):
            continue
        target = PredictionTarget(Configuration(m.clamping_length, "x"), m.frf.frequency_hz, m.frf)
        mode = next(md for md in predict(draws, model, [target]).modes if md.dominant)
        q = mode.natural_frequency_hz
        out[m.clamping_length] = q
        print(f"held out {m.clamping_length * 1e3:.0f} mm: predicted {q['q50']:.1f} Hz "
              f"[{q['q05']:.1f}, {q['q95']:.1f}], measured {mode.measured_hz:.1f} Hz")
    return out


if __name__ == "__main__":
    main()
