"""Cutting-test outcomes update an existing posterior: :func:`update` -> :class:`CutUpdate`.

The job of ``bayes-rcsa update``: every draw of the contact, paired with
draws of the cutting coefficients from their prior, is weighted by the
probability of the observed outcomes (importance re-weighting with an ESS
check, an MCMC fallback when it collapses), optionally with the hammer-only
vs hammer + cuts lobes and recommendations on a speed grid.  The work is
:func:`bayes_rcsa.cuts.workflow.run_update`; see docs/stability.md.
"""

from __future__ import annotations

import json
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Sequence

import numpy as np

from ..errors import SetupError
from ..messages import current_warnings, merge_warnings, warning_log
from ..units import mm, num, rpm
from .result import Result, saving

__all__ = ["update", "CutUpdate"]


@dataclass(eq=False)
class CutUpdate(Result):
    """The posterior updated with cutting tests, and what the cuts changed.

    Attributes
    ----------
    document : dict
        The update.json document (inputs, ESS of the draws, K_t/K_r quantiles before and after in Pa, the
        sampler used, optional hammer-only vs with-cuts lobes and recommendations, warnings).
    setup : Setup, path or None, the setup of the fit
    folder : Path or None, where it was saved or loaded from
    warnings : tuple of str
    run : UpdateRun or None, the computation in memory (what :meth:`save` writes posterior.nc from)
    """

    title: ClassVar[str] = "Posterior updated with cutting tests"
    files: ClassVar[tuple[str, ...]] = ("posterior.nc", "update.json")

    document: dict
    setup: Any = None
    folder: Path | None = None
    warnings: tuple[str, ...] = ()
    run: Any = field(default=None, repr=False)

    # -- numbers -------------------------------------------------------------------------------------------------
    @property
    def kt_pa(self) -> list:
        """K_t after the update, [5 %, 50 %, 95 %] in Pa."""
        return self.document["kt_pa"]["after"]

    @property
    def kr_pa(self) -> list:
        """K_r after the update, [5 %, 50 %, 95 %] in Pa."""
        return self.document["kr_pa"]["after"]

    @property
    def ess_draws(self) -> float | None:
        """Effective number of posterior draws after the re-weighting (None when unknown)."""
        ess = self.document["ess"]["draws"]
        return ess if ess is not None and np.isfinite(ess) else None

    @property
    def recommended(self) -> dict | None:
        lobes = self.document.get("lobes")
        return None if lobes is None else lobes["with_cuts"]["recommended"]

    @property
    def posterior(self):
        """The updated posterior as a :class:`~bayes_rcsa.workflows.identification.Posterior` (read into memory)."""
        from .identification import Posterior

        if self.folder is not None:
            return Posterior.load(Path(self.folder) / "posterior.nc", self._setup_object())
        with tempfile.TemporaryDirectory(prefix="bayes_rcsa_update_") as tmp:
            self._write(Path(tmp))
            post = Posterior.load(Path(tmp) / "posterior.nc", self._setup_object())
        post.path = post._folder = None
        return post

    def _setup_object(self):
        if self.setup is None or hasattr(self.setup, "measurements"):
            return self.setup
        from ..io.setup import load_setup

        return load_setup(self.setup, load_data=False, load_spindle=False)

    def to_dict(self) -> dict:
        return self.document

    def headline(self) -> list[tuple[str, str]]:
        kt, kr = self.kt_pa, self.kr_pa
        ess = self.ess_draws
        rows = [("cuts", str(self.document["inputs"]["n_cuts"])),
                ("effective draws", "unknown" if ess is None else f"{ess:.0f} of {self.document['ess']['n_draws']}"),
                ("tangential cutting coefficient Kt, 90 % interval", _mpa(kt)),
                ("radial cutting coefficient Kr, 90 % interval", _mpa(kr))]
        r = self.recommended
        if r is not None:
            rows.append(("recommended", f"{rpm(r['spindle_speed_rpm'])}, {mm(r['depth_m'])}"))
        return rows

    def summary_line(self) -> str:
        doc = self.document
        kt = self.kt_pa
        ess = self.ess_draws
        where = Path(self.folder) if self.folder is not None else Path("memory")
        msg = (f"wrote {where / 'posterior.nc'}, update.json; {doc['inputs']['n_cuts']} cuts, "
               + ("MCMC fallback, " if doc["sampler"] == "mcmc" else "")
               + ("ESS unknown of " if ess is None else f"ESS {ess:.0f} of ")
               + f"{doc['ess']['n_draws']} draws; tangential cutting coefficient Kt {_mpa(kt)}")
        lobes = doc.get("lobes")
        if lobes is not None:
            b, a = lobes["hammer_only"]["recommended"], lobes["with_cuts"]["recommended"]
            fmt = lambda r: "no recommendation" if r is None else f"{rpm(r['spindle_speed_rpm'])}, {mm(r['depth_m'])}"  # noqa: E731
            msg += f"; recommendation hammer only {fmt(b)} -> with cuts {fmt(a)}"
        return msg

    def summary_data(self) -> dict:
        return {"ess_draws": self.ess_draws, "kt_pa": self.kt_pa, "kr_pa": self.kr_pa,
                "recommended": self.recommended}

    # -- files ---------------------------------------------------------------------------------------------------
    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write posterior.nc (with per-draw K_t, K_r) and update.json into ``folder``; returns posterior.nc."""
        folder = Path(folder)
        with saving(folder, force):
            self._write(folder)
        self.folder = folder
        return folder / "posterior.nc"

    def _write(self, folder: Path) -> list:
        from ..cuts.workflow import write_update

        if self.run is None:
            raise SetupError(f"{self.folder}: a loaded update is saved by copying its folder (the draws' weights are "
                             "not stored)")
        return write_update(self.run, folder)

    @classmethod
    def load(cls, folder) -> "CutUpdate":
        """Read update.json of a folder written by :meth:`save` (or ``bayes-rcsa update``)."""
        from ..errors import DataError

        folder = Path(folder)
        path = folder / "update.json"
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise DataError(f"{path}: cannot read update.json ({exc})") from None
        return cls(document=doc, setup=doc.get("inputs", {}).get("setup"), folder=folder,
                   warnings=tuple(doc.get("warnings", [])))

    def figures(self) -> dict:
        """update.py writes no plots (the lobes of the updated posterior come from ``lobes``)."""
        return {}


def update(setup, posterior, cuts, *, flutes: int, kt: float, kr: float, kt_tolerance: float = 0.0,
           kr_tolerance: float = 0.0, clamping_length: float | None = None, radial_immersion: float | None = None,
           entry_angle: float | None = None, exit_angle: float | None = None, milling: str = "down", feed: str = "x",
           pitch_angles: Sequence[float] | None = None, boundary_width: float | tuple[float, float] = 0.1,
           label_error: float = 0.01, method: str = "zoa", intervals: int | None = None, max_modes: int = 4,
           draws: int = 1000, particles: int | None = None, min_ess: float | None = None, mcmc: bool = True,
           mcmc_steps: int = 300, mcmc_walkers: int = 32, seed: int = 0, tool: str | None = None,
           speeds_rpm=None, level: float = 0.95, speed_tolerance: float = 0.02, depth_margin: float = 0.10,
           max_depth: float | None = None, allow_unusual: bool = False) -> CutUpdate:
    """Update a posterior with the outcomes of cutting tests (stable/chatter), without refitting the hammer data.

    Parameters
    ----------
    setup : path of the setup TOML of the fit, or its Setup
    posterior : Posterior or path of its posterior.nc
    cuts : path of the cut table (spindle_speed_rpm, depth_m, outcome[, clamping_length_m, radial_immersion,
        feed_direction, tool])
    flutes : int; kt, kr : Pa
    kt_tolerance : relative prior spread of the cutting-force level (Kt and Kr together; 0.3 = ±30 %)
    kr_tolerance : relative prior spread of Kr/Kt
    clamping_length : m, of cuts without their own (and of the lobes comparison with ``speeds_rpm``)
    radial_immersion : fraction in (0, 1], or entry_angle, exit_angle : rad
    milling : "down" or "up"; feed : "x" or "y"; pitch_angles : (flutes,) rad or None
    boundary_width : float or (lo, hi), probit width in ln(depth / limit) (a pair: log-uniform, sampled)
    label_error : probability in [0, 0.5) that a cut far from the boundary is reported the other way
    method : stability method ("zoa", "sdm"); intervals, max_modes : SDM options
    draws : hammer-posterior draws used; particles : coefficient draws per posterior draw (None: default)
    min_ess : least effective number of draws accepted (>= 1; None: default)
    mcmc : bool, sample by MCMC when the ESS collapses (False: refuse); mcmc_steps, mcmc_walkers : its settings
    seed : int, seed of every random choice
    tool : tool of cuts without their own (default: the setup's only tool)
    speeds_rpm : (n,) rpm or None, compare hammer-only and with-cuts lobes and recommendations on this grid
    level : P(stable) of the recommendation in (0, 1]; speed_tolerance, depth_margin : fractions; max_depth : m
    allow_unusual : bool, coefficients outside the ranges for metals are a warning instead of an error

    Returns
    -------
    CutUpdate
    """
    with warning_log():
        from ..cuts import CoefficientPrior
        from ..cuts.joint_fit import as_boundary_width
        from ..cuts.mcmc import MCMCSettings
        from ..cuts.update import UpdateSettings
        from ..cuts.workflow import run_update
        from ..stability import Tolerances
        from ..stability.conditions import cutting_conditions
        from ..stability.methods import MethodOptions

        cutting, cut_warnings = cutting_conditions(kt=kt, kr=kr, flutes=flutes, radial_immersion=radial_immersion,
                                                   entry_angle=entry_angle, exit_angle=exit_angle, milling=milling,
                                                   feed=feed, pitch_angles=pitch_angles, allow_unusual=allow_unusual)
        prior = CoefficientPrior.from_tolerances(cutting.kt, kt_tolerance, cutting.kr, kr_tolerance)
        width = as_boundary_width(boundary_width)
        if not (0 <= label_error < 0.5):
            raise SetupError(f"--label-error {label_error}: expected a probability in [0, 0.5)")
        settings = UpdateSettings(**{k: v for k, v in (("particles_per_draw", particles), ("min_ess", min_ess))
                                     if v is not None})
        if settings.min_ess < 1:
            raise SetupError(f"--min-ess {min_ess}: expected >= 1")
        if not 0 < level <= 1:
            raise SetupError(f"--level {level}: expected a probability in (0, 1]")
        # the ± of kt is the prior spread that the cuts narrow, not a tolerance of the recommendation's neighbourhood
        tol = Tolerances(speed_tolerance, depth_margin, 0.0)
        if speeds_rpm is not None and clamping_length is None:
            raise SetupError("--speeds compares the lobes at --clamping-length; give --clamping-length M")
        options = MethodOptions(intervals=intervals, max_modes=max_modes)
        sampler = MCMCSettings(mcmc_walkers, mcmc_steps) if mcmc else None
        setup_path = getattr(setup, "path", setup)
        result = run_update(setup_path, _posterior_file(posterior), cuts, cutting, clamping_length, prior, width,
                            label_error, method, options, settings, draws, seed, tool,
                            None if speeds_rpm is None else np.asarray(speeds_rpm, dtype=float), level, tol, max_depth,
                            sampler)
        doc = result.document
        doc["warnings"] = merge_warnings(current_warnings(), cut_warnings, doc["warnings"])
        return CutUpdate(document=doc, setup=setup, warnings=tuple(doc["warnings"]), run=result)


def _posterior_file(posterior) -> Path:
    """The posterior.nc of ``posterior`` (a path, or a saved or loaded Posterior: its file)."""
    if isinstance(posterior, (str, Path)):
        return posterior
    if getattr(posterior, "path", None) is None:
        raise SetupError("update: the posterior is only in memory; the updated posterior.nc keeps the hammer "
                         "posterior's file data, so save it first (Posterior.save(folder))")
    return posterior.path


def _mpa(q) -> str:
    """A cutting coefficient's (q05, q50, q95) in Pa as ``790 MPa (780–800)`` (N/mm², as cutting data give it)."""
    lo, mid, hi = (None if v is None else v / 1e6 for v in q)
    return f"{num(mid)} MPa ({num(lo)}–{num(hi)})"
