"""Shared helpers of the design tests and benchmarks/design.py (this module holds no tests).

A replicate is one synthetic campaign from the bench (independent FE model,
no hidden effect, 2 % noise, x direction, 8 Hz lines) with measurements at
25, 27, 35 and 40 mm.  The truth (k_xf, k_thetaM at l_a and one growth
factor g for both) is drawn from the prior the setup states, as in the
calibration test, so that coverage statements are about the prior the
growth law encodes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bayes_rcsa.inference import IdentificationOptions, SamplerSettings, build_problem_from_setup, identify, write_outputs
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

__all__ = ["PRIOR_KX", "PRIOR_KT", "Q", "LENGTHS", "campaign", "fit", "quick"]

PRIOR_KX = (1.0e6, 4.0e6)
PRIOR_KT = (1.5e5, 1.5e6)
Q = 0.5
LENGTHS = (0.025, 0.027, 0.035, 0.040)


def quick() -> SamplerSettings:
    """Cheap sampler settings (ample for 5 %/95 % quantiles, cf. the calibration test)."""
    return SamplerSettings(tau_factor=30.0, ess_min=200.0, rhat_max=1.02, check_every=100, progress=False)


def campaign(seed: int, out: Path):
    """(BenchConfig, setup path) of one replicate written to ``out``."""
    rng = np.random.default_rng(seed)
    kx = 10 ** rng.uniform(*np.log10(PRIOR_KX))
    kt = 10 ** rng.uniform(*np.log10(PRIOR_KT))
    g = rng.uniform(0.0, Q)
    cfg = default_bench_config(directions=("x",), clamping_lengths=LENGTHS, frequency_step=8.0, k_xf=kx, k_thetaM=kt,
                               growth=g, prior_k_xf=PRIOR_KX, prior_k_thetaM=PRIOR_KT, growth_bound=Q,
                               clamping_range=(0.025, 0.040))
    camp = generate_campaign(cfg, rng)
    write_campaign(camp, out, overwrite=True)
    return cfg, out / "setup.toml"


def fit(setup_path: Path, lengths, out: Path, seed: int):
    """Identify from the measurements at ``lengths``; returns (result, posterior.nc path)."""
    setup = load_setup(setup_path)
    prob = build_problem_from_setup(setup, IdentificationOptions(lengths=tuple(lengths)))
    res = identify(prob, seed=seed, settings=quick(), max_draws=2000)
    write_outputs(res, out, plots=False)
    return res, out / "posterior.nc"
