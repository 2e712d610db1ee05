"""Synthetic impact-hammer campaigns with hidden effects: the test bench.

Data are made by a *different and richer* model than the one identified
(no inverse crime): a full-assembly Timoshenko finite-element model of
spindle shaft on bearings, holder taper, holder and clamped tool, with the
contact lumped at the holder tip or spread along the clamping length, plus
hidden effects that the user's setup does not know about.  See
docs/synthetic.md.

Main entry points
-----------------
:class:`BenchConfig`, :func:`default_bench_config`, :func:`load_bench_config`
    What to simulate.
:func:`generate_campaign` -> :class:`Campaign`
    Spindle files, noisy tool-point FRFs, user setup, truth.
:func:`write_campaign`
    One directory: spindle_x.csv (+ y), tip_*.csv, setup.toml, truth.json.
:func:`true_tool_point_frf`
    Noise-free tool-point receptance of the true structure.
"""

from .bench import (
    build_assembly,
    exported_spindle_receptance,
    true_contact,
    true_spindle_receptance,
    true_tool,
    true_tool_point_frf,
)
from .campaign import Campaign, dominant_peak, generate_campaign, measured_mean_frf, tip_file_name, write_campaign
from .config import BenchConfig, default_bench_config, load_bench_config
from .effects import CANONICAL_EFFECTS, DEFAULT_MAGNITUDES, HIDDEN_EFFECTS, stiffness_factor
from .spindle import Bearing, ShaftSegment, SpindleModel

__all__ = [
    "BenchConfig", "default_bench_config", "load_bench_config",
    "Campaign", "generate_campaign", "write_campaign", "measured_mean_frf", "tip_file_name", "dominant_peak",
    "true_tool_point_frf", "true_contact", "true_tool", "true_spindle_receptance", "exported_spindle_receptance",
    "build_assembly",
    "HIDDEN_EFFECTS", "CANONICAL_EFFECTS", "DEFAULT_MAGNITUDES", "stiffness_factor",
    "SpindleModel", "ShaftSegment", "Bearing",
]
