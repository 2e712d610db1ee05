"""``bayes-rcsa update`` as one library call: cuts + hammer posterior -> updated posterior and its report.

Steps: read and complete the cuts (:mod:`.data`), the draws' FRFs at every
cut setup (:mod:`.frf`), the inverse limits at the cut speeds per ratio node
(:func:`~.likelihood.inverse_limits_at_cuts`), importance re-weighting
(:mod:`.update`), optionally hammer-only vs hammer + cuts lobes and
recommendations on a speed grid (:mod:`.compare`), and the document of
``update.json``.  :func:`write_update` writes the files.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .coefficients import CoefficientPrior
from .likelihood import DEFAULT_LABEL_ERROR, BoundaryWidth, CutGroup, CutLikelihood, inverse_limits_at_cuts
from .update import UpdateSettings, importance_update, weighted_quantile

__all__ = ["UpdateRun", "run_update", "write_update"]

_Q = (0.05, 0.5, 0.95)


@dataclass
class UpdateRun:
    """Everything ``update`` computed.

    Attributes
    ----------
    document : dict, the content of update.json
    result : UpdateResult (its ``draw`` indexes ``draws``)
    dynamics : CutDynamics
    cuts : CutSet
    attrs : dict, attributes of the updated posterior.nc
    warnings : list of str
    draws : PosteriorDraws the result's ``draw`` refers to (the hammer draws, or the MCMC samples)
    """

    document: dict
    result: object
    dynamics: object
    cuts: object
    attrs: dict
    warnings: list = field(default_factory=list)
    draws: object = None


def _q(values, weights=None) -> list[float]:
    v = np.asarray(values, dtype=float)
    w = np.full(v.size, 1.0 / v.size) if weights is None else weights
    return [float(x) for x in weighted_quantile(v, w, _Q)]


def run_update(setup_path, posterior_path, cuts_path, cutting, clamping_length, prior: CoefficientPrior,
               width: BoundaryWidth | None = None, label_error: float = DEFAULT_LABEL_ERROR, method: str = "zoa",
               options=None, settings: UpdateSettings | None = None, n_draws: int | None = None, seed: int = 0,
               tool: str | None = None, speeds=None, level: float = 0.95, tolerances=None,
               max_depth: float | None = None, mcmc=None) -> UpdateRun:
    """Update the posterior ``posterior_path`` with the cut outcomes of ``cuts_path``.

    Parameters
    ----------
    setup_path, posterior_path, cuts_path : paths
    cutting : CuttingConditions, the command's geometry (cuts may override immersion and feed)
    clamping_length : float or None, m, for cuts without their own
    prior : CoefficientPrior
    width : BoundaryWidth (default fixed 0.1)
    label_error : float
    method : stability method name
    options : MethodOptions or None
    settings : UpdateSettings
    n_draws : int or None, hammer draws used (None: all)
    seed : int, the seed of every random choice (draw subset, growth transfer, particles, resampling)
    tool : str or None, tool of cuts without one
    speeds : (n_speed,) rpm or None; when given, hammer-only vs updated lobes and recommendations at
        ``clamping_length`` with ``cutting`` are compared, and each cut's move of the recommendation
    level, tolerances, max_depth : of the recommendation
    mcmc : MCMCSettings or None; when the ESS of the draws falls below ``settings.min_ess`` the posterior is
        sampled by the MCMC fallback (:mod:`.mcmc`) with these settings, or the update is refused (None)

    Returns
    -------
    UpdateRun
    """
    from ..stability.posterior_frf import flute_length
    from ..stability.tests_io import read_cut_table
    from .data import check_supported, cut_groups, prepare_cuts
    from .frf import posterior_dynamics
    from .compare import compare_recommendations, grid_limits

    t0 = time.perf_counter()
    width = width or BoundaryWidth()
    settings = settings or UpdateSettings()
    rng = np.random.default_rng(seed)
    table = read_cut_table(cuts_path)
    from ..io import load_setup

    setup0 = load_setup(setup_path, load_data=False, load_spindle=False)
    cuts = prepare_cuts(table, cutting, clamping_length, setup0.tools, tool,
                        lambda name: flute_length(setup0.tools[name]))
    setups = cuts.setups()
    default_tool = tool if tool is not None else (next(iter(setup0.tools)) if len(setup0.tools) == 1 else None)
    compare_key = None
    if speeds is not None and clamping_length is not None and default_tool is not None:
        compare_key = (float(clamping_length), default_tool)
        if compare_key not in setups:
            setups = setups + [compare_key]
    dyn = posterior_dynamics(setup_path, posterior_path, setups, n_draws, rng)
    groups = cut_groups(cuts, dyn.frfs, dyn.frequency_hz)
    inverse = inverse_limits_at_cuts(groups, cuts.n_cuts, prior, method, options)
    check_supported(cuts, inverse)
    likelihood = CutLikelihood(inverse, cuts.depth_m, cuts.chatter, label_error)
    result = importance_update(likelihood, prior, width, rng, settings, refuse=mcmc is None)
    start, draws_out, mcmc_info = result, dyn.draws, None
    warnings: list[str] = []
    from ..stability.coefficients import read_coefficient_draws

    if read_coefficient_draws(posterior_path) is not None:
        warnings.append(f"{posterior_path} already carries cutting-coefficient draws (an earlier update): its cuts "
                        "shaped the contact draws but its K_t/K_r draws are replaced by the --kt/--kr prior; to combine "
                        "campaigns, update the hammer posterior once with all cuts in one file")
    if result.ess_draws < settings.min_ess:  # only reachable with the MCMC fallback
        from .mcmc import mcmc_update

        warnings.append(f"importance re-weighting collapsed (ESS {result.ess_draws:.1f} of {result.n_draws} hammer "
                        f"draws, below {settings.min_ess:g}); the posterior was sampled by MCMC instead, with the "
                        "hammer posterior approximated by a Gaussian in its sampling coordinates")
        draws_out, result, mcmc_info = mcmc_update(dyn, cuts, prior, width, label_error, method, options, start,
                                                   rng, start.n_draws, mcmc)
        if not mcmc_info["converged"]:
            warnings.append(f"the MCMC fallback ({mcmc_info['convergence']}); give more --mcmc-steps")
    elif result.ess_draws < min(4 * settings.min_ess, 0.5 * result.n_draws):
        warnings.append(f"the cuts leave {result.ess_draws:.0f} effective hammer draws of {result.n_draws}; the "
                        "updated posterior repeats few draws (use more --draws for smoother results)")
    contact = {}
    for name in dyn.draws.sampled:
        contact[name] = {"before": _q(dyn.draws.values[name]), "after": _q(draws_out.values[name][result.draw])}
    for name, values in (("kt", result.kt), ("kr", result.kr)):
        lo, hi = np.quantile(values, [0.05, 0.95])
        plo, phi = np.quantile(result.prior_kt if name == "kt" else result.prior_kr, [0.01, 0.99])
        if (prior.level_sd > 0) and (lo <= plo or hi >= phi):
            warnings.append(f"the updated K_{name[1]} interval [{lo:.4g}, {hi:.4g}] Pa reaches the edge of its prior "
                            f"[{plo:.4g}, {phi:.4g}] Pa (1-99 %): widen --k{name[1]} V±T")
    per_cut = []
    for i, pc in enumerate(result.per_cut):
        per_cut.append({"line": int(cuts.table.line[i]), "spindle_speed_rpm": float(cuts.speed_rpm[i]),
                        "clamping_length_m": float(cuts.clamping_length_m[i]), "tool": cuts.tool[i],
                        "radial_immersion": cuts.cutting[i].radial_immersion, "feed_direction": cuts.cutting[i].feed,
                        **pc})
    doc = {
        "created_by": "bayes_rcsa update",
        "inputs": {"setup": str(setup_path), "posterior": str(posterior_path), "cuts": str(cuts_path),
                   "n_cuts": cuts.n_cuts, "n_chatter": int(np.sum(cuts.chatter)), "method": method, "seed": seed,
                   "coefficient_prior": prior.describe(), "boundary_width": width.describe(),
                   "label_error": label_error, "particles_per_draw": settings.particles_per_draw,
                   "min_ess": settings.min_ess},
        "sampler": "importance" if mcmc_info is None else "mcmc",
        "ess": {"draws": result.ess_draws, "particles": result.ess_particles, "n_draws": result.n_draws,
                "n_particles": result.n_particles, "importance_draws": start.ess_draws},
        "mcmc": mcmc_info,
        "log_evidence": result.log_evidence,
        "kt_pa": {"quantiles": list(_Q), "before": _q(result.prior_kt), "after": _q(result.kt)},
        "kr_pa": {"quantiles": list(_Q), "before": _q(result.prior_kr), "after": _q(result.kr)},
        "boundary_width": {"after": _q(result.width)} if width.sampled else {"fixed": width.lo},
        "contact": contact,
        "cuts": per_cut,
        "source": dyn.source,
    }
    if compare_key is not None:
        def grid_inverse(gx, gy):
            grid = CutGroup(gx, gy, dyn.frequency_hz, cutting, np.arange(np.size(speeds)), np.asarray(speeds, float))
            return inverse_limits_at_cuts([grid], np.size(speeds), prior, method, options)

        inv_grid = grid_inverse(*dyn.frfs[compare_key])
        before = grid_limits(inv_grid, start.particle_draw, start.particle_u, start.particle_node)
        if mcmc_info is None:
            after = before
        else:
            from .frf import frfs_of_draws

            after = grid_limits(grid_inverse(*frfs_of_draws(draws_out, dyn.model, {
                k: v for k, v in dyn.caches.items() if k[:2] == compare_key})[compare_key]),
                result.particle_draw, result.particle_u, result.particle_node)
        fl = flute_length(setup0.tools[compare_key[1]])
        doc["lobes"] = {"clamping_length_m": compare_key[0], "tool": compare_key[1],
                        **compare_recommendations(speeds, before, after, result.weights, result.loo_weights,
                                                  result.n_draws, rng, level, tolerances, max_depth, fl)}
        for pc, mv in zip(doc["cuts"], doc["lobes"]["per_cut"]):
            pc["recommendation_moved"] = mv
    doc["seconds"] = time.perf_counter() - t0
    doc["warnings"] = warnings
    attrs = {"cuts_file": str(cuts_path), "n_cuts": cuts.n_cuts, "cut_update_ess_draws": result.ess_draws,
             "cut_update": {"coefficient_prior": prior.describe(), "boundary_width": width.describe(),
                            "label_error": label_error, "method": method}}
    attrs["cut_update_sampler"] = doc["sampler"]
    return UpdateRun(doc, result, dyn, cuts, attrs, warnings, draws_out)


def write_update(run: UpdateRun, out_dir) -> list:
    """Write ``posterior.nc`` and ``update.json`` into ``out_dir`` (which must exist); returns the paths."""
    from pathlib import Path

    from .outputs import write_update_json, write_updated_posterior

    out = Path(out_dir)
    p = write_updated_posterior(out / "posterior.nc", run.document["inputs"]["posterior"],
                                run.draws if run.draws is not None else run.dynamics.draws, run.result, run.attrs)
    j = write_update_json(out / "update.json", run.document)
    return [p, j]
