"""Forward model: tool-point FRF of the bundled example at several clamping lengths.

Shows the cached, batched RCSA model: the parameter-independent parts are
computed once per clamping length, then a whole batch of contact parameter
sets is evaluated at once.  Run: ``python examples/forward_model.py``
(about two seconds; ``--quick`` or ``BAYES_RCSA_QUICK=1`` evaluates 50 sets
on 2 Hz lines instead of 200 on 1 Hz lines).
"""

import os
import sys

import numpy as np

from bayes_rcsa.data import example_setup
from bayes_rcsa.io import load_setup
from bayes_rcsa.model import Configuration, ConfigurationStack
from bayes_rcsa.model.natural_frequencies import natural_frequency


def quick_requested(argv=None) -> bool:
    """``--quick`` on the command line or ``BAYES_RCSA_QUICK=1`` in the environment."""
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK", "") not in ("", "0")


def main(quick: bool | None = None) -> dict:
    quick = quick_requested() if quick is None else quick
    n_sets = 50 if quick else 200
    setup = load_setup(example_setup())
    model = setup.model()
    freq = np.arange(500.0, 3500.0, 2.0 if quick else 1.0)  # Hz
    lengths = (0.025, 0.030, 0.035, 0.040)  # m
    stack = ConfigurationStack([model.precompute(Configuration(l), freq) for l in lengths])

    # n_sets contact parameter sets: stiffness scattered by 10 % around a linear growth law
    rng = np.random.default_rng(0)
    growth = 1 + 0.45 * (np.array(lengths) - 0.025) / 0.015
    kx = 1.8e6 * growth * rng.lognormal(0.0, 0.1, (n_sets, 1))  # (n_sets, 4) N/m
    kt = 4.5e5 * growth * rng.lognormal(0.0, 0.1, (n_sets, 1))  # (n_sets, 4) N m/rad
    h = stack.frf(kx, kt, 10.0, 5e-4)                            # (n_sets, 4 * n_freq) m/N

    out = {}
    for length, hl in zip(lengths, stack.split(h)):
        fn = natural_frequency(freq, hl)
        out[length] = np.percentile(fn, [5, 50, 95])
        print(f"clamping {length * 1e3:4.1f} mm: first natural frequency 5/50/95 % = "
              f"{out[length][0]:7.1f} / {out[length][1]:7.1f} / {out[length][2]:7.1f} Hz")
    return out


if __name__ == "__main__":
    main()
