"""Stability lobes and a robust operating point, from measured FRFs or from posterior draws (``bayes-rcsa lobes``).

:func:`lobes` takes the tool-point dynamics in one of two modes:

- measured: ``measured_x``/``measured_y`` (CSV or UFF58 files; several comma-separated files are repeated hits),
  probabilistic from their coherence and averages or from the repeated hits, else deterministic;
- posterior: ``setup`` + ``posterior`` (paths, or a loaded Setup and the ``Posterior`` of
  :func:`bayes_rcsa.identify`) + ``clamping_length``: posterior-predictive FRF draws.

It computes the P(stable) map with the chosen method (:mod:`bayes_rcsa.stability.methods`) and recommends the
operating point with the largest removal rate whose neighbourhood (speed tolerance x depth margin x cutting-force
tolerance) is stable with probability >= ``level``.  The job itself lives in :mod:`bayes_rcsa.stability`; this
module checks the inputs, builds the domain objects and returns a :class:`Lobes` that writes lobes.json,
p_stable.npz and lobes.png.  See docs/stability.md.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import ClassVar

import numpy as np

from ..errors import SetupError
from ..messages import merge_warnings, warning_log
from ..units import mm, num, percent, rpm
from ..vocabulary import depth_limit_name, method_name
from .result import Result, saving
from ._posterior_input import is_path, posterior_parts, setup_of

__all__ = ["lobes", "Lobes", "DEFAULT_BUDGET_S"]

#: Run time (s) above which the estimate printed before the job comes with advice on cutting it.
DEFAULT_BUDGET_S = 120.0


@dataclass
class Lobes(Result):
    """Stability lobes: the P(stable) map, the depth-limit quantiles and the recommended operating point.

    Attributes
    ----------
    document : dict
        The lobes.json document (keys: :mod:`bayes_rcsa.stability.outputs`).
    speed_rpm : (n_speed,) rpm
    depth_m : (n_depth,) m, the depth grid of the map
    p_stable : (n_speed, n_depth), probability of stability
    warnings : tuple of str
    path : Path or None, the lobes.json written or read (None until saved)
    lobes : ProbabilisticLobes or None, the full result in memory (per-draw limits, modal fits); None after
        :meth:`load`
    """

    title: ClassVar[str] = "Stability lobes"
    files: ClassVar[tuple[str, ...]] = ("lobes.json", "p_stable.npz", "lobes.png")

    document: dict
    speed_rpm: np.ndarray
    depth_m: np.ndarray
    p_stable: np.ndarray
    warnings: tuple[str, ...] = ()
    path: Path | None = None
    lobes: object = field(default=None, repr=False, compare=False)

    # -- numbers ---------------------------------------------------------------------------------------------
    @property
    def recommended(self) -> dict | None:
        """The robust recommended point (lobes.json ``recommended``) or None."""
        return self.document.get("recommended")

    @property
    def level(self) -> float:
        """P(stable) required over the neighbourhood (and the robust envelope's confidence)."""
        return float(self.document["level"])

    @property
    def deterministic(self) -> bool:
        """True for one FRF (P(stable) is 0 or 1: the classical lobes)."""
        return bool(self.document["deterministic"])

    def to_dict(self) -> dict:
        return json.loads(json.dumps(self.document))

    def headline(self) -> list[tuple[str, str]]:
        d = self.document
        rows = [("method", f"{method_name(d['method'])}, {d['n_draws']} draw(s)"), ("required P(stable)", num(self.level))]
        rec = self.recommended
        if rec is None:
            rows.append(("recommended point", f"none: {d.get('recommended_note', '')}"))
            return rows
        below, above = rec["margin_speed_rpm"]["below"], rec["margin_speed_rpm"]["above"]
        rows += [("recommended spindle speed", rpm(rec["spindle_speed_rpm"])),
                 ("recommended axial depth", mm(rec["depth_m"])),
                 ("P(stable) over the neighbourhood", f"{rec['p_stable_neighbourhood']:.2f}"),
                 ("speed margins", f"{rpm(below, unit=False)} / {rpm(above)}"),
                 ("depth margin", mm(rec["margin_depth_m"])),
                 ("limited by", depth_limit_name(rec["binding_limit"]))]
        return rows

    def summary_line(self) -> str:
        d = self.document
        rec = self.recommended
        if self.path is None:
            msg = "lobes computed"
        else:
            png = self.path.with_name("lobes.png")
            msg = f"wrote {self.path}, p_stable.npz" + (", lobes.png" if png.exists() else "")
        if rec is not None:
            below, above = rec["margin_speed_rpm"]["below"], rec["margin_speed_rpm"]["above"]
            msg += (f"; recommended {rpm(rec['spindle_speed_rpm'])}, {mm(rec['depth_m'])} (P(stable) >= "
                    f"{rec['p_stable_neighbourhood']:.2f} over ±{num(100 * rec['speed_tolerance_rel'])} % speed and "
                    f"+{num(100 * rec['depth_margin_rel'])} % depth; margins {rpm(below, unit=False)}/"
                    f"{rpm(above)}, {mm(rec['margin_depth_m'])}; limited by {depth_limit_name(rec['binding_limit'])})")
        else:
            msg += f"; no recommendation: {d.get('recommended_note', '')}"
        med = d.get("median_recommended")
        if rec is not None and med is not None and d["n_draws"] > 1:
            cost = med["depth_m"] - rec["depth_m"]
            rel = (d.get("confidence_cost") or {}).get("relative")
            msg += (f"; at P(stable) >= 0.5 it would be {rpm(med['spindle_speed_rpm'])}, {mm(med['depth_m'])} "
                    f"(confidence {num(d['level'])} costs {mm(cost)}" + ("" if rel is None else f", {percent(rel)}")
                    + ")")
        source = d["source"]
        if source.get("deterministic"):
            msg += "; " + source["deterministic_note"]
        elif source.get("mode") == "measured":
            unc = source["uncertainty"]

            def direction(name, u):
                averages = "" if u["averages"] is None else f", {u['averages']} averages"
                return f"{name} {u['model']} ({len(u['files'])} file(s){averages})"

            msg += ("; FRF random error: " + ", ".join(direction(a, unc[k]) for a, k in (("X", "x"), ("Y", "y")))
                    + f", {unc['n_draws']} realisations")
        return msg

    def summary_data(self) -> dict:
        d = self.document
        rec = self.recommended
        status = d["source"].get("posterior_status") or {}
        return {"recommended": None if rec is None else {
                    "spindle_speed_rpm": rec["spindle_speed_rpm"], "depth_m": rec["depth_m"],
                    "p_stable": rec["p_stable_neighbourhood"], "binding": rec["binding_limit"]},
                "robust_envelope_confidence": d["level"], "deterministic": self.deterministic,
                "uncertainty": d.get("uncertainty"), "posterior_converged": status.get("converged")}

    # -- files -----------------------------------------------------------------------------------------------
    def _plot_title(self) -> str:
        d = self.document
        return f"{d['cutting']['flutes']} flutes, {d['method'].upper()}, " + (
            "measured FRFs" if d["source"]["mode"] == "measured" else f"{d['n_draws']} draws")

    def _tests(self):
        tests = self.document.get("tests")
        if tests is None:
            return None
        return (np.array([t["spindle_speed_rpm"] for t in tests], dtype=float),
                np.array([t["depth_m"] for t in tests], dtype=float),
                np.array([t["outcome"] == "stable" for t in tests], dtype=bool))

    def _max_depth(self):
        return self.document["depth_limits_m"]["max_depth"]

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write lobes.json, p_stable.npz and (``plots``) lobes.png into ``folder``; returns the path of lobes.json."""
        from ..stability.outputs import write_lobes_outputs

        res = self.lobes if self.lobes is not None else self._view()
        # a forced run removes the earlier run's files first: no lobes.png of other lobes beside these
        with saving(folder, force, earlier_outputs=self.files) as out:
            path = write_lobes_outputs(out, res, self.document, self._tests(), self._plot_title(),
                                       max_depth=self._max_depth(), plots=plots)
        self.path = path
        return path

    @classmethod
    def load(cls, folder) -> "Lobes":
        from ..errors import DataError
        from ._documents import read_document

        folder = Path(folder)
        path = folder / "lobes.json"
        document = read_document(folder, "lobes.json", "lobes")
        try:
            with np.load(folder / "p_stable.npz") as z:
                speed, depth, p = (np.asarray(z[k]) for k in ("spindle_speed_rpm", "depth_m", "p_stable"))
        except (OSError, ValueError, KeyError) as exc:
            raise DataError(f"{folder}: not an output directory of 'bayes-rcsa lobes' ({exc})") from None
        return cls(document, speed, depth, p, tuple(document.get("warnings", ())), path)

    # -- pictures --------------------------------------------------------------------------------------------
    def _view(self):
        """The attributes :func:`~bayes_rcsa.stability.plots.lobes_figure` draws, rebuilt from the document."""
        d = self.document

        def arr(values):
            return np.array([np.inf if v is None else v for v in values], dtype=float)

        def point(p):
            return None if p is None else SimpleNamespace(**{**p, "speed_window_rpm": tuple(p.get("speed_window_rpm",
                                                                                                   ()))})

        env = d.get("robust_envelope")
        return SimpleNamespace(
            speed_rpm=self.speed_rpm, depth_m=self.depth_m, p_stable=self.p_stable,
            quantiles={0.05: arr(d["depth_limit_m"]["q05"]), 0.5: arr(d["depth_limit_m"]["q50"]),
                       0.95: arr(d["depth_limit_m"]["q95"])},
            depth_limit_m=np.empty((int(d["n_draws"]), 0)), envelope=None if env is None else arr(env["depth_limit_m"]),
            level=d["level"], alternatives=d.get("alternatives") or [], pointwise=point(d.get("pointwise_optimum")),
            recommended=point(d.get("recommended")))

    def figures(self) -> dict:
        from ..stability.plots import lobes_figure

        res = self.lobes if self.lobes is not None else self._view()
        return {"lobes": lobes_figure(res, self._tests(), self._plot_title(), self._max_depth())}


# ------------------------------------------------------------------------------------------------------------
def lobes(*, posterior=None, setup=None, clamping_length: float | None = None, tool: str | None = None,
          measured_x=None, measured_y=None, averages: int | None = None, deterministic: bool = False,
          draws: int = 500, seed: int = 0, flutes: int, kt: float | None = None, kr: float | None = None,
          kt_tolerance: float = 0.0, radial_immersion: float | None = None, entry_angle: float | None = None,
          exit_angle: float | None = None, milling: str = "down", feed: str = "x", pitch_angles=None,
          allow_unusual: bool = False, speeds_rpm, max_depth: float | None = None, flute_length: float | None = None,
          speed_tolerance: float = 0.02, depth_margin: float = 0.10, depth_points: int = 200, method: str = "zoa",
          intervals: int | None = None, max_modes: int = 4, sdm_exact: bool = False, level: float | None = None,
          confidence: float | None = None, tests=None, spindle_samples=None, progress: bool = False,
          budget_s: float = DEFAULT_BUDGET_S) -> Lobes:
    """Milling stability lobes and a robust operating point.

    Parameters
    ----------
    posterior : path of posterior.nc, or a ``Posterior`` (:func:`bayes_rcsa.identify`); posterior mode
    setup : path of the setup TOML or a loaded Setup (with its spindle files); posterior mode
    clamping_length : float, m; posterior mode
    tool : str or None, tool name (default: the setup's only tool)
    measured_x, measured_y : str, measured tool-point FRF files in X and Y (``FILE`` or ``FILE1,FILE2,...`` for
        repeated hits); measured mode
    averages : int or None, impacts averaged per measured FRF (default: the files' ``# averages = N`` line)
    deterministic : bool, measured mode: use the measured FRFs without their random error
    draws : int >= 1, posterior draws used, or FRF realisations drawn in measured mode
    seed : int, seed of the draw choice or the FRF realisations
    flutes : int, number of teeth
    kt, kr : float or None, Pa, cutting-force coefficients; both None with a posterior written by
        ``bayes-rcsa update``: its per-draw coefficients (the cutting block gives their medians)
    kt_tolerance : float in [0, 0.5), relative tolerance of the cutting-force level (part of the neighbourhood)
    radial_immersion : float in (0, 1], radial depth / tool diameter; or ``entry_angle``/``exit_angle`` (rad)
    milling : "down" or "up"
    feed : "x" or "y", the machine axis along which the tool advances
    pitch_angles : sequence of float or None, rad, variable pitch
    allow_unusual : bool, warn instead of refusing coefficients outside the ranges for metals
    speeds_rpm : (n_speed,) rpm, increasing spindle-speed grid
    max_depth, flute_length : float or None, m, depth limits of the recommendation (flute length in posterior
        mode: default from the setup's fluted tool segments)
    speed_tolerance : float, ± relative spindle-speed tolerance of the recommendation
    depth_margin : float, relative depth margin of the recommendation
    depth_points : int >= 2, depth levels of the map
    method : str, stability method (``"zoa"``, ``"sdm"``; :mod:`bayes_rcsa.stability.methods`)
    intervals : int or None, SDM intervals per tooth period
    max_modes : int >= 1, largest mode count of the SDM modal fit
    sdm_exact : bool, SDM on every draw (no surrogate from a subset of exact draws; minutes for 500 draws:
        :mod:`bayes_rcsa.stability.sdm_draws`)
    level : float in (0, 1] or None, P(stable) required over the neighbourhood (default 0.95)
    confidence : float in [0.5, 1) or None, confidence of the robust envelope; sets ``level``
    tests : path of a cutting-test CSV (spindle_speed_rpm,depth_m,outcome) or None
    spindle_samples : SpindleSamples, path of spindle_samples.npz (``bayes-rcsa spindle``) or None; posterior
        mode: the spindle receptance's own uncertainty enters the FRF draws
    progress : bool, print the run-time estimate and a progress bar on stderr
    budget_s : float, s, run time above which the estimate comes with advice on cutting it

    Returns
    -------
    Lobes

    Raises
    ------
    SetupError
        Inconsistent or out-of-range inputs (one line naming the option), before any heavy work.
    DataError
        Unreadable or implausible input files.
    """
    from ..stability import CuttingConditions, Tolerances, lobes_from_frf_draws
    from ..stability.methods import STABILITY_METHODS, MethodOptions
    from ..stability.outputs import lobes_document
    from ..stability.plausibility import check_cutting_coefficients
    from ..stability.tests_io import read_cutting_tests
    from ..io.limits import check_memory

    with warning_log() as log:
        parts = posterior_parts(posterior) if posterior is not None else None
        kt, kr, per_draw, inference_data = _coefficients(parts, kt, kr)
        warnings = check_cutting_coefficients(kt, kr, allow_unusual=allow_unusual)
        if (radial_immersion is None) == (entry_angle is None and exit_angle is None):
            raise SetupError("give exactly one of --immersion (radial depth / diameter) and --angles ENTRY,EXIT (deg)")
        geometry = ({"radial_immersion": radial_immersion} if radial_immersion is not None
                    else {"entry_angle": entry_angle, "exit_angle": exit_angle})
        if pitch_angles is not None:
            geometry["pitch_angles"] = tuple(float(a) for a in pitch_angles)
        cutting = CuttingConditions(kt=kt, kr=kr, flutes=flutes, milling=milling, feed=feed, **geometry)
        speeds = np.asarray(speeds_rpm, dtype=float)
        level = _level(level, confidence)
        tol = Tolerances(speed_tolerance, depth_margin, kt_tolerance)
        if depth_points < 2:
            raise SetupError(f"--depth-points {depth_points}: expected >= 2")
        if max_modes < 1:
            raise SetupError(f"--max-modes {max_modes}: expected >= 1 (the modal fit needs at least one mode)")
        impl = STABILITY_METHODS.get(method, "--method")
        impl.check(MethodOptions(intervals=intervals, max_modes=max_modes, exact=sdm_exact))
        test_cuts = read_cutting_tests(tests) if tests is not None else None
        n_cells = speeds.size * depth_points
        check_memory(8.0 * (8 * draws * speeds.size + 4 * n_cells), f"--draws {draws} x --speeds "
                     f"{speeds.size} x --depth-points {depth_points}", "use fewer draws, speeds or depth points, or "
                     "split the speed range into several runs")
        frf = _dynamics(parts, inference_data, setup, clamping_length, tool, measured_x, measured_y, averages,
                        deterministic, draws, seed, spindle_samples)
        # the inputs are read and checked: load the compiled kernels (many draws) and matplotlib beside the job
        from ..stability import warmup

        warmup.start(kernels=frf.n_draws > 1 and method == "zoa", figure=True)
        check_memory(8.0 * (8 * frf.n_draws * speeds.size + 4 * n_cells)
                     + 16.0 * 6 * frf.n_draws * frf.frequency_hz.size,
                     f"{frf.n_draws} draw(s) x {frf.frequency_hz.size} frequency lines x --speeds {speeds.size}",
                     "use fewer --draws or a coarser speed grid, or split the speed range into several runs")
        flute = flute_length if flute_length is not None else frf.flute_length_m
        status = frf.source.get("posterior_status") or {}
        if status.get("converged") is False:
            warnings.append(f"the posterior {frf.source['posterior']} did not converge (see its summary.json): "
                            "the P(stable) map inherits its uncertainty estimate")
        warnings += [n.removeprefix("warning:").strip() for n in frf.source.get("parameter_model_notes", [])
                     if n.startswith("warning:")]
        bar = None
        if progress:
            from ..stability.progress import ProgressBar

            _print_estimate(impl, frf, speeds, method, budget_s, sdm_exact)
            bar = ProgressBar(f"lobes: {method_name(method)}")
        try:
            res = lobes_from_frf_draws(
                frf.frf_x, frf.frf_y, frf.frequency_hz, cutting, speeds, method=method, level=level,
                max_depth=max_depth, depth_points=depth_points, intervals=intervals, max_modes=max_modes,
                tolerances=tol, flute_length=flute, progress=bar, coefficients=frf.coefficients if per_draw else None,
                exact=sdm_exact)
        finally:
            if bar is not None:
                bar.close()
        fit_report = None
        if method == "sdm" and frf.measured is not None:
            from ..io.checks import warn_all
            from ..stability.modal_quality import measured_fit_report

            fit_report, fit_warnings = measured_fit_report(frf.measured, res.modal_fits, max_modes)
            warn_all(fit_warnings)
        warnings = merge_warnings(log, warnings)  # the data warnings issued on the way go into lobes.json
        doc = lobes_document(res, cutting, frf.source, test_cuts, warnings, max_depth=max_depth, flute_length=flute)
        if per_draw:
            kt_q, kr_q = (np.quantile(c, [0.05, 0.5, 0.95]).tolist() for c in frf.coefficients)
            doc["cutting_coefficients"] = {"source": "per-draw K_t/K_r of the updated posterior (bayes-rcsa update); "
                                           "the cutting block gives their medians", "kt_pa_q05_q50_q95": kt_q,
                                           "kr_pa_q05_q50_q95": kr_q}
        if fit_report is not None:
            doc["modal_fit"] = fit_report
        return Lobes(doc, res.speed_rpm, res.depth_m, res.p_stable, tuple(warnings), None, res)


def _coefficients(parts, kt, kr):
    """(K_t, K_r, per-draw?, the posterior's content if read): the medians of an updated posterior's per-draw
    coefficients when both are None."""
    inference_data = None if parts is None else parts.inference_data
    if kt is not None and kr is not None:
        return float(kt), float(kr), False, inference_data
    if (kt is None) != (kr is None):
        raise SetupError("give both --kt and --kr, or neither (an updated posterior's per-draw coefficients)")
    if parts is None:
        raise SetupError("--kt and --kr are required (only a posterior written by 'bayes-rcsa update' carries "
                         "per-draw cutting coefficients)")
    from ..stability.coefficients import read_coefficient_draws

    if inference_data is None:
        from ..store import read_posterior

        inference_data = read_posterior(parts.path, option=None, arrays=True)  # the one read of posterior.nc, passed on to the FRF draws
    coef = read_coefficient_draws(parts.path, inference_data=inference_data)
    if coef is None:
        raise SetupError(f"--kt and --kr are required: {parts.path} carries no cutting-coefficient draws (only "
                         "'bayes-rcsa update' writes them)")
    return float(np.median(coef[0])), float(np.median(coef[1])), True, inference_data


def _level(level, confidence) -> float:
    """The P(stable) required: ``confidence`` if given (it must agree with ``level``), else ``level`` or 0.95."""
    value = 0.95 if level is None else float(level)
    if not (0 < value <= 1):
        raise SetupError(f"--level {value:g}: expected a probability in (0, 1]")
    if confidence is None:
        return value
    if not (0.5 <= confidence < 1):
        raise SetupError(f"--confidence {confidence:g}: expected a probability in [0.5, 1) (e.g. 0.95)")
    if level is not None and abs(confidence - level) > 1e-12:
        raise SetupError(f"--confidence {confidence:g} and --level {level:g} differ; give one of them")
    return float(confidence)


def _dynamics(parts, inference_data, setup, clamping_length, tool, measured_x, measured_y, averages,
              deterministic, draws, seed, spindle_samples):
    """FRF draws in X and Y (FRFInput) of the measured or the posterior mode."""
    from ..io.checks import warn_all
    from ..stability.posterior_frf import measured_frf_draws, posterior_frf_draws

    measured = measured_x is not None or measured_y is not None
    if measured and (setup is not None or parts is not None or clamping_length is not None):
        raise SetupError("give either --measured-x/--measured-y or SETUP --posterior --clamping-length, not both")
    if measured:
        if measured_x is None or measured_y is None:
            raise SetupError("measured mode needs both --measured-x and --measured-y")
        if averages is not None and averages < 1:
            raise SetupError(f"--averages {averages!r}: expected a whole number >= 1 (impacts averaged per FRF)")
        if deterministic and averages is not None:
            raise SetupError(f"--averages {averages} and --deterministic contradict each other (averages give the "
                             "FRF's random error, --deterministic ignores it); give one of them")
        if spindle_samples is not None:
            raise SetupError("--spindle-uncertainty: only for posterior draws (SETUP --posterior FILE "
                             "--clamping-length M); measured FRFs include the spindle")
        pair = measured_frf_draws(measured_x, measured_y, averages, draws, np.random.default_rng(seed),
                                  exact=deterministic)
        warn_all(pair.source["notes"])
        warn_all(_pair_warnings(*pair.measured))
        return pair
    if setup is None or parts is None or clamping_length is None:
        raise SetupError(
            "give --measured-x FX --measured-y FY, or SETUP --posterior FILE --clamping-length M for posterior draws"
        )
    if averages is not None:
        raise SetupError(f"--averages {averages}: only for measured FRFs (--measured-x/--measured-y)")
    if deterministic:
        raise SetupError("--deterministic: only for measured FRFs (--measured-x/--measured-y)")
    if not (np.isfinite(clamping_length) and clamping_length > 0):
        raise SetupError(f"--clamping-length {clamping_length!r}: expected a finite number > 0")
    if draws < 1:
        raise SetupError(f"--draws {draws}: expected >= 1")
    from ..posterior.setup_match import posterior_setup_warnings

    loaded, setup_name = setup_of(setup, load_data=False, load_spindle=True)  # the one read of the setup
    # a posterior identified for another geometry or material says so
    warn_all(posterior_setup_warnings(parts.path, loaded, summary_document=parts.summary))
    if spindle_samples is not None:
        from ..spindle.uncertainty import load_spindle_samples

        spindle_samples = load_spindle_samples(spindle_samples) if is_path(spindle_samples) else spindle_samples
        spindle_samples.require_directions(["x", "y"])  # both directions are coupled in the lobes
    return posterior_frf_draws(setup_name, parts.path, clamping_length, draws, np.random.default_rng(seed), tool=tool,
                               setup=loaded, posterior_draws=parts.draws, inference_data=inference_data,
                               summary=parts.summary, spindle_samples=spindle_samples)


def _pair_warnings(mx, my) -> list[str]:
    """Plausibility of the X/Y pair (similar modes, similar stiffness) on X's lines."""
    from ..io.checks import xy_pair_warnings
    from ..stability.measured import interpolate_lines

    same_grid = mx.frequency_hz.shape == my.frequency_hz.shape and np.allclose(mx.frequency_hz, my.frequency_hz)
    gy = my.mean if same_grid else interpolate_lines(my.mean, my.frequency_hz, mx.frequency_hz)[0]
    return xy_pair_warnings(Path(mx.files[0]).name, Path(my.files[0]).name, mx.frequency_hz, mx.mean, gy)


def _print_estimate(impl, frf, speeds, method: str, budget: float, exact: bool = False) -> None:
    """The run-time estimate on stderr (with advice when it exceeds ``budget`` s); ``exact``: every draw computed
    by the method itself (``--sdm-exact``), passed only then, so that a registered method without the option works."""
    from ..stability.progress import format_seconds

    est = impl.estimate_seconds(frf.n_draws, speeds.size, frf.frequency_hz.size, **({"exact": True} if exact else {}))
    print(f"lobes: {method_name(method)}, {frf.n_draws} draw(s) x {speeds.size} speeds: estimated "
          f"{format_seconds(est)}",
          file=sys.stderr)
    if est > budget:
        print(f"lobes: that is more than --budget {budget:g} s; to cut it use fewer draws (--draws "
              f"{max(1, frf.n_draws // 4)} is about 4x faster), a coarser speed grid (START:STOP:{max(2, speeds.size // 2)} "
              f"halves it)" + ("" if method == "zoa" else ", or --method zoa (seconds; accurate at moderate to "
                               "full radial immersion, semi-discretisation is needed below about 0.3)"), file=sys.stderr)
