"""The true limit of a bench's test cuts by the project's SDM (``synthesize --cuts``, ``benchmarks/cuts.py``).

The bench (:mod:`bayes_rcsa.synthetic.cuts`) labels cuts with its own zero-order (ZOA) limit by
default, because ``synthetic`` may not import ``stability``.  The cut likelihood of this package uses ZOA
too, so a truth from the same approximation would share its method error with the model under test.
The semi-discretisation method (SDM) solves the delay equation with the time-varying directional
matrix, so it also holds where ZOA's tooth-pass average is poor (low immersion, few flutes); this
module passes it, from the layer above both, as the bench's ``true_limit``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SDM_TRUTH", "sdm_true_limit"]

#: The truth file's description of this method.
SDM_TRUTH = "sdm (the project's semi-discretisation on a modal fit of the noise-free FE FRFs, X and Y)"


def sdm_true_limit(plan):
    """A ``true_limit`` callable for :func:`bayes_rcsa.synthetic.cuts.generate_cuts`: SDM with the TRUE K_t, K_r.

    Parameters
    ----------
    plan : CutPlan
        Its true coefficients, flutes, radial immersion, milling and feed direction.

    Returns
    -------
    callable ``(frequency_hz (n_freq,), frf_x (n_freq,), frf_y (n_freq,), speed_rpm (n,)) -> (n,) m``
        The lowest SDM limit at each speed (+inf where SDM finds none).
    """
    from ..stability import CuttingConditions
    from ..stability.methods import STABILITY_METHODS, MethodOptions, method_names

    method_names()  # registers the built-in methods
    cutting = CuttingConditions(kt=plan.kt_true, kr=plan.kr_true, flutes=plan.flutes,
                                radial_immersion=plan.radial_immersion, milling=plan.milling, feed=plan.feed)
    sdm = STABILITY_METHODS.get("sdm")

    def limit(frequency_hz, frf_x, frf_y, speed_rpm):
        speeds = np.asarray(speed_rpm, dtype=float)
        unique, back = np.unique(speeds, return_inverse=True)  # the methods take increasing speeds
        res = sdm.depth_limits(np.asarray(frf_x)[None, :], np.asarray(frf_y)[None, :], frequency_hz, cutting,
                               unique, MethodOptions())
        return np.asarray(res.depth_limit_m, dtype=float)[0][back]

    return limit
