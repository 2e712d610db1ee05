"""Posterior draws of the contact parameters in physical units, with their growth law.

Predictions need, per draw, the six contact parameters ``k_xf``,
``k_thetaM`` (at the reference clamping length), ``g_xf``, ``g_thetaM``,
``c_xf`` and ``c_thetaM`` plus the growth law that carries the stiffness to
other clamping lengths.  They come either from an identification run in
memory (:func:`draws_from_result`) or from the ``posterior.nc`` it wrote
(:func:`load_posterior`, read through the inference package's reader).

``posterior.nc`` stores the *sampled* parameters only.  A parameter that was
held fixed in the fit is taken from an attribute ``fixed_<name>`` of the
file when present, and otherwise from the setup the fit was made from: a
growth factor absent from the file was fixed at 0 (one clamping length, or
``growth_bound = 0``), a damping absent from the file is the setup's fixed
``[contact]`` damping.  Anything else missing is an error, never a guess.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np

from ..errors import DataError, SetupError
from ..inference.parameters import GrowthLaw

__all__ = ["CONTACT_NAMES", "PosteriorDraws", "draws_from_result", "load_posterior"]

CONTACT_NAMES = ("k_xf", "k_thetaM", "g_xf", "g_thetaM", "c_xf", "c_thetaM")


@dataclass(frozen=True)
class PosteriorDraws:
    """Flat posterior draws of the contact parameters.

    Attributes
    ----------
    values : dict of str to (n_draws,) float
        Physical values of every name in :data:`CONTACT_NAMES` (N/m,
        N m/rad, 1, 1, N s/m, N m s/rad); fixed parameters are repeated.
    growth : GrowthLaw
        ``k(l) = k(l_a) (1 + g (l - l_a) / (l_b - l_a))``; without growth
        (single clamping length) the stiffness is the same at every length.
    method : str
        Identification method (``"multi"``, ``"single"``, ...).
    sampled : tuple of str
        Contact parameters that were sampled (the others were fixed).
    fit_lengths : tuple of float
        m, clamping lengths of the measurements used in the fit.
    source : str
        Where the draws came from (file name or ``"memory"``).
    """

    values: Mapping[str, np.ndarray]
    growth: GrowthLaw
    method: str = "multi"
    sampled: tuple[str, ...] = ()
    fit_lengths: tuple[float, ...] = ()
    source: str = "memory"

    def __post_init__(self) -> None:
        missing = [n for n in CONTACT_NAMES if n not in self.values]
        if missing:
            raise DataError(f"{self.source}: posterior draws lack {missing}")
        sizes = {np.asarray(self.values[n]).shape for n in CONTACT_NAMES}
        if len(sizes) != 1 or len(next(iter(sizes))) != 1 or next(iter(sizes))[0] == 0:
            raise DataError(f"{self.source}: posterior draws must be non-empty 1-D arrays of one length, got shapes {sizes}")

    @property
    def n_draws(self) -> int:
        return int(np.asarray(self.values["k_xf"]).size)

    def contact(self, lengths) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Contact parameters of every draw at ``lengths``.

        Parameters
        ----------
        lengths : (n_len,) m

        Returns
        -------
        k_xf, k_thetaM, c_xf, c_thetaM : each (n_draws, n_len)
        """
        lengths = np.atleast_1d(np.asarray(lengths, dtype=float))
        v = self.values
        kx = self.growth.stiffness(v["k_xf"], v["g_xf"], lengths)
        kt = self.growth.stiffness(v["k_thetaM"], v["g_thetaM"], lengths)
        shape = kx.shape
        cx = np.broadcast_to(np.asarray(v["c_xf"], dtype=float)[:, None], shape)
        ct = np.broadcast_to(np.asarray(v["c_thetaM"], dtype=float)[:, None], shape)
        return kx, kt, cx, ct

    def take(self, index) -> "PosteriorDraws":
        """The draws at ``index`` (an integer array or slice)."""
        values = {n: np.asarray(v)[index] for n, v in self.values.items()}
        return PosteriorDraws(values, self.growth, self.method, self.sampled, self.fit_lengths, self.source)

    def subset(self, max_draws: int | None, rng: np.random.Generator | None) -> "PosteriorDraws":
        """At most ``max_draws`` draws chosen at random without replacement (all if fewer)."""
        if max_draws is None or self.n_draws <= max_draws:
            return self
        if max_draws < 1:
            raise SetupError(f"max_draws = {max_draws!r}: expected a positive integer")
        if rng is None:
            raise SetupError("a random subset of posterior draws needs an explicit numpy.random.Generator")
        return self.take(np.sort(rng.choice(self.n_draws, max_draws, replace=False)))

    def median_values(self) -> dict[str, float]:
        """Posterior median of each contact parameter (physical units)."""
        return {n: float(np.median(self.values[n])) for n in CONTACT_NAMES}


