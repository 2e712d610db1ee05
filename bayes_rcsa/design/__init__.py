"""Which test next?  Expected information gain of the next hammer test.

* :mod:`.targets` -- the design target (natural frequency, contact stiffness or chatter limit at a clamping
  length) and candidate tests (clamping length, tool, direction);
* :mod:`.estimators` -- expected 90 % width after a test: nested Monte Carlo with importance re-weighting of
  posterior draws, and the Laplace/Fisher approximation;
* :mod:`.workflow` -- ranking candidates from a posterior (:func:`run_design`) and the no-data planning of two
  clamping lengths (:func:`run_planning`);
* :mod:`.outputs` -- design.json and the plot.

See docs/design.md.
"""

from .estimators import ESS_MIN, NoiseLevel, WidthEstimate, importance_widths, laplace_widths
from .targets import Candidate, Target, parse_candidates, parse_target
from .workflow import (
    WORTH_IT_FRACTION,
    DesignResult,
    PlanningResult,
    design_from_draws,
    run_design,
    run_planning,
)

__all__ = [
    "ESS_MIN", "NoiseLevel", "WidthEstimate", "importance_widths", "laplace_widths",
    "Candidate", "Target", "parse_candidates", "parse_target",
    "WORTH_IT_FRACTION", "DesignResult", "PlanningResult", "design_from_draws", "run_design", "run_planning",
]
