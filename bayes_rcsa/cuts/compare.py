"""Hammer only against hammer + N cuts: the lobes' median limit and the robust recommendation, and what each cut moved.

The limits of every particle on a speed grid come from the same inverse
limits as the likelihood (one method call per ratio node, exact scaling by
the level).  "Hammer only" is the particle set with equal weights (the
hammer posterior with the coefficient prior), "hammer + N cuts" the weighted
set; both are turned into equally weighted draws by systematic resampling
(same count) and passed to :func:`bayes_rcsa.stability.recommend.recommend`.
Each cut's move is the recommendation with all cuts against the one without
that cut (leave-one-cut-out weights, no new stability evaluation).
"""

from __future__ import annotations

import numpy as np

from ..stability.probabilistic import depth_quantiles
from ..stability.recommend import recommend
from .update import systematic_resample

__all__ = ["grid_limits", "compare_recommendations"]


def grid_limits(inverse_grid, particle_draw, u, node) -> np.ndarray:
    """(n_particles, n_speed) m from (n_nodes, n_draws, n_speed) inverse limits."""
    inv = inverse_grid[np.asarray(node), np.asarray(particle_draw)] * np.exp(np.asarray(u, dtype=float))[:, None]
    with np.errstate(divide="ignore"):
        return 1.0 / inv


def _rec_dict(rec) -> dict | None:
    if rec is None:
        return None
    return {"spindle_speed_rpm": rec.spindle_speed_rpm, "depth_m": rec.depth_m,
            "p_stable": rec.p_stable_neighbourhood, "binding": rec.binding}


def _summary(speeds, limits, level, tolerances, max_depth, flute_length) -> dict:
    rec = recommend(speeds, limits, level, tolerances, max_depth=max_depth, flute_length=flute_length)
    q = depth_quantiles(limits)
    return {"recommended": _rec_dict(rec["recommended"]), "note": rec["note"],
            "median_limit_m": [float(v) for v in q[0.5]], "q05_limit_m": [float(v) for v in q[0.05]]}


def compare_recommendations(speeds, before_limits, limits, weights, loo_weights, n_draws: int, rng,
                            level: float = 0.95, tolerances=None, max_depth=None, flute_length=None) -> dict:
    """Recommendations before and after the cuts, and each cut's move.

    Parameters
    ----------
    speeds : (n_speed,) rpm
    before_limits : (n_before, n_speed) m, the hammer-only particles (equal weights)
    limits : (n_particles, n_speed) m, the updated particles
    weights : (n_particles,) after all cuts
    loo_weights : (n_cuts, n_particles), without each cut
    n_draws : int, draws resampled for each recommendation
    rng : numpy.random.Generator
    level, tolerances, max_depth, flute_length : as :func:`bayes_rcsa.stability.recommend.recommend`

    Returns
    -------
    dict ``{"speed_rpm", "hammer_only", "with_cuts", "per_cut": [{"recommended_without", "speed_moved_rpm",
    "depth_moved_m"}]}``.
    """
    pick = lambda w: limits[systematic_resample(w, n_draws, rng)]  # noqa: E731
    flat = np.full(before_limits.shape[0], 1.0 / before_limits.shape[0])
    before = _summary(speeds, before_limits[systematic_resample(flat, n_draws, rng)], level, tolerances, max_depth,
                      flute_length)
    after = _summary(speeds, pick(weights), level, tolerances, max_depth, flute_length)
    per_cut = []
    a = after["recommended"]
    for w in loo_weights:  # one recommendation per cut (the cut count is small)
        r = recommend(speeds, pick(w), level, tolerances, max_depth=max_depth, flute_length=flute_length)["recommended"]
        d = _rec_dict(r)
        moved = (None, None) if d is None or a is None else (a["spindle_speed_rpm"] - d["spindle_speed_rpm"],
                                                             a["depth_m"] - d["depth_m"])
        per_cut.append({"recommended_without": d, "speed_moved_rpm": moved[0], "depth_moved_m": moved[1]})
    return {"speed_rpm": [float(s) for s in speeds], "level": level, "hammer_only": before, "with_cuts": after,
            "per_cut": per_cut}
