"""The prior of the unexplained remainder's law shape: the physics envelope, or a tool library's population.

The remainder (workflow.py, :data:`~.workflow.REMAINDER_TERMS`) adds ``law_shape_uncertainty``, whose one
parameter ``law_shape_bend`` (``u``, 1) places the contact-stiffness law between the fitted clamping lengths
between the parallel (linear, ``u = 0``) and the series two-spring law (``u = 1``).  With two fitted lengths
the taps do not identify ``u``, so its prior is what the held-out intervals carry: by default the physics
envelope, uniform on [0, 1].  Where a tool library pools ``u`` over combinations of the setup's holder type
fitted at three or more lengths, the population predictive of ``u`` for that type and shank diameter
(:func:`bayes_rcsa.library.predictive.law_shape_prior`, computed by the workflows layer: the library sits
above this package) replaces it, as a normal truncated to [0, 1] (:class:`LawShapePrior`).

The prior enters through the ``[model]`` table of the refitted problem (``law_shape_bend = {distribution =
"normal", ...}``), the setup file's own way of giving a term's parameter a prior; a setup whose ``[model]``
already gives ``law_shape_bend`` a prior keeps it.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import SetupError
from ..params.priors import Normal
from ..params.terms.law_shape_uncertainty import BEND, LawShapeUncertainty

__all__ = ["LawShapePrior", "LAW_SHAPE_TERM", "LAW_SHAPE_PARAMETER", "law_shape_overrides", "law_shape_report"]

#: The remainder's law-shape term and its one parameter.
LAW_SHAPE_TERM = LawShapeUncertainty.name
LAW_SHAPE_PARAMETER = BEND

#: What the report says of the envelope (no library, or a library that does not pool the bend).
ENVELOPE_TEXT = "the physics envelope, uniform between the parallel and the series law"


@dataclass(frozen=True)
class LawShapePrior:
    """A tool library's prior of the law bend ``u`` (``law_shape_bend``) for one setup.

    Attributes
    ----------
    prior : Normal, truncated to [0, 1] (1)
    holder_type : str, the setup's holder type in the library
    n_combinations : int or None, combinations of that type pooled (None: not recorded in the population file)
    mean, sd, q05, q95 : float, the population predictive of ``u`` for this holder type and shank diameter (1)
    shank_diameter_m : float, m
    """

    prior: Normal
    holder_type: str
    n_combinations: int | None
    mean: float
    sd: float
    q05: float
    q95: float
    shank_diameter_m: float

    def __post_init__(self) -> None:
        if not isinstance(self.prior, Normal) or self.prior.bounds != (0.0, 1.0):
            raise SetupError(f"law shape prior {self.prior!r}: expected a normal truncated to [0, 1]")

    @classmethod
    def from_library(cls, prior: Normal, info: dict) -> "LawShapePrior":
        """From :func:`bayes_rcsa.library.predictive.law_shape_prior`'s prior and info dict."""
        return cls(prior, str(info["holder_type"]), info.get("n_combinations"), float(info["mean"]),
                   float(info["sd"]), float(info["q05"]), float(info["q95"]), float(info["shank_diameter_m"]))

    def describe(self) -> dict:
        """The report's entry (``law_shape_prior`` of discrepancy.json)."""
        n = "" if self.n_combinations is None else f" ({self.n_combinations} combinations)"
        return {"source": "library", "holder_type": self.holder_type, "n_combinations": self.n_combinations,
                "shank_diameter_m": self.shank_diameter_m, "mean": self.mean, "sd": self.sd, "q05": self.q05,
                "q95": self.q95, "prior": self.prior.describe(),
                "text": f"library population of holder type {self.holder_type}{n}: mean {self.mean:.2f}, "
                        f"sd {self.sd:.2f}"}


def law_shape_overrides(law_shape: LawShapePrior | None, terms, model_table: dict) -> dict:
    """The ``[model]`` entries that give the remainder's law bend the library's prior (empty: keep the default).

    Parameters
    ----------
    law_shape : LawShapePrior or None
    terms : sequence of str, the terms the remainder adds
    model_table : dict, the setup's ``[model]`` table (a ``law_shape_bend`` it sets is the user's and wins)
    """
    if law_shape is None or LAW_SHAPE_TERM not in terms or LAW_SHAPE_PARAMETER in model_table:
        return {}
    return {LAW_SHAPE_PARAMETER: law_shape.prior.describe()}


def law_shape_report(final, law_shape: LawShapePrior | None) -> dict | None:
    """Which prior the final model's law bend had, for discrepancy.json's ``law_shape_prior``.

    Parameters
    ----------
    final : ModelFit, the final model
    law_shape : LawShapePrior or None, the library's prior given to the workflow

    Returns
    -------
    None when the final model samples no law bend; else a dict with ``source``
    (``"library"``, ``"envelope"`` or ``"setup"``), ``text`` (plain words) and, for a library, its numbers.
    """
    pm = final.problem.parameters
    if LAW_SHAPE_PARAMETER not in pm.names or not pm[LAW_SHAPE_PARAMETER].sampled:
        return None
    prior = pm[LAW_SHAPE_PARAMETER].prior
    if law_shape is not None and prior == law_shape.prior:
        return law_shape.describe()
    desc = prior.describe()
    if desc.get("distribution") == "uniform" and prior.bounds == (0.0, 1.0):
        return {"source": "envelope", "text": ENVELOPE_TEXT, "prior": desc}
    return {"source": "setup", "text": "the prior the setup's [model] table gives", "prior": desc}
