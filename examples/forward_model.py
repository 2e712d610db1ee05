"""Forward model: tool-point FRF of the bundled example at several clamping lengths.

Shows the cached, batched RCSA model: the parameter-independent parts are
computed once per clamping length, then a whole batch of contact parameter
sets is evaluated at once.  Run: ``python examples/forward_model.py``.
"""

import numpy as np

from bayes_rcsa.data import example_setup
from bayes_rcsa.io import load_setup
from bayes_rcsa.model import Configuration, ConfigurationStack
from bayes_rcsa.model.natural_frequencies import natural_frequency


def main() -> dict:
    setup = load_setup(example_setup())
    model = setup.model()
    freq = np.arange(500.0, 3500.0, 1.0)  # Hz
    lengths = (0.025, 0.030, 0.035, 0.040)  # m
    stack = ConfigurationStack([model.precompute(Configuration(l), freq) for l in lengths])

    # 200 contact parameter sets: stiffness scattered by 10 % around a linear growth law
    rng = np.random.default_rng(0)
    growth = 1 + 0.45 * (np.array(lengths) - 0.025) / 0.015
    kx = 1.8e6 * growth * rng.lognormal(0.0, 0.1, (200, 1))     # (200, 4) N/m
    kt = 4.5e5 * growth * rng.lognormal(0.0, 0.1, (200, 1))     # (200, 4) N m/rad
    h = stack.frf(kx, kt, 10.0, 5e-4)                            # (200, 4 * n_freq) m/N

    out = {}
    for length, hl in zip(lengths, stack.split(h)):
        fn = natural_frequency(freq, hl)
        out[length] = np.percentile(fn, [5, 50, 95])
        print(f"clamping {length * 1e3:4.1f} mm: first natural frequency 5/50/95 % = "
              f"{out[length][0]:7.1f} / {out[length][1]:7.1f} / {out[length][2]:7.1f} Hz")
    return out


if __name__ == "__main__":
    main()
