"""Speed: the forward model with a spindle term on a grid over the contact (the optimiser's start search).

Sets that share their structural-term values share one spindle-holder coupling (``ForwardModel._unique_sets``);
the naive way couples every set.  Prints the median wall time of ``ForwardModel.frf`` over repeats for both, and
their ratio, measured in the same run (the project's bench, a spindle file without rotations, the term
``spindle_rotation_omitted`` at a non-baseline value shared by every set, 25 and 40 mm in x and y, 2 Hz lines).

Run: ``OMP_NUM_THREADS=1 python benchmarks/forward_shared_terms.py [--sets 289] [--repeats 5]``
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.model import ConfigurationStack
from bayes_rcsa.params import ForwardModel, GrowthLaw, LogUniform, ParameterModel, Uniform, make_term
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", type=int, default=289, help="contact grid size (17 x 17 in the optimiser's search)")
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    cfg = default_bench_config(hidden_effects={"spindle_rotation_omitted": 1.0})
    with tempfile.TemporaryDirectory() as tmp:
        setup = load_setup(write_campaign(generate_campaign(cfg, np.random.default_rng(0)), Path(tmp) / "c"))
        model = setup.model()
        meas = [m for m in setup.measurements if m.clamping_length in (0.025, 0.040)]
        f = meas[0].frf.frequency_hz
        stack = ConfigurationStack([model.precompute(m.configuration, f) for m in meas])
        term = make_term("spindle_rotation_omitted")
        priors = {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e3, 1e8), "g_xf": Uniform(0.0, 0.5),
                  "g_thetaM": Uniform(0.0, 0.5)}
        pm = ParameterModel.from_priors(GrowthLaw(0.025, 0.040, 0.5), priors,
                                        {"c_xf": cfg.c_xf, "c_thetaM": cfg.c_thetaM}, terms=[term], model=model)
        n = a.sets
        rng = np.random.default_rng(1)
        values = {"k_xf": np.geomspace(3e5, 3e7, n), "k_thetaM": rng.permutation(np.geomspace(3e4, 3e7, n)),
                  "g_xf": np.full(n, 0.3), "g_thetaM": np.full(n, 0.3), "c_xf": np.full(n, cfg.c_xf),
                  "c_thetaM": np.full(n, cfg.c_thetaM)}
        for p in term.parameters(model):
            lo, hi = p.prior.bounds
            values[p.name] = np.full(n, lo + 0.6 * (hi - lo))
        shared = ForwardModel(pm, stack, model)
        naive = ForwardModel(pm, stack, model)
        naive._unique_sets = lambda values, n_sets: None  # every set coupled on its own (the way before)
        times = {"shared": [], "naive": []}
        for _ in range(a.repeats):
            for name, fwd in (("shared", shared), ("naive", naive)):
                t0 = time.perf_counter()
                h = fwd.frf(values)
                times[name].append(time.perf_counter() - t0)
        np.testing.assert_allclose(shared.frf(values), naive.frf(values), rtol=1e-12)
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"ForwardModel.frf, {n} contact sets x {h.shape[1]} lines, spindle_rotation_omitted shared by all sets")
    print(f"| way | median s ({a.repeats} repeats) |\n|---|---|")
    for k in ("naive", "shared"):
        print(f"| {k} | {med[k]:.3f} |")
    print(f"ratio naive / shared: {med['naive'] / med['shared']:.1f}")


if __name__ == "__main__":
    main()
