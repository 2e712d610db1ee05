"""Cutting tests update the hammer-test posterior: the acceptance tables of issue #23.

Run (2 shared cores, progress on stdout; tables in docs/stability.md, "Cutting tests: benchmark")::

    OMP_NUM_THREADS=1 nice python benchmarks/cuts.py --json full.json          # 1-3: ~25-40 min, cost row
    OMP_NUM_THREADS=1 nice python benchmarks/cuts.py --anchor-mcmc anchor.json  # the MCMC anchor, ~15 min
    python benchmarks/cuts.py --combine full.json anchor.json                   # the anchor table
    python benchmarks/cuts.py --cost-only --runs 5                              # the cost row again

Campaigns (seeds 5000, 5001, ...)
---------------------------------
Each campaign is its own FE bench (:mod:`bayes_rcsa.synthetic`, lumped contact): the true contact
stiffnesses k_xf, k_thetaM scaled by U(0.8, 1.2), a hammer campaign with its own noise, ``bayes-rcsa
identify`` from the 25 and 40 mm tool-point FRFs (X and Y), and test cuts at a clamping length the hammer
test did NOT measure (30 mm in even, 35 mm in odd campaigns: the RCSA transfer).  The cutting conditions
are case B of docs/stability.md (4 flutes, 95 % immersion, down milling, feed Y) with the assumed
K_t = 790 MPa, K_r = 230 MPa; the truth's coefficients are 20 % off (x1.2 in campaigns 0, 1, 4, 5, ...,
x0.8 in 2, 3, 6, 7, ...; K_t and K_r together).  Outcomes come from the truth
(:mod:`bayes_rcsa.synthetic.cuts`: the bench's own ZOA on the noise-free FE FRFs), without label noise.
Cuts lie in 5000-30000 rpm x 5-80 um (the bench's slender end mill chatters at 10-50 um between lobes).

The update (what the benchmark measures)
----------------------------------------
Recovery: :func:`bayes_rcsa.cuts.update.importance_update` itself (1000 hammer draws x 32 particles, the
``--kt 790e6±30%`` level prior, w = 0.1, label error 0.01, refusal below an ESS of 50).  The design races
re-weight a pool of the same draws x ``--pairs`` level draws with the same likelihood after every cut
(limits computed once at K_t = 1 and divided by the level: the ZOA limit is exactly inversely
proportional to a common scale of K_t and K_r).

Tables
------
1. Recovery (``--campaigns``, 10 random cuts, and 10 cuts chosen one by one by ``--next-cut``): coverage of the true K_t by the 90 % interval
   (Clopper-Pearson), mean absolute P(stable) error on the truth's 50 x 50 map for hammer only (assumed
   K_t), hammer + K_t prior, hammer + 10 cuts, and whether the robust recommended point (P(stable) >= 0.95,
   +-2 % speed, 10 % depth margin; :func:`bayes_rcsa.stability.recommend`) is stable in the truth over its
   whole speed window.
2. Design (``--design-campaigns``): cuts one at a time, chosen by ``--next-cut`` (map target,
   :func:`bayes_rcsa.cuts.next_cut.rank_next_cuts`, 25 speeds x 15 depths, no risk budget and with a 0.3
   budget), at random in the box, or on a 5 x 4 grid of the box visited in a seeded random order; the number
   of cuts until the map error is at most half of the hammer-only error (at most 20).
3. Against the anchor: the same race from generic modal priors (no hammer test; the Cornelius/Schmitz
   setting with one mode, the same in X and Y as on this symmetric bench: f_n log-normal (median 1000 Hz,
   sigma 0.2), k log-normal (median 1e6 N/m, sigma 0.5), zeta log-normal (median 0.02, sigma 0.5); medians
   near the bench's true dominant mode (963 Hz, 8.4e5 N/m, 0.011 at 30 mm), i.e. a favourable anchor),
   sampled by emcee after every cut (``--anchor-mcmc``; :class:`OneModeLimits`), next-cut and random
   choice, 20 cuts; ``--combine`` counts the cuts to the race's target.  ``--anchor-draws N`` adds the
   importance-sampled anchor (N prior draws re-weighted; it collapses, ESS 2-15 after 20 designed cuts).
4. Cost: the update from 20 cuts on a 1000-draw posterior with ZOA.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bayes_rcsa.cuts import (DEFAULT_BOUNDARY_WIDTH, DEFAULT_LABEL_ERROR, BoundaryWidth, CoefficientPrior, CutGroup,
                             CutLikelihood, inverse_limits_at_cuts, outcome_log_likelihood)
from bayes_rcsa.cuts.next_cut import candidate_grid, parse_next_cut_target, rank_next_cuts
from bayes_rcsa.cuts.update import UpdateSettings, importance_update
from bayes_rcsa.errors import ConvergenceError
from bayes_rcsa.stability import CuttingConditions, Tolerances, recommend, zoa_lobes
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign
from bayes_rcsa.synthetic.cuts import CutPlan, label_cuts, true_cut_frfs, true_depth_limit

sys.path.insert(0, str(Path(__file__).resolve().parent))
from discrepancy import clopper_pearson  # noqa: E402  (benchmarks share one Clopper-Pearson interval)

SEED0 = 5000
KT, KR = 790e6, 230e6
CUT = dict(flutes=4, radial_immersion=0.95, milling="down", feed="y")
SPEEDS = (5000.0, 30000.0)
DEPTHS = (5e-6, 8e-5)
LENGTHS = (0.030, 0.035)
BOUNDARY_WIDTH = DEFAULT_BOUNDARY_WIDTH  # the update's defaults: w = 0.1, label error 0.01
LABEL_ERROR = DEFAULT_LABEL_ERROR
KT_SIGMA = math.log(1.3)  # "--kt 790e6±30%": log-normal level, sd ln(1.3), as bayes-rcsa update
LEVEL = 0.95
ANCHOR_FN, ANCHOR_K, ANCHOR_ZETA = 1000.0, 1e6, 0.02  # generic one-mode priors (medians), near the truth
RANK_DRAWS = 2000
#: Stability method of the truth ("sdm": the project's SDM on the true FRFs, set by --truth; "zoa": the bench's own).
TRUTH = {"method": "sdm"}
FINE = np.linspace(SPEEDS[0], SPEEDS[1], 501)  # speeds of cuts in the design race and of the recommendation


def unit_cutting() -> CuttingConditions:
    """Case B at K_t = 1 Pa, K_r = K_r/K_t: limits for K_t = s KT are these / (s KT)."""
    return CuttingConditions(kt=1.0, kr=KR / KT, **CUT)


def log_lik(depth, stable, limits):
    """Log-likelihood of cut outcomes (the update's probit), (N,) from depths (C,), outcomes (C,), limits (N, C)."""
    return outcome_log_likelihood(np.asarray(depth)[None, :], limits, ~np.asarray(stable)[None, :], BOUNDARY_WIDTH,
                                  LABEL_ERROR).sum(axis=1)


def normalise(ll):
    w = np.exp(ll - np.max(ll))
    return w / w.sum()


def weighted_quantiles(values, weights, qs):
    o = np.argsort(values)
    c = np.cumsum(weights[o]) - 0.5 * weights[o]
    return np.interp(qs, c, values[o])


def p_map(limits, weights, depths):
    """P(stable) (S, A) of weighted draws with limits (N, S)."""
    return np.einsum("n,nsa->sa", weights, (depths[None, None, :] < limits[:, :, None]).astype(float))


class Truth:
    """Campaign i's bench, cut plan and truth (the true limits on the fine speed grid and the 50 x 50 map)."""

    def __init__(self, i: int):
        self.i = i
        self.seed = SEED0 + i
        self.rng = np.random.default_rng(self.seed)
        u = self.rng.uniform(0.8, 1.2, 2)
        self.cfg = default_bench_config(k_xf=1.8e6 * u[0], k_thetaM=4.5e5 * u[1], seed=self.seed)
        self.length = LENGTHS[i % 2]
        self.factor = 1.2 if (i // 2) % 2 == 0 else 0.8
        self.plan = CutPlan(n_cuts=10, clamping_length=self.length, speed_range=SPEEDS, depth_range=DEPTHS,
                            kt_assumed=KT, kr_assumed=KR, kt_error=self.factor - 1, kr_error=self.factor - 1, **CUT)
        f = np.arange(self.cfg.frequency_start, self.cfg.frequency_stop + 1e-9, 1.0)
        self.true_frfs = (f, *true_cut_frfs(self.cfg, self.length, f))
        self.sdm = None
        if TRUTH["method"] == "sdm":
            from bayes_rcsa.cuts.truth import sdm_true_limit

            self.sdm = sdm_true_limit(self.plan)
        self.map_speed = np.linspace(SPEEDS[0], SPEEDS[1], 50)
        self.map_depth = np.linspace(DEPTHS[1] / 50, DEPTHS[1], 50)
        self.map_truth = self.map_depth[None, :] < self.true_limit(self.map_speed)[:, None]
        self.fine_truth = self.true_limit(FINE)

    def true_limit(self, speeds):
        if self.sdm is not None:
            return self.sdm(*self.true_frfs, np.atleast_1d(np.asarray(speeds, dtype=float)))
        return true_depth_limit(self.cfg, self.plan, speeds, self.true_frfs)

    def cut_truth(self) -> dict:
        """``generate_cuts`` keywords: the same truth for its random cuts."""
        if self.sdm is None:
            return {}
        from bayes_rcsa.cuts.truth import SDM_TRUTH

        return {"true_limit": lambda f, gx, gy, speeds: self.true_limit(speeds), "truth_method": SDM_TRUTH}

    def map_error(self, p):
        return float(np.mean(np.abs(p - self.map_truth)))


class Campaign(Truth):
    """One bench, its hammer-test posterior draws at the cut length, and its truth."""

    def __init__(self, i: int, tmp: Path, n_draws: int, pairs: int):
        super().__init__(i)
        rng = self.rng
        t0 = time.perf_counter()
        out = tmp / f"c{i}"
        setup = write_campaign(generate_campaign(self.cfg, rng), out)
        from bayes_rcsa.cli.main import main as cli

        status = cli(["identify", str(setup), "--out", str(out / "id"), "--lengths", "0.025,0.040",
                      "--seed", str(self.seed), "--no-plots", "--quiet"])
        if status != 0:
            raise SystemExit(f"campaign {i}: identify failed")
        self.t_identify = time.perf_counter() - t0
        self.setup, self.posterior = setup, out / "id" / "posterior.nc"
        from bayes_rcsa.stability.posterior_frf import posterior_frf_draws

        frf = posterior_frf_draws(setup, self.posterior, self.length, n_draws, rng)
        self.frf = frf
        # unit-K_t limits of the hammer draws on the map and fine speeds
        speeds = np.unique(np.concatenate([self.map_speed, FINE]))
        lim = zoa_lobes(frf.frf_x, frf.frf_y, frf.frequency_hz, unit_cutting(), speeds).depth_limit_m
        self.unit_map = lim[:, np.searchsorted(speeds, self.map_speed)]
        self.unit_fine = lim[:, np.searchsorted(speeds, FINE)]
        # pool: every theta draw with `pairs` prior draws of the coefficient scale
        self.theta = np.repeat(np.arange(n_draws), pairs)
        self.scale = np.exp(rng.normal(0.0, KT_SIGMA, self.theta.size))

    def unit_at(self, speeds):
        return zoa_lobes(self.frf.frf_x, self.frf.frf_y, self.frf.frequency_hz, unit_cutting(),
                         np.asarray(speeds)).depth_limit_m

    def pool_limits(self, unit):
        """Limits (N, k) of the pool from unit-K_t limits (n_draws, k) of the theta draws."""
        return unit[self.theta] / (KT * self.scale[:, None])


def window_stable(c: Campaign, rec) -> bool:
    """The recommended depth is below the true limit over the whole speed window (fine grid + ends + point)."""
    lo, hi = rec.speed_window_rpm
    s = np.unique(np.concatenate([[lo, hi, rec.spindle_speed_rpm], FINE[(FINE >= lo) & (FINE <= hi)]]))
    return bool(rec.depth_m < np.min(c.true_limit(s)))


def resample(weights, n, rng):
    """Systematic resampling: n indices with frequencies proportional to the weights."""
    u = (rng.random() + np.arange(n)) / n
    return np.minimum(np.searchsorted(np.cumsum(weights), u), weights.size - 1)


def product_update(c: Campaign, speed, depth, stable, seed) -> dict:
    """``bayes_rcsa.cuts`` importance update (32 particles per draw, ESS >= 50) of the cuts on the campaign's
    draws: K_t interval and coverage, map error and robust recommendation, or the refusal."""
    prior = CoefficientPrior.from_tolerances(KT, 0.3, KR, 0.0)
    group = CutGroup(c.frf.frf_x, c.frf.frf_y, c.frf.frequency_hz, CuttingConditions(kt=KT, kr=KR, **CUT),
                     np.arange(speed.size), speed)
    inv = inverse_limits_at_cuts([group], speed.size, prior)
    rng = np.random.default_rng(seed)
    try:
        res = importance_update(CutLikelihood(inv, depth, ~stable, LABEL_ERROR), prior, BoundaryWidth(), rng,
                                UpdateSettings())
    except ConvergenceError as exc:
        return {"refused": str(exc)}
    lo, hi = np.quantile(res.kt, [0.05, 0.95])
    lvl = np.exp(res.particle_u)[:, None]
    post = p_map(c.unit_map[res.particle_draw] / (KT * lvl), res.weights, c.map_depth)
    rec = recommend(FINE, c.unit_fine[res.draw] / (KT * np.exp(res.u)[:, None]), LEVEL, Tolerances())["recommended"]
    return {"kt_lo": float(lo), "kt_hi": float(hi), "covered": bool(lo <= c.plan.kt_true <= hi),
            "ess": res.ess_draws, "err": c.map_error(post), "n_stable": int(np.sum(stable)),
            "rec": None if rec is None else (rec.spindle_speed_rpm, rec.depth_m),
            "rec_stable": None if rec is None else window_stable(c, rec), "refused": None}


def recovery(c: Campaign) -> dict:
    """10 random cuts, and 10 cuts chosen one by one with --next-cut (map target), each updated by bayes_rcsa.cuts."""
    from bayes_rcsa.synthetic.cuts import generate_cuts

    cuts = generate_cuts(c.cfg, c.plan, np.random.default_rng([c.seed, 1]), **c.cut_truth())
    _, _, _, made = sequence(c, c.unit_map, c.unit_fine, c.theta, c.scale, "next", np.random.default_rng([c.seed, 6]),
                             max_cuts=c.plan.n_cuts)
    n_draws, n_pool = c.unit_map.shape[0], c.theta.size
    hammer = p_map(c.unit_map / KT, np.full(n_draws, 1 / n_draws), c.map_depth)
    prior = p_map(c.pool_limits(c.unit_map), np.full(n_pool, 1 / n_pool), c.map_depth)
    rec_hammer = recommend(FINE, c.unit_fine / KT, LEVEL, Tolerances())["recommended"]
    out = {"campaign": c.i, "length_mm": 1e3 * c.length, "factor": c.factor, "kt_true": c.plan.kt_true,
           "err_hammer": c.map_error(hammer), "err_prior": c.map_error(prior),
           "rec_hammer_stable": None if rec_hammer is None else window_stable(c, rec_hammer), "t_identify": c.t_identify}
    for prefix, (s, a, st) in (("random_", (cuts.speed_rpm, cuts.depth_m, cuts.stable)), ("next_", made)):
        out.update({prefix + k: v for k, v in product_update(c, s, a, st, c.seed).items()})
    return out


# ------------------------------------------------------------------ design race --
def sequence(c: Campaign, unit_map, unit_fine, theta, scale, strategy: str, rng, max_cuts=20, stop_err=None,
             risk_budget=1.0) -> tuple[int | None, list, np.ndarray, tuple]:
    """Cuts one at a time (strategy next/random/grid) from the pool (theta, scale).

    Returns (cuts until the map error is <= stop_err or None, map error after each cut, final weights,
    (speeds, depths, stable) of the cuts made).
    """
    pool_map = unit_map[theta] / (KT * scale[:, None])
    pool_fine = unit_fine[theta] / (KT * scale[:, None])
    ll = np.zeros(theta.size)
    cs, ca = candidate_grid(SPEEDS, DEPTHS, 25, 15)
    ci = np.searchsorted(FINE, cs)
    cs = FINE[ci]  # candidate speeds on the fine grid (25 of its 501 speeds)
    grid_s = FINE[np.round(np.linspace(0.1, 0.9, 5) * 500).astype(int)]
    grid_a = DEPTHS[0] + (np.arange(4) + 0.5) * (DEPTHS[1] - DEPTHS[0]) / 4
    gs, ga = (x.ravel() for x in np.meshgrid(grid_s, grid_a, indexing="ij"))
    grid_order = rng.permutation(gs.size)
    errors, made = [], []
    target = parse_next_cut_target("map")
    for n in range(max_cuts):
        w = normalise(ll)
        if strategy == "next":
            # large pools are ranked on RANK_DRAWS draws resampled by weight (the update uses the whole pool)
            use, wr = (np.arange(w.size), w) if w.size <= RANK_DRAWS else (resample(w, RANK_DRAWS, rng), None)
            r = rank_next_cuts(target, cs, ca, pool_fine[use][:, ci], c.map_speed, c.map_depth, pool_map[use], wr,
                               BOUNDARY_WIDTH, risk_budget, label_error=LABEL_ERROR)
            best = r.best or r.candidates[0]
            k, a = int(np.searchsorted(FINE, best.speed_rpm)), best.depth_m
        elif strategy == "random":
            k, a = int(rng.integers(FINE.size)), float(rng.uniform(*DEPTHS))
        else:
            j = grid_order[n % gs.size]
            k, a = int(np.searchsorted(FINE, gs[j])), float(ga[j])
        stable, _ = label_cuts(np.array([a]), c.fine_truth[k:k + 1], 0.0, rng)
        made.append((FINE[k], a, bool(stable[0])))
        ll += log_lik(np.array([a]), stable, pool_fine[:, k:k + 1])
        errors.append(c.map_error(p_map(pool_map, normalise(ll), c.map_depth)))
        if stop_err is not None and errors[-1] <= stop_err:
            return n + 1, errors, normalise(ll), tuple(np.array(v) for v in zip(*made))
    return None, errors, normalise(ll), tuple(np.array(v) for v in zip(*made))


def generic_modal_draws(c: Campaign, n: int, rng):
    """Unit-K_t limits (n, map) and (n, fine) of one-mode FRFs from generic priors (the same mode in X and Y)."""
    f = c.frf.frequency_hz
    fn = ANCHOR_FN * np.exp(rng.normal(0, 0.2, n))
    k = ANCHOR_K * np.exp(rng.normal(0, 0.5, n))
    z = ANCHOR_ZETA * np.exp(rng.normal(0, 0.5, n))
    r = f[None, :] / fn[:, None]
    g = 1.0 / (k[:, None] * (1 - r**2 + 2j * z[:, None] * r))
    speeds = np.unique(np.concatenate([c.map_speed, FINE]))
    lim = zoa_lobes(g, g, f, unit_cutting(), speeds).depth_limit_m
    return lim[:, np.searchsorted(speeds, c.map_speed)], lim[:, np.searchsorted(speeds, FINE)]


def design(c: Campaign, pairs: int, anchor_draws: int) -> dict:
    n_draws = c.unit_map.shape[0]
    hammer_err = c.map_error(p_map(c.unit_map / KT, np.full(n_draws, 1 / n_draws), c.map_depth))
    target = 0.5 * hammer_err
    theta = np.repeat(np.arange(n_draws), pairs)
    rng = np.random.default_rng([c.seed, 2])
    scale = np.exp(rng.normal(0.0, KT_SIGMA, theta.size))
    out = {"campaign": c.i, "hammer_err": hammer_err, "target": target}
    for name, kw in (("next", {}), ("next_budget", {"risk_budget": 0.3}), ("random", {}), ("grid", {})):
        t0 = time.perf_counter()
        n, errs, _, _ = sequence(c, c.unit_map, c.unit_fine, theta, scale, name.split("_")[0],
                              np.random.default_rng([c.seed, 3]), stop_err=target, **kw)
        out[name] = n
        out[name + "_errors"] = errs
        print(f"    design {c.i} {name}: {n} cuts ({time.perf_counter() - t0:.0f} s)", flush=True)
    if not anchor_draws:
        return out
    rng = np.random.default_rng([c.seed, 4])
    um, uf = generic_modal_draws(c, anchor_draws, rng)
    a_theta = np.arange(anchor_draws)
    a_scale = np.exp(rng.normal(0.0, KT_SIGMA, anchor_draws))
    out["anchor_prior_err"] = c.map_error(p_map(um / (KT * a_scale[:, None]), np.full(anchor_draws, 1 / anchor_draws),
                                                c.map_depth))
    for name in ("next", "random"):
        n, errs, w, _ = sequence(c, um, uf, a_theta, a_scale, name, np.random.default_rng([c.seed, 3]),
                              stop_err=target)
        out["anchor_" + name] = n
        out["anchor_" + name + "_errors"] = errs
        out["anchor_" + name + "_ess"] = float(1 / np.sum(w**2))
        print(f"    anchor {c.i} {name}: {n} cuts (ESS {out['anchor_' + name + '_ess']:.0f})", flush=True)
    return out


# ------------------------------------------------------------- anchor by MCMC --
ANCHOR_ZETAS = np.exp(np.linspace(np.log(0.002), np.log(0.2), 25))
ANCHOR_R = np.exp(np.linspace(np.log(2.0), np.log(100.0), 4000))  # n / f_n, rpm per Hz
ANCHOR_SD = np.array([0.2, 0.5, 0.5, KT_SIGMA])  # prior sd of ln f_n, ln k, ln zeta, u
ANCHOR_MEAN = np.array([np.log(ANCHOR_FN), np.log(ANCHOR_K), np.log(ANCHOR_ZETA), 0.0])


class OneModeLimits:
    """ZOA limit of one mode (the same in X and Y) for any (f_n, k, zeta, u), case B.

    For G = G1(f / f_n; zeta) / k the ZOA boundary scales exactly: a_lim(n) = k / (K_t) A(n / f_n; zeta), so
    one table A(r, zeta) (``zoa_lobes`` on one-mode FRFs at f_n = 1000 Hz, k = 1, 24001 log-spaced lines from
    50 to 8000 Hz, 25 log-spaced damping ratios 0.002-0.2, 4000 log-spaced r = 2-100 rpm/Hz) interpolated
    bilinearly in (ln zeta, ln r) of ln A gives the limit of any draw; where the table finds no limit (the
    chatter frequency outside its band) ln A is set to ln 1 m (no chatter in the map).
    """

    def __init__(self):
        from scipy.interpolate import RegularGridInterpolator

        fn = 1000.0
        f = fn * np.exp(np.linspace(np.log(0.05), np.log(8.0), 24001))
        r = f[None, :] / fn
        g = 1.0 / (1 - r**2 + 2j * ANCHOR_ZETAS[:, None] * r)
        lim = zoa_lobes(g, g, f, unit_cutting(), fn * ANCHOR_R).depth_limit_m  # (Z, R) m at K_t = 1, k = 1
        table = np.log(np.where(np.isfinite(lim), lim, 1.0 * 1e3 * KT))  # no limit: 1 m at the assumed K_t
        self.interp = RegularGridInterpolator((np.log(ANCHOR_ZETAS), np.log(ANCHOR_R)), table,
                                              bounds_error=False, fill_value=None)

    def __call__(self, x, speeds):
        """Limits (n, k) m of draws x (n, 4) = (ln f_n, ln k, ln zeta, u) at speeds (k,) rpm."""
        lr = np.log(np.asarray(speeds, dtype=float))[None, :] - x[:, 0:1]
        lz = np.broadcast_to(x[:, 2:3], lr.shape)
        a = self.interp(np.stack([lz, lr], axis=-1))
        return np.exp(a + x[:, 1:2] - x[:, 3:4]) / KT


def anchor_mcmc_race(t: Truth, table: OneModeLimits, strategy: str, target_err: float, max_cuts=20, n_prior=4000,
                     walkers=32, steps=600) -> dict:
    """The anchor's race with a proper posterior: emcee over (ln f_n, ln k, ln zeta, u) after every cut."""
    import emcee

    rng = np.random.default_rng([t.seed, 7])
    x = ANCHOR_MEAN + ANCHOR_SD * rng.standard_normal((n_prior, 4))
    lo, hi = np.log(ANCHOR_ZETAS[0]), np.log(ANCHOR_ZETAS[-1])
    x[:, 2] = np.clip(x[:, 2], lo, hi)  # the table's damping range (the prior's +-4.6 sd)
    cs, ca = candidate_grid(SPEEDS, DEPTHS, 25, 15)
    ci = np.searchsorted(FINE, cs)
    cs = FINE[ci]
    speeds, depths, stable = [], [], []
    errors, acc = [], []
    target = parse_next_cut_target("map")

    def log_post(z):
        lp = -0.5 * np.sum(((z - ANCHOR_MEAN) / ANCHOR_SD) ** 2, axis=1)
        lp = np.where((z[:, 2] >= lo) & (z[:, 2] <= hi), lp, -np.inf)
        lim = table(z, np.array(speeds))
        return lp + log_lik(np.array(depths), np.array(stable), lim)

    for n in range(max_cuts):
        if strategy == "next":
            r = rank_next_cuts(target, cs, ca, table(x, cs), t.map_speed, t.map_depth, table(x, t.map_speed), None,
                               BOUNDARY_WIDTH, label_error=LABEL_ERROR)
            best = r.best or r.candidates[0]
            k, a = int(np.searchsorted(FINE, best.speed_rpm)), best.depth_m
        else:
            k, a = int(rng.integers(FINE.size)), float(rng.uniform(*DEPTHS))
        ok, _ = label_cuts(np.array([a]), t.fine_truth[k:k + 1], 0.0, rng)
        speeds.append(FINE[k])
        depths.append(a)
        stable.append(bool(ok[0]))
        sampler = emcee.EnsembleSampler(walkers, 4, log_post, vectorize=True)
        start = x[rng.choice(x.shape[0], walkers, replace=False)]
        sampler.run_mcmc(start, steps, progress=False)
        x = sampler.get_chain(discard=steps // 2, thin=3, flat=True)
        acc.append(float(np.mean(sampler.acceptance_fraction)))
        w = np.full(x.shape[0], 1.0 / x.shape[0])
        errors.append(t.map_error(p_map(table(x, t.map_speed), w, t.map_depth)))
        if errors[-1] <= target_err:
            return {"count": n + 1, "errors": errors, "acceptance": acc}
    return {"count": None, "errors": errors, "acceptance": acc}


# ------------------------------------------------------------------------- cost --
def cost(c: Campaign, runs: int) -> dict:
    """``bayes-rcsa update`` with 20 cuts on 1000 draws, ZOA: in-process (median of ``runs``) and one subprocess."""
    import subprocess

    from bayes_rcsa.cli.main import main as cli
    from bayes_rcsa.synthetic.cuts import generate_cuts, write_cuts

    plan = CutPlan(**{**c.plan.__dict__, "n_cuts": 20})
    cuts = generate_cuts(c.cfg, plan, np.random.default_rng([c.seed, 5]), **c.cut_truth())
    out = {"n_cuts": 20, "n_stable": int(cuts.stable.sum())}
    with tempfile.TemporaryDirectory() as d:
        write_cuts(cuts, d)
        argv = ["update", str(c.setup), "--posterior", str(c.posterior), "--cuts", str(Path(d) / "cuts.csv"),
                "--clamping-length", str(c.length), "--flutes", "4", "--kt", f"{KT:g}±30%", "--kr", f"{KR:g}",
                "--immersion", "0.95", "--milling", "down", "--feed", "y", "--draws", "1000"]
        times, cpu = [], []
        for k in range(runs):
            t0, c0 = time.perf_counter(), time.process_time()
            status = cli(argv + ["--out", str(Path(d) / f"u{k}")])
            times.append(time.perf_counter() - t0 if status == 0 else float("nan"))
            cpu.append(time.process_time() - c0)
        out["in_process_median_s"] = statistics.median(times)
        out["in_process_cpu_median_s"] = statistics.median(cpu)
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "bayes_rcsa", *argv, "--out", str(Path(d) / "sub")],
                           capture_output=True, text=True)
        out["subprocess_s"] = time.perf_counter() - t0 if r.returncode == 0 else float("nan")
        doc = json.loads((Path(d) / "u0" / "update.json").read_text())
        out["ess_draws"] = doc["ess"]["draws"]
        out["kt_after"] = doc["kt_pa"]["after"]
    return out


def combine(full_json, anchor_json) -> None:
    """Cuts to the design target (half the hammer-only error): hammer next-cut vs the MCMC anchor."""
    races = {r["campaign"]: r for r in json.loads(Path(full_json).read_text())["design"]}
    anchor = json.loads(Path(anchor_json).read_text())

    def first(errors, target):
        return next((n + 1 for n, e in enumerate(errors) if e <= target), None)

    def val(x):
        return 21 if x is None else x

    rows = []
    for a in anchor:
        r = races.get(a["campaign"])
        if r is None:
            continue
        rows.append((a["campaign"], r["target"], r["next"], first(a["next"]["errors"], r["target"]),
                     first(a["random"]["errors"], r["target"]), a))
        print(f"campaign {a['campaign']}: target {r['target']:.4f}; hammer next-cut {r['next']}; anchor (MCMC) "
              f"next-cut {rows[-1][3]}, random {rows[-1][4]}; anchor error after 20 cuts next "
              f"{a['next']['errors'][-1]:.4f}, random {a['random']['errors'][-1]:.4f}; acceptance "
              f"{np.median(a['next']['acceptance']):.2f}")
    print(f"hammer fewer cuts than the anchor (next-cut both): {sum(val(x[2]) < val(x[3]) for x in rows)}/{len(rows)}; "
          f"median hammer {statistics.median(val(x[2]) for x in rows)}, anchor next {statistics.median(val(x[3]) for x in rows)}, "
          f"anchor random {statistics.median(val(x[4]) for x in rows)} (21 = not within 20)")
    for key in ("next", "random"):
        print(f"anchor {key} map error after 1, 3, 5, 10, 20 cuts (median): " + " ".join(
            f"{statistics.median(x[5][key]['errors'][n - 1] for x in rows):.4f}" for n in (1, 3, 5, 10, 20)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--campaigns", type=int, default=20)
    ap.add_argument("--design-campaigns", type=int, default=5)
    ap.add_argument("--draws", type=int, default=1000)
    ap.add_argument("--pairs", type=int, default=2, help="coefficient-scale draws per theta draw")
    ap.add_argument("--anchor-draws", type=int, default=0,
                    help="draws of the generic modal prior for the importance-sampled anchor (0: skipped; it collapses, "
                         "see --anchor-mcmc)")
    ap.add_argument("--runs", type=int, default=5, help="timing runs of the cost row")
    ap.add_argument("--json", default=None, help="write all rows to this JSON file")
    ap.add_argument("--cost-only", action="store_true", help="only the cost row (campaign 0)")
    ap.add_argument("--truth", choices=("sdm", "zoa"), default="sdm",
                    help="stability method of the true limit (default sdm: not the ZOA the update uses)")
    ap.add_argument("--anchor-mcmc", default=None, metavar="JSON",
                    help="only the MCMC anchor races (20 cuts each) of the --design-campaigns, written to JSON")
    ap.add_argument("--combine", nargs=2, default=None, metavar=("FULL_JSON", "ANCHOR_JSON"),
                    help="the anchor table from a full run's --json and an --anchor-mcmc file")
    args = ap.parse_args()
    TRUTH["method"] = args.truth
    if args.anchor_mcmc:  # 20 cuts per race, no early stop: counts for any target follow from the errors
        table = OneModeLimits()
        out = []
        for i in range(args.design_campaigns):
            t = Truth(i)
            row = {"campaign": i}
            for strategy in ("next", "random"):
                t0 = time.perf_counter()
                row[strategy] = anchor_mcmc_race(t, table, strategy, -1.0)
                print(f"anchor MCMC campaign {i} {strategy}: errors " + " ".join(
                    f"{e:.3f}" for e in row[strategy]["errors"]) + f"; acceptance "
                    f"{np.median(row[strategy]['acceptance']):.2f} ({time.perf_counter() - t0:.0f} s)", flush=True)
            out.append(row)
            Path(args.anchor_mcmc).write_text(json.dumps(out, indent=1))
        return
    if args.combine:
        combine(*args.combine)
        return
    if args.cost_only:
        with tempfile.TemporaryDirectory() as tmpdir:
            print(cost(Campaign(0, Path(tmpdir), args.draws, args.pairs), args.runs))
        return
    rows, races, timing = [], [], {}
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = Path(tmpdir)
        for i in range(args.campaigns):
            c = Campaign(i, tmp, args.draws, args.pairs)
            r = recovery(c)
            rows.append(r)
            print(f"campaign {i} ({r['length_mm']:.0f} mm, K_t x{r['factor']}, identify {r['t_identify']:.0f} s, "
                  f"elapsed {time.perf_counter() - t_start:.0f} s): map error hammer {r['err_hammer']:.3f}, "
                  f"prior {r['err_prior']:.3f}; hammer-only point stable {r['rec_hammer_stable']}", flush=True)
            for p in ("random_", "next_"):
                if r[p + "refused"]:
                    print(f"    {p[:-1]:6s} 10 cuts: update refused: {r[p + 'refused']}", flush=True)
                    continue
                print(f"    {p[:-1]:6s} 10 cuts ({r[p + 'n_stable']} stable): K_t 90 % [{r[p + 'kt_lo'] / 1e6:.0f}, "
                      f"{r[p + 'kt_hi'] / 1e6:.0f}] MPa (true {r['kt_true'] / 1e6:.0f}) covered {r[p + 'covered']}, "
                      f"ESS {r[p + 'ess']:.0f}, map error {r[p + 'err']:.3f}, point {r[p + 'rec']} stable "
                      f"{r[p + 'rec_stable']}", flush=True)
            if i < args.design_campaigns:
                races.append(design(c, args.pairs, args.anchor_draws))
            if i == 0:
                timing = cost(c, args.runs)
                print(f"cost: {timing}", flush=True)
    report(rows, races, timing)
    if args.json:
        Path(args.json).write_text(json.dumps({"recovery": rows, "design": races, "cost": timing}, indent=1,
                                              default=float))


def report(rows, races, timing) -> None:
    n = len(rows)
    print("\n## Recovery")
    for key, label in (("err_hammer", "hammer only (assumed K_t)"), ("err_prior", "hammer + K_t prior +-30 %")):
        v = [r[key] for r in rows]
        print(f"mean |P(stable) - truth| {label}: mean {np.mean(v):.4f}, median {np.median(v):.4f}")
    okh = [r["rec_hammer_stable"] for r in rows]
    print(f"hammer-only recommended point stable in the truth: {sum(bool(x) for x in okh)}/{n}")
    for p in ("random_", "next_"):
        done = [r for r in rows if not r[p + "refused"]]
        k = sum(r[p + "covered"] for r in done)  # a refused update counts as not covering
        lo, hi = clopper_pearson(k, n)
        v = [r[p + "err"] for r in done]
        ratio = [r[p + "err"] / r["err_hammer"] for r in done]
        ok = [r[p + "rec_stable"] for r in done]
        print(f"[{p[:-1]} 10 cuts] refused {n - len(done)}/{n}; K_t 90 % interval covers the truth: {k}/{n} = "
              f"{k / n:.2f} (95 % Clopper-Pearson [{lo:.2f}, {hi:.2f}]); map error mean {np.mean(v):.4f}, median "
              f"{np.median(v):.4f}; ratio of mean errors to hammer only "
              f"{np.mean(v) / np.mean([r['err_hammer'] for r in done]):.2f}, per campaign median {np.median(ratio):.2f}, "
              f"halved in {sum(x <= 0.5 for x in ratio)}/{n}; recommended point stable in the truth "
              f"{sum(bool(x) for x in ok)}/{n} (none recommended {sum(x is None for x in ok)}); ESS of the draws median "
              f"{np.median([r[p + 'ess'] for r in done]):.0f}, min {np.min([r[p + 'ess'] for r in done]):.0f}")
    if races:
        print("\n## Design (cuts to reach half the hammer-only map error; None = not within 20)")
        for r in races:
            print(f"campaign {r['campaign']}: target {r['target']:.4f}; next {r['next']}, next (budget 0.3) "
                  f"{r['next_budget']}, random {r['random']}, grid {r['grid']}" + (
                      f"; importance anchor next {r['anchor_next']}, random {r['anchor_random']} (prior error "
                      f"{r['anchor_prior_err']:.3f})" if "anchor_next" in r else ""))

        def val(x):
            return 21 if x is None else x

        wins = sum(val(r["next"]) < min(val(r["random"]), val(r["grid"])) for r in races)
        print(f"next-cut fewer than both random and grid: {wins}/{len(races)}")
        keys = ("next", "next_budget", "random", "grid") + (("anchor_next", "anchor_random") if "anchor_next" in races[0]
                                                             else ())
        for key in keys:
            print(f"median {key}: {statistics.median(val(r[key]) for r in races)}")
        print("map error after 1, 3, 5, 10, 20 cuts (median over campaigns; a race stops at the target):")
        for key in [k for k in keys if k != "next_budget"]:
            e = [r[key + "_errors"] for r in races]
            at = [statistics.median(x[min(n, len(x)) - 1] for x in e) for n in (1, 3, 5, 10, 20)]
            print(f"  {key:14s} " + " ".join(f"{v:.4f}" for v in at))
        if "anchor_next" in races[0]:
            print(f"importance anchor ESS after the race: next median "
                  f"{statistics.median(r['anchor_next_ess'] for r in races):.0f}, random median "
                  f"{statistics.median(r['anchor_random_ess'] for r in races):.0f}")
    print(f"\n## Cost\n{timing}")


if __name__ == "__main__":
    main()