def draws_from_result(result) -> PosteriorDraws:
    """Draws of an :class:`bayes_rcsa.inference.identify.IdentificationResult` in memory."""
    problem = result.problem
    values = problem.layout.values(result.flat_theta)
    sampled = tuple(n for n in CONTACT_NAMES if n in problem.layout.names)
    lengths = tuple(sorted({float(o.configuration.clamping_length) for o in problem.observations}))
    return PosteriorDraws({n: np.asarray(values[n], dtype=float) for n in CONTACT_NAMES}, problem.growth,
                          problem.method, sampled, lengths, "memory")


def _attrs(idata) -> dict:
    out: dict = {}
    for group in ("posterior", "sample_stats", "constant_data", "observed_data", "log_likelihood"):
        ds = getattr(idata, group, None)
        if ds is not None:
            out.update(dict(ds.attrs))
    return out


def load_posterior(path, setup=None) -> PosteriorDraws:
    """Read the draws of a ``posterior.nc`` written by ``bayes-rcsa identify``.

    Parameters
    ----------
    path : path-like
    setup : Setup, optional
        The setup the fit was made from; supplies fixed damping values that
        the file does not record.

    Raises
    ------
    DataError
        The file is not a bayes_rcsa posterior, or lacks a parameter that
        neither its attributes nor the setup supply.
    """
    from ..inference.diagnostics import read_netcdf

    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: posterior file not found (expected DIR/posterior.nc written by 'bayes-rcsa identify')")
    try:
        idata = read_netcdf(path)
    except Exception as exc:  # netCDF/HDF5 readers raise many unrelated types
        raise DataError(f"{path}: cannot read as an ArviZ InferenceData netCDF file ({exc})") from None
    post = getattr(idata, "posterior", None)
    if post is None:
        raise DataError(f"{path}: no 'posterior' group")
    attrs = _attrs(idata)
    for key in ("l_a", "l_b"):
        if key not in attrs:
            raise DataError(f"{path}: attribute {key!r} (growth law range) missing; not written by 'bayes-rcsa identify'?")
    growth = GrowthLaw(float(attrs["l_a"]), float(attrs["l_b"]), float(attrs.get("growth_bound", 0.0)))
    values: dict[str, np.ndarray] = {}
    sampled = []
    n = None
    for name in CONTACT_NAMES:
        if name in post.data_vars:
            values[name] = np.asarray(post[name].values, dtype=float).reshape(-1)
            n = values[name].size
            sampled.append(name)
    if n is None:
        raise DataError(f"{path}: the posterior holds none of the contact parameters {list(CONTACT_NAMES)}")
    for name in CONTACT_NAMES:
        if name in values:
            continue
        if f"fixed_{name}" in attrs:
            fixed = float(attrs[f"fixed_{name}"])
        elif name.startswith("g_"):
            fixed = 0.0
        elif setup is not None:
            spec = setup.contact.translational_damping if name == "c_xf" else setup.contact.rotational_damping
            if isinstance(spec, (list, tuple)):
                raise DataError(
                    f"{path}: {name} is not in the posterior, but the setup {setup.path} samples it "
                    f"({list(spec)}); was the posterior made from another setup?"
                )
            fixed = float(spec)
        else:
            raise DataError(f"{path}: {name} was fixed in the fit and its value is not recorded; pass the setup")
        values[name] = np.full(n, fixed)
    for name in ("k_xf", "k_thetaM"):
        if not np.all(np.isfinite(values[name]) & (values[name] > 0)):
            raise DataError(f"{path}: {name} draws must be finite and positive")
    fit_lengths: tuple[float, ...] = ()
    const = getattr(idata, "constant_data", None)
    if const is not None and "fit_clamping_length" in const.data_vars:
        fit_lengths = tuple(sorted({float(v) for v in np.asarray(const["fit_clamping_length"].values).ravel()}))
    return PosteriorDraws(values, growth, str(attrs.get("method", "multi")), tuple(sampled), fit_lengths, str(path))
