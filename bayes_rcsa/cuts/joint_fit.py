"""The cut term of ``identify --cuts`` from numbers, and the per-draw coefficients after the fit.

:func:`joint_cut_term` builds the :class:`~.joint.CutTerm` that the
identification samples together with the hammer FRFs (checked against the
problem before any sampling); :func:`cut_coefficients` draws (K_t, K_r, w)
for every posterior draw afterwards, with the quantiles summary.json reports.
"""

from __future__ import annotations

import numpy as np

from ..errors import SetupError
from .coefficients import CoefficientPrior
from .likelihood import DEFAULT_BOUNDARY_WIDTH, DEFAULT_LABEL_ERROR, BoundaryWidth

__all__ = ["joint_cut_term", "cut_coefficients", "as_boundary_width"]


def as_boundary_width(width) -> BoundaryWidth:
    """``w`` (fixed) or ``(lo, hi)`` (log-uniform, sampled) -> :class:`BoundaryWidth`."""
    if isinstance(width, BoundaryWidth):
        return width
    if np.ndim(width) == 0:
        return BoundaryWidth(float(width), float(width))
    lo, hi = width
    return BoundaryWidth(float(lo), float(hi))


def joint_cut_term(problem, setup, path, *, flutes: int, kt: float, kr: float, kt_tolerance: float = 0.0,
                   kr_tolerance: float = 0.0, clamping_length: float | None = None, tool: str | None = None,
                   radial_immersion: float | None = None, entry_angle: float | None = None,
                   exit_angle: float | None = None, milling: str = "down", feed: str = "x", pitch_angles=None,
                   boundary_width=DEFAULT_BOUNDARY_WIDTH, label_error: float = DEFAULT_LABEL_ERROR):
    """The :class:`~.joint.CutTerm` of the cut outcomes in ``path`` for ``problem``; checks everything first.

    Parameters
    ----------
    problem : bayes_rcsa.inference.problem.Problem, the identification the cuts join
    setup : bayes_rcsa.io.setup.Setup of the problem (tools, spindle data of both directions)
    path : path of the cut table (spindle_speed_rpm, depth_m, outcome[, clamping_length_m, radial_immersion,
        feed_direction, tool])
    flutes : int; kt, kr : Pa; kt_tolerance, kr_tolerance : relative prior spreads of the force level and of Kr/Kt
    clamping_length : m, of cuts without their own; tool : tool of cuts without their own
    radial_immersion : fraction, or entry_angle, exit_angle : rad; milling, feed, pitch_angles (rad)
    boundary_width : float or (lo, hi), probit width in ln(depth / limit)
    label_error : probability in [0, 0.5) that a cut far from the boundary is reported the other way

    Raises
    ------
    SetupError, DataError
        Implausible coefficients, a cut at a clamping length the fit cannot predict, a setup without both
        spindle directions, speeds outside the band.
    """
    from ..io.checks import warn_all
    from ..io.frf import overlap_mask
    from ..stability.conditions import cutting_conditions
    from ..stability.posterior_frf import flute_length
    from ..stability.tests_io import read_cut_table
    from .data import cut_groups, prepare_cuts
    from .frf import configuration_caches
    from .joint import CutTerm

    cutting, warnings = cutting_conditions(kt=kt, kr=kr, flutes=flutes, radial_immersion=radial_immersion,
                                           entry_angle=entry_angle, exit_angle=exit_angle, milling=milling, feed=feed,
                                           pitch_angles=pitch_angles)
    warn_all(warnings)
    prior = CoefficientPrior.from_tolerances(cutting.kt, kt_tolerance, cutting.kr, kr_tolerance)
    width = as_boundary_width(boundary_width)
    if not (0 <= label_error < 0.5):
        raise SetupError(f"--cut-label-error {label_error}: expected a probability in [0, 0.5)")
    cuts = prepare_cuts(read_cut_table(path), cutting, clamping_length, setup.tools, tool,
                        lambda name: flute_length(setup.tools[name]), option_prefix="--cut-")
    pm = problem.parameters
    lengths = sorted({float(l) for l in cuts.clamping_length_m})
    fitted = sorted({float(o.configuration.clamping_length) for o in problem.observations})
    if pm.growth.has_growth:
        pm.growth.check_lengths(lengths, "cut clamping length")
    elif any(all(abs(l - f) > 1e-9 for f in fitted) for l in lengths):
        raise SetupError(f"--cuts: cuts at clamping length(s) {lengths} m, but this fit (one length, no growth law) "
                         f"predicts only {fitted} m; fit several lengths or cut at a fitted length")
    for d in ("x", "y"):
        if d not in setup.spindle:
            raise SetupError(f"{setup.path}: [spindle] {d} is needed for --cuts (both directions are coupled)")
    sx, sy = setup.spindle["x"].frequency_hz, setup.spindle["y"].frequency_hz
    f = sx[overlap_mask(sx, sy)]
    dummy = {k: (np.zeros((1, f.size), complex),) * 2 for k in cuts.setups()}
    cut_groups(cuts, dummy, f)  # refuses speeds outside the band before any sampling
    model = setup.model()
    return CutTerm(pm, model, configuration_caches(model, cuts.setups(), f), f, cuts, prior, width, label_error)



def cut_coefficients(flat_theta: np.ndarray, term, seed: int):
    """(K_t, K_r, w) for every posterior draw (their conditional given the cuts) and summary.json's ``cuts`` entry.

    Parameters
    ----------
    flat_theta : (n_draws, ndim) sampling coordinates of the posterior draws (chains flattened)
    term : CutTerm of the fit
    seed : int, the run's seed (the coefficients use their own stream of it)

    Returns
    -------
    draws : (kt (n_draws,) Pa, kr (n_draws,) Pa, w (n_draws,))
    info : dict (file, n_cuts, 5/50/95 % quantiles of K_t and K_r, prior, boundary width, label error)
    """
    kt, kr, w = term.coefficient_draws(flat_theta, np.random.default_rng([seed, 23]))
    q = lambda v: [float(x) for x in np.quantile(v, [0.05, 0.5, 0.95])]  # noqa: E731
    info = {"file": str(term.cuts.table.path), "n_cuts": term.cuts.n_cuts, "kt_pa_q05_q50_q95": q(kt),
            "kr_pa_q05_q50_q95": q(kr), "coefficient_prior": term.prior.describe(),
            "boundary_width": term.width.describe(), "label_error": term.label_error}
    return (kt, kr, w), info
