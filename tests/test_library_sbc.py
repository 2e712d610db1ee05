"""The library stage-2 SBC's simulator draws the model docs/theory.md states ("Tool-library population").

The SBC itself (200 replicates of a default stage-2 fit, ~5 s each) is benchmarks/sbc_library.py, its table in
docs/calibration.md; what is checked here, cheaply, is that the truths and data it ranks come from the
hyperprior the fit assumes: SBC is only a test of the fit if the simulator is the model.
"""

from __future__ import annotations

import math

import numpy as np

from bayes_rcsa.library.population import Hyperprior, covariate
from bayes_rcsa.library.sbc import simulate_library, stage2_sbc_names


def test_the_simulated_libraries_follow_the_documented_hyperprior():
    hyper = Hyperprior.from_box(("k_xf",), np.array([[4.0, 10.0]]), 1.5)
    types = np.array([0, 0, 0, 1, 1, 1])
    x = covariate(np.array([0.006, 0.010, 0.016] * 2))
    C = np.full((6, 1, 1), 0.02)
    rng = np.random.default_rng(77)
    n = 10_000
    sims = [simulate_library(hyper, types, x, C, rng) for _ in range(n)]
    truth = np.array([t for t, _ in sims])
    names = stage2_sbc_names(hyper, 2)
    col = {k: truth[:, names.index(k)] for k in names}

    def close(value, want, se):  # within 4.5 standard errors: a false alarm in ~1e-5 of runs per check
        assert abs(value - want) < 4.5 * se, (value, want, se)

    a_mean, a_sd = float(hyper.a_mean[0]), float(hyper.a_sd[0])
    close(col["a_k_xf_T0"].mean(), a_mean, a_sd / math.sqrt(n))
    close(col["a_k_xf_T1"].std(), a_sd, a_sd / math.sqrt(2 * n))
    tb = float(hyper.tb_scale[0])
    close(col["tau_b_k_xf"].mean(), tb * math.sqrt(2 / math.pi), tb / math.sqrt(n))
    # b_t = b0 + tau_b delta_t: variance b_sd^2 + E tau_b^2, correlation between types b_sd^2 / that
    var_b = float(hyper.b_sd[0]) ** 2 + tb ** 2
    close(col["b_k_xf_T0"].var(), var_b, var_b * math.sqrt(2 / n))
    corr = np.corrcoef(col["b_k_xf_T0"], col["b_k_xf_T1"])[0, 1]
    close(corr, float(hyper.b_sd[0]) ** 2 / var_b, 2 / math.sqrt(n))
    # ln sigma_t = ln sigma0 + tau_s eps: mean ls_mean, variance ls_sd^2 + E tau_s^2 = ls_sd^2 + ts_scale^2
    ls = np.log(col["sigma_k_xf_T0"])
    var_ls = hyper.ls_sd ** 2 + hyper.ts_scale ** 2
    close(ls.mean(), float(hyper.ls_mean[0]), math.sqrt(var_ls / n))
    close(ls.var(), var_ls, var_ls * math.sqrt(2 / n) * 1.5)  # a mixture of normals: a wider sampling error
    # the surrogate means: m_s = a_t + b_t x_s + sigma_t eps + sqrt(C_s) eta
    g0 = np.array([g[0].m[:, 0] for _, g in sims])  # (n, 3) type 0's combinations
    resid = g0 - col["a_k_xf_T0"][:, None] - col["b_k_xf_T0"][:, None] * x[:3][None, :]
    # given its replicate's sigma_t, each residual has variance sigma_t^2 + C_s: the paired differences average 0
    diff = resid ** 2 - (col["sigma_k_xf_T0"][:, None] ** 2 + 0.02)
    close(diff.mean(), 0.0, diff.std() / math.sqrt(diff.size))
    close(resid.mean(), 0.0, resid.std() / math.sqrt(resid.size))
    assert [g.holder_type for g in sims[0][1]] == ["T0", "T1"] and sims[0][1][1].x.tolist() == x[3:].tolist()
