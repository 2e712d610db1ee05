"""Shared helpers of the inference tests (this module holds no tests).

Data come from the synthetic bench (:mod:`bayes_rcsa.synthetic`): an
independent finite-element model of the whole assembly, so the forward
model being identified is not the one that made the data.
"""

from __future__ import annotations

import numpy as np

from bayes_rcsa.inference.sampler import SamplerSettings
from bayes_rcsa.io.setup import ContactSpec
from bayes_rcsa.model import Configuration, ToolPointModel
from bayes_rcsa.posterior import natural_frequency
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, true_contact, true_tool_point_frf

__all__ = ["bench", "contact_spec", "bench_model", "true_natural_frequency", "quick_settings", "true_k"]


def bench(seed: int = 0, **overrides):
    """(config, campaign) of the default bench, x direction only unless overridden."""
    overrides.setdefault("directions", ("x",))
    cfg = default_bench_config(**overrides)
    return cfg, generate_campaign(cfg, np.random.default_rng(seed))


def contact_spec(campaign) -> ContactSpec:
    """The user's contact priors, read from the campaign's setup dictionary."""
    c = campaign.setup["contact"]
    return ContactSpec(
        translational_stiffness=tuple(c["translational_stiffness"]),
        rotational_stiffness=tuple(c["rotational_stiffness"]),
        growth_bound=c["growth_bound"],
        clamping_range=tuple(c["clamping_range"]),
        translational_damping=c["translational_damping"],
        rotational_damping=c["rotational_damping"],
    )


def bench_model(cfg, campaign) -> ToolPointModel:
    """The RCSA model the user would build (exported spindle, nominal geometry)."""
    return ToolPointModel(cfg.holder, {"tool": cfg.tool}, campaign.spindle)


def true_natural_frequency(cfg, clamping_length: float, frequency_hz, band=None) -> float:
    """The natural-frequency rule applied to the bench's noise-free FRF."""
    h = true_tool_point_frf(cfg, Configuration(clamping_length, "x"), frequency_hz)
    return float(natural_frequency(frequency_hz, h, band))


def true_k(cfg, clamping_length: float) -> float:
    return float(true_contact(cfg, clamping_length)["k_xf"])


def quick_settings(**kw) -> SamplerSettings:
    """Sampler settings for cheap test runs (no progress output)."""
    kw.setdefault("progress", False)
    return SamplerSettings(**kw)
