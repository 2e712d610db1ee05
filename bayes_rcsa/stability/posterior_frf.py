"""Tool-point FRFs for the lobes job: posterior-predictive draws, or a measured X/Y pair.

Posterior mode uses the public API of :mod:`bayes_rcsa.posterior`
(``load_posterior``, ``predictive_frf``); measured files are read through
:func:`bayes_rcsa.io.frf.read_frf`, so every check of the readers (format,
units, passivity) applies to ``lobes --measured-x/--measured-y`` as well.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError, SetupError

__all__ = ["FRFInput", "posterior_frf_draws", "measured_frf_pair", "measured_frf_draws", "common_frequency_grid",
           "flute_length"]


class FRFInput:
    """FRF draws in X and Y on one grid and where they came from.

    Attributes
    ----------
    frequency_hz : (n_freq,) Hz
    frf_x, frf_y : (n_draws, n_freq) complex, m/N
    source : dict, JSON-able description
    flute_length_m : float or None, the tool's flute length when known (posterior mode)
    """

    def __init__(self, frequency_hz, frf_x, frf_y, source: dict, flute_length_m: float | None = None):
        self.frequency_hz = np.asarray(frequency_hz, dtype=float)
        self.frf_x = np.atleast_2d(frf_x)
        self.frf_y = np.atleast_2d(frf_y)
        self.source = source
        self.flute_length_m = flute_length_m
        self.measured = None
        self.coefficients = None  # (kt (n_draws,), kr (n_draws,)) Pa of an updated posterior, else None

    @property
    def n_draws(self) -> int:
        return int(self.frf_x.shape[0])


def common_frequency_grid(frf_x, frf_y):
    """Both FRFs on one grid: X's lines inside the overlap, Y interpolated (complex, linear) when grids differ.

    Parameters
    ----------
    frf_x, frf_y : FRF (``frequency_hz``, ``values``, ``source``)

    Returns
    -------
    frequency_hz (n,), gx (n,), gy (n,)
    """
    from ..io.frf import overlap_mask

    fx, fy = frf_x.frequency_hz, frf_y.frequency_hz
    if fx.shape == fy.shape and np.allclose(fx, fy, rtol=1e-12, atol=0):
        return fx, frf_x.values, frf_y.values
    keep = overlap_mask(fx, fy)
    if keep.sum() < 2:
        raise DataError(
            f"{frf_x.source} ({fx[0]:g}-{fx[-1]:g} Hz) and {frf_y.source} ({fy[0]:g}-{fy[-1]:g} Hz) do not share a frequency band"
        )
    f = fx[keep]
    gy = np.interp(f, fy, frf_y.values.real) + 1j * np.interp(f, fy, frf_y.values.imag)
    return f, frf_x.values[keep], gy


def measured_frf_pair(path_x, path_y) -> FRFInput:
    """Measured tool-point FRFs in X and Y on a common grid (one "draw")."""
    from ..io.frf import read_frf

    fx = read_frf(path_x)  # the reader refuses non-passive files (sign-convention slips)
    fy = read_frf(path_y)
    f, gx, gy = common_frequency_grid(fx, fy)
    return FRFInput(f, gx[None], gy[None], {"mode": "measured", "measured_x": str(path_x), "measured_y": str(path_y)})


def measured_frf_draws(spec_x: str, spec_y: str, averages: int | None, n_draws: int, rng,
                       exact: bool = False) -> FRFInput:
    """Realisations of the measured X and Y tool-point FRFs on one grid (:mod:`.measured`).

    Parameters
    ----------
    spec_x, spec_y : str, ``FILE`` or ``FILE1,FILE2,...`` per direction (repeated hits; UFF58 records count too)
    averages : int or None, impacts averaged per FRF (``--averages``; else the files' header key)
    n_draws : int >= 1, realisations drawn when a direction has a random-error model
    rng : numpy.random.Generator (X drawn first, then Y)
    exact : bool, use the measured FRFs (the mean of the hits) as they are, without their random error
        (``lobes --deterministic``)

    Returns
    -------
    FRFInput
        (n_draws, n_freq) draws, or one "draw" (the measured FRFs) when neither direction has a
        random-error model.  ``source["uncertainty"]`` describes the model per direction,
        ``source["deterministic"]`` says whether the lobes are deterministic and
        ``source["notes"]`` holds the warnings (one line each).  ``measured`` carries the two
        :class:`~bayes_rcsa.stability.measured.MeasuredDirection` objects.
    """
    from ..io.frf import overlap_mask
    from .measured import draw_measured_frf, interpolate_lines, read_measured_direction

    mx = read_measured_direction(spec_x, averages, "--measured-x", exact)
    my = read_measured_direction(spec_y, averages, "--measured-y", exact)
    deterministic = mx.model == "none" and my.model == "none"
    if not deterministic and n_draws < 2:
        raise SetupError(f"--draws {n_draws}: the measured FRFs carry a random error ({mx.model} in X, {my.model} "
                         "in Y); its realisations need --draws >= 2 (default 500)")
    gx = draw_measured_frf(mx, n_draws, rng)
    gy = draw_measured_frf(my, n_draws, rng)
    fx, fy = mx.frequency_hz, my.frequency_hz
    f = fx
    if not (fx.shape == fy.shape and np.allclose(fx, fy, rtol=1e-12, atol=0)):
        keep = overlap_mask(fx, fy)
        if keep.sum() < 2:
            raise DataError(f"{mx.files[0]} ({fx[0]:g}-{fx[-1]:g} Hz) and {my.files[0]} ({fy[0]:g}-{fy[-1]:g} Hz) "
                            "do not share a frequency band")
        f = fx[keep]
        gx = gx[:, keep]
        gy = interpolate_lines(gy, fy, f)
    gx, gy = np.broadcast_arrays(gx, gy)
    note = ""
    if deterministic:
        coh = [Path(m.files[0]).name for m in (mx, my) if m.has_coherence]
        note = "deterministic (P(stable) is 0 or 1): " + (
            "--deterministic: the measured FRFs are used as they are, without their random error" if exact else (
                f"{' and '.join(coh)} carry coherence but no number of averages, so no random error is assumed; give "
                "--averages N (or a '# averages = N' header line)" if coh else
                "no random error is known for the measured FRFs; give files with a coherence column and --averages N")
            + ", or repeated hits FILE1,FILE2,...")
    source = {"mode": "measured", "measured_x": str(spec_x), "measured_y": str(spec_y),
              "deterministic": deterministic, "deterministic_note": note,
              "uncertainty": {"x": mx.describe(), "y": my.describe(), "n_draws": int(gx.shape[0])},
              "notes": mx.notes + my.notes}
    out = FRFInput(f, gx.copy(), gy.copy(), source)
    out.measured = (mx, my)
    return out


def flute_length(tool) -> float | None:
    """Length (m) of the fluted tip section of a :class:`~bayes_rcsa.model.geometry.Tool`: the leading
    segments with ``diameter_ratio < 1``; None when the tool has no fluted segment."""
    total = 0.0
    for seg in tool.segments:
        if seg.diameter_ratio >= 1.0:
            break
        total += seg.length
    return total if total > 0 else None


def posterior_frf_draws(setup_path, posterior_path, clamping_length: float, n_draws: int, rng, tool=None, *,
                        setup=None, posterior_draws=None, inference_data=None, summary=None,
                        spindle_samples=None) -> FRFInput:
    """Posterior-predictive tool-point FRFs in X and Y at one clamping length.

    The contact parameters are shared by both directions; the spindle
    receptance is per direction.  The frequency lines are those of the X
    spindle file inside the range both spindle files cover.

    Parameters
    ----------
    setup_path : path of the setup TOML
    posterior_path : path of ``posterior.nc``
    clamping_length : float, m
    n_draws : int, draws used (a random subset chosen with ``rng``)
    rng : numpy.random.Generator
    tool : str or None, tool name (default: the setup's only tool)
    setup : Setup or None, the setup of ``setup_path`` already loaded with its spindle files (not read again)
    posterior_draws : PosteriorDraws or None, the draws of ``posterior_path`` already loaded (all of them; the subset is
        chosen here)
    inference_data : arviz.InferenceData or None, the content of ``posterior_path`` already read; without it the
        file is read once here (draws, convergence status and cutting coefficients come from that one read)
    summary : dict or None, the fit's summary.json document for a posterior held in memory only
    spindle_samples : SpindleSamples, optional
        Bootstrap samples of the flange receptance (``bayes-rcsa spindle``):
        every draw uses one of them in X and Y (sample ``i`` of both
        directions), so the FRF draws, and hence P(stable), include the
        spindle uncertainty.  Their frequency range must cover the lines.
        The assignment comes from a child of ``rng`` (``rng.spawn``), so the
        draws chosen and ``rng``'s own stream stay as without samples.
        Recorded as ``source["spindle_uncertainty"]``.

    Returns
    -------
    FRFInput with (n_draws, n_freq) draws
    """
    from ..io import load_setup
    from ..io.frf import overlap_mask
    from ..model import Configuration
    from ..posterior import load_posterior, predictive_frf
    from ..store import read_posterior
    from ..posterior.growth_prior import transfer_draws
    from ..posterior.prediction_outputs import check_prediction_lengths, posterior_status
    from .coefficients import read_coefficient_draws

    if setup is None:
        setup = load_setup(setup_path, load_data=False, load_spindle=True)
    for d in ("x", "y"):
        if d not in setup.spindle:
            raise SetupError(f"{setup_path}: [spindle] {d} is needed for lobes (both directions are coupled)")
    if tool is None:
        if len(setup.tools) != 1:
            raise SetupError(f"{setup_path}: several tools {sorted(setup.tools)}; the posterior mode needs one")
        tool = next(iter(setup.tools))
    full = posterior_draws
    if full is None:
        if inference_data is None:
            inference_data = read_posterior(posterior_path, option=None, arrays=True)  # the one read of the file
        full = load_posterior(posterior_path, setup, inference_data=inference_data)
    # the subset of PosteriorDraws.subset, keeping the index for the draws' cutting coefficients (after an update)
    index = (np.arange(full.n_draws) if n_draws is None or full.n_draws <= n_draws
             else np.sort(rng.choice(full.n_draws, n_draws, replace=False)))
    draws = full.take(index)
    check_prediction_lengths(draws, setup, [clamping_length])
    # a single-length fit carries the growth law's prior to other lengths (multi-length draws pass unchanged)
    draws = transfer_draws(draws, setup, [clamping_length], rng)
    sx, sy = setup.spindle["x"].frequency_hz, setup.spindle["y"].frequency_hz
    f = sx[overlap_mask(sx, sy)]
    model = setup.model()
    assignment = None
    if spindle_samples is not None:
        from ..spindle.uncertainty import assign_samples

        assignment = assign_samples(draws.n_draws, spindle_samples.n_samples, rng.spawn(1)[0])
    hx, hy = (predictive_frf(draws, model, Configuration(clamping_length, d, tool), f,
                             spindle_samples=spindle_samples, assignment=assignment) for d in ("x", "y"))
    source = {
        "mode": "posterior",
        "setup": str(setup_path),
        "posterior": str(posterior_path),
        "clamping_length_m": clamping_length,
        "n_draws": int(draws.n_draws),
        "method": draws.method,
        **draws.provenance(),
        "posterior_status": posterior_status(posterior_path, inference_data=inference_data, summary=summary),
    }
    if spindle_samples is not None:
        source["spindle_uncertainty"] = spindle_samples.describe()
    out = FRFInput(f, hx, hy, source, flute_length(setup.tools[tool]))
    out.coefficients = None if inference_data is None else read_coefficient_draws(posterior_path, index,
                                                                                     inference_data=inference_data)
    return out
