"""The posterior draws and their tool-point FRFs at every (clamping length, tool) of a cut file.

One set of draws serves every cut setup (the same θ_d at every clamping
length), so that the cut likelihood of draw d multiplies the evidence of all
its cuts.  A single-length fit gets the growth law's prior once for all
lengths (:func:`bayes_rcsa.posterior.growth_prior.transfer_draws`); the
returned draws carry those growth factors, and the updated posterior stores
them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SetupError

__all__ = ["CutDynamics", "posterior_dynamics", "configuration_caches", "frfs_of_draws"]


@dataclass(frozen=True)
class CutDynamics:
    """Draws and their FRFs.

    Attributes
    ----------
    setup : Setup
    draws : PosteriorDraws (after the subset and the length transfer)
    frequency_hz : (n_freq,) Hz, the X spindle file's lines inside both spindle files' range
    frfs : dict (clamping length m, tool) -> (frf_x, frf_y), each (n_draws, n_freq) complex m/N
    source : dict, JSON-able provenance
    model : ToolPointModel of the setup
    caches : dict (length, tool, direction) -> the model's precomputation (reused by the MCMC fallback)
    """

    setup: object
    draws: object
    frequency_hz: np.ndarray
    frfs: dict
    source: dict
    model: object = None
    caches: dict | None = None


def posterior_dynamics(setup_path, posterior_path, setups, n_draws: int | None, rng) -> CutDynamics:
    """Draws of ``posterior_path`` and their X/Y tool-point FRFs at every (length, tool) of ``setups``.

    Parameters
    ----------
    setup_path : path of the setup TOML
    posterior_path : path of posterior.nc
    setups : list of (clamping length m, tool name)
    n_draws : int or None, draws used (a random subset; None: all)
    rng : numpy.random.Generator

    Raises
    ------
    SetupError
        A clamping length the posterior cannot predict, a setup without X and Y spindle files.
    """
    from ..io import load_setup
    from ..io.frf import overlap_mask
    from ..posterior import load_posterior
    from ..posterior.growth_prior import transfer_draws
    from ..posterior.prediction_outputs import check_prediction_lengths, posterior_status

    setup = load_setup(setup_path, load_data=False, load_spindle=True)
    for d in ("x", "y"):
        if d not in setup.spindle:
            raise SetupError(f"{setup_path}: [spindle] {d} is needed for cut outcomes (both directions are coupled)")
    lengths = sorted({float(l) for l, _ in setups})
    draws = load_posterior(posterior_path, setup).subset(n_draws, rng)
    try:
        check_prediction_lengths(draws, setup, lengths)
    except SetupError as exc:
        raise SetupError(f"cuts at a clamping length the posterior cannot predict: {exc}") from None
    draws = transfer_draws(draws, setup, lengths, rng)
    sx, sy = setup.spindle["x"].frequency_hz, setup.spindle["y"].frequency_hz
    f = sx[overlap_mask(sx, sy)]
    model = setup.model()
    caches = configuration_caches(model, setups, f)
    frfs = frfs_of_draws(draws, model, caches)
    source = {"setup": str(setup_path), "posterior": str(posterior_path), "n_draws": int(draws.n_draws),
              "method": draws.method, **draws.provenance(), "posterior_status": posterior_status(posterior_path)}
    return CutDynamics(setup, draws, f, frfs, source, model, caches)


def configuration_caches(model, setups, frequency_hz) -> dict:
    """The model's contact-independent precomputation of every (clamping length, tool) in X and Y."""
    from ..model import Configuration

    return {(float(l), tool, d): model.precompute(Configuration(float(l), d, tool), frequency_hz)
            for l, tool in setups for d in ("x", "y")}


def frfs_of_draws(draws, model, caches) -> dict:
    """(frf_x, frf_y), each (n_draws, n_freq) complex m/N, of ``draws`` at every (length, tool) of ``caches``."""
    from ..model import Configuration
    from ..posterior import predictive_frf

    out = {}
    for (l, tool, d), cache in caches.items():  # a few cut setups; each vectorised over draws and lines
        out.setdefault((l, tool), {})[d] = predictive_frf(draws, model, Configuration(l, d, tool),
                                                          cache.frequency_hz, cache=cache)
    return {k: (v["x"], v["y"]) for k, v in out.items()}
