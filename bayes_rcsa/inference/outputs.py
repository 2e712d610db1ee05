"""The files of an identify run: posterior.nc, summary.json and the plots.

:func:`write_outputs` writes what :func:`.identify.identify` returned; nothing
here samples or changes a result.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..params.model import PARAMETER_MODEL_ATTR
from . import results as R
from .band import band_mask
from .identify import IdentificationResult, corner_columns, predict_frf, sampling_labels

__all__ = ["write_outputs", "frf_panels"]


def frf_panels(result: IdentificationResult, rng: np.random.Generator, n_draws: int = 300) -> list[dict]:
    """The panels of frf.png: each measurement's |H| against the predicted 5/50/95 % band on its likelihood band.

    Parameters
    ----------
    result : IdentificationResult
    rng : numpy Generator, picks the plotted subset of at most ``n_draws`` draws
    n_draws : int

    Returns
    -------
    list of dict with ``title``, ``frequency_hz`` (n,) Hz, ``measured`` (n,) complex m/N and ``q05``, ``q50``,
    ``q95`` (n,) m/N
    """
    problem = result.problem
    panels = []
    for cfg, frf in problem.all_measurements:
        band = problem.band_of(frf)
        mask = band_mask(frf, band)
        f = frf.frequency_hz[mask]
        h = np.abs(predict_frf(result, cfg, f, max_draws=n_draws, rng=rng))
        q05, q50, q95 = np.quantile(h, [0.05, 0.5, 0.95], axis=0)
        used = any(o.configuration == cfg and o.source == frf.source for o in problem.observations)
        panels.append({"title": f"{cfg.label()}{'' if used else ' (not fitted)'}", "frequency_hz": f,
                       "measured": frf.values[mask], "q05": q05, "q50": q50, "q95": q95})
    return panels


def write_outputs(result: IdentificationResult, out_dir, plots: bool = True) -> list[Path]:
    """Write summary.json, posterior.nc (Bayesian methods) and PNG plots to ``out_dir``.

    trace.png only of a chain (not of accepted importance sampling: its draws are independent).

    Returns
    -------
    list of Path written
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    problem = result.problem
    if result.bayesian:
        written.append(_write_posterior(result, out / "posterior.nc"))
    if plots:
        from . import plots as P

        labels = sampling_labels(problem.parameters)
        if result.chain is not None:  # independent importance draws have no trace
            written.append(P.trace_plot(result.chain.chain, labels, result.chain.burn, out / "trace.png"))
        if result.bayesian:
            cols = corner_columns(problem.parameters)
            written.append(P.corner_plot(result.flat_theta[:, cols], [labels[i] for i in cols], out / "corner.png"))
        written.append(P.frf_plot(frf_panels(result, np.random.default_rng(result.seed)), out / "frf.png"))
    R.write_summary(out / "summary.json", result.summary)
    written.append(out / "summary.json")
    return written


def _write_posterior(result: IdentificationResult, path: Path) -> Path:
    from ..store import write_posterior
    from .diagnostics import build_inference_data

    problem = result.problem
    nc, nd, _ = result.theta.shape
    flat = result.flat_theta
    pm = problem.parameters
    values = pm.values(flat)
    post = {n: values[n].reshape(nc, nd) for n in pm.names}
    lengths = np.array(sorted({round(c.clamping_length, 12) for c, _ in problem.all_measurements}))
    kx, kt = pm.contact(values, lengths)[:2]
    post["k_xf_at_length"] = kx.reshape(nc, nd, -1)
    post["k_thetaM_at_length"] = kt.reshape(nc, nd, -1)
    post["natural_frequency"] = result.natural_frequency
    lik = problem.likelihood.with_tempering(result.tempering)
    ll = np.concatenate([lik.pointwise(flat[a : a + 256]) for a in range(0, flat.shape[0], 256)])
    obs = problem.observations
    constant = {
        "frequency_hz": problem.likelihood.stack.frequency_hz,
        "line_measurement": problem.likelihood.stack.index,
        "fit_clamping_length": np.array([o.configuration.clamping_length for o in obs]),
        "band_lo_hz": np.array([o.band.lo_hz for o in obs]),
        "band_hi_hz": np.array([o.band.hi_hz for o in obs]),
        "measured_natural_frequency": np.array([e["measured_hz"] if e["measured_hz"] is not None else np.nan
                                                for e in result.summary["natural_frequencies"]]),
        "measurement_clamping_length": np.array([c.clamping_length for c, _ in problem.all_measurements]),
    }
    labels = [f"{c.label()} [{f.source}]" for c, f in problem.all_measurements]
    idata = build_inference_data(
        posterior=post,
        log_prob=result.log_prob,
        log_likelihood=ll.reshape(nc, nd, -1),
        observed=problem.likelihood.data,
        constant=constant,
        dims={
            "k_xf_at_length": ["clamping_length"], "k_thetaM_at_length": ["clamping_length"],
            "natural_frequency": ["measurement"], "frequency_hz": ["line"], "line_measurement": ["line"],
            "fit_clamping_length": ["fit_measurement"], "band_lo_hz": ["fit_measurement"], "band_hi_hz": ["fit_measurement"],
            "measured_natural_frequency": ["measurement"], "measurement_clamping_length": ["measurement"],
        },
        coords={"clamping_length": lengths, "measurement": labels, "line": np.arange(problem.likelihood.n_lines),
                "fit_measurement": [o.source for o in obs]},
        attrs={"method": problem.method, "seed": result.seed, "converged": result.summary["converged"],
               "tempering": result.tempering, "growth_bound": problem.growth.growth_bound,
               "l_a": problem.growth.l_a, "l_b": problem.growth.l_b, "created_by": "bayes_rcsa identify",
               # the whole parameter model (priors, fixed values, terms): predictions never re-read the setup
               PARAMETER_MODEL_ATTR: json.dumps(pm.to_dict()),
               **{f"fixed_{k}": float(v) for k, v in pm.fixed.items()}},
    )
    return write_posterior(idata, path)
