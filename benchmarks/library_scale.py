"""Stage 2 of a tool library at scale: 1,000 combinations in three holder types (issue #20, acceptance "Scale").

Stage-1 posteriors are synthetic (Gaussian draws around each combination's law, 1,000 draws of the six pooled
coordinates, as narrow as the bench's identify posteriors): the point is the time of stage 2 (surrogates, one
coupled emcee fit of all holder types, per-setup importance ESS and pooled estimates) and of the leave-one-out outlier check,
not the physics.  Seeds 5000+ (the development seeds were 0-99).

    python3 benchmarks/library_scale.py [N_COMBINATIONS] [REPEATS]
    python3 benchmarks/library_scale.py joint [REPLICATES] [RUNS] [STEPS] [SEED] [emcee|gibbs]
    python3 benchmarks/library_scale.py joint-real LIBRARY STAGE1 NAME,NAME,NAME,NAME [RUNS] [STEPS] [THIN] [SEED] [real|surrogate]
        [emcee|gibbs] [CACHE.json]
    python3 benchmarks/library_scale.py two-stage LIBRARY STAGE1 NAME,NAME,NAME,NAME [SEED]

Prints one line per repeat and the median; the table goes to docs/library.md ("Scale").  ``joint`` checks
stage 2 against joint emcee on 4-combination stand-ins (two holder types of two, two pooled coordinates,
exactly Gaussian stage-1 likelihoods): per replicate the largest |median difference| / posterior sd and the
largest difference of a 90 % interval end / the joint interval's width over the 14 hyperparameters (a, b, sigma
per type and coordinate, tau_b per coordinate; docs/library.md, "Stage 2").  ``joint-real`` does the same
with four real identify posteriors of a ``benchmarks/library.py`` library and their tempered FRF likelihoods.
``two-stage`` is a cheap check of the Gaussian surrogates alone (seconds, no joint sampler): stage 2's draws
re-weighted to the exact two-stage target in which each setup's stage-1 draws are its likelihood
(:func:`bayes_rcsa.library.exact.two_stage_log_weights`).
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from bayes_rcsa.inference.diagnostics import chain_diagnostics
from bayes_rcsa.library.hierarchy import Group, fit_hyper
from bayes_rcsa.library.joint import gaussian_log_likelihood, pool_runs, run_spread, sample_gibbs, sample_joint
from bayes_rcsa.library.outliers import flag_outliers, loo_p_values
from bayes_rcsa.library.population import COORDINATES, Hyperprior, covariate
from bayes_rcsa.library.exact import reweight_exact, two_stage_log_weights
from bayes_rcsa.library.stage2 import SetupDraws, Stage2Settings, fit_population, surrogate

BOX = np.array([[5.0, 9.0], [3.0, 8.0], [0.0, 1.5], [0.0, 1.5], [0.0, 4.0], [-6.0, 0.0]])
MEAN = np.array([6.6, 5.8, 0.45, 0.35, 1.1, -3.2])  # at 10 mm, per type offset below
SLOPE = np.array([0.9, 1.3, 0.0, 0.0, 0.4, 1.3])
SPREAD = np.array([0.05, 0.05, 0.08, 0.08, 0.09, 0.09])


def synthetic_library(n: int, rng: np.random.Generator, n_types: int = 3, n_draws: int = 1000) -> list[SetupDraws]:
    """``n`` combinations cycling through ``n_types`` holder types, diameters 6-20 mm."""
    out = []
    for i in range(n):
        t = i % n_types
        dia = rng.uniform(0.006, 0.020)
        x = np.log(dia / 0.010)
        z = MEAN + 0.15 * t + SLOPE * x + SPREAD * rng.standard_normal(6)
        A = 0.004 * rng.standard_normal((6, 6))
        C = A @ A.T + np.diag(rng.uniform(0.002, 0.01, 6) ** 2)
        L = np.linalg.cholesky(C)
        m = z + L @ rng.standard_normal(6)
        draws = m + rng.standard_normal((n_draws, 6)) @ L.T
        out.append(SetupDraws(f"c{i}", f"type{t}", dia, np.clip(draws, BOX[:, 0], BOX[:, 1]), np.zeros(6),
                              np.zeros((6, 6)), BOX))
    return out


def main(n: int = 1000, repeats: int = 3) -> None:
    hyper = Hyperprior.from_box(COORDINATES, BOX, 1.5)
    times, loo_times = [], []
    print(f"stage 2 for {n} combinations, 3 holder types, 6 coordinates, 1000 stage-1 draws each; "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at start")
    for r in range(repeats):
        rng = np.random.default_rng(5000 + r)
        setups = synthetic_library(n, rng)
        t0 = time.perf_counter()
        res = fit_population(setups, hyper, rng)
        t1 = time.perf_counter()
        rows = loo_p_values(res.fit, hyper, rng)
        flagged, _ = flag_outliers(rows, n)
        t2 = time.perf_counter()
        times.append(t1 - t0)
        loo_times.append(t2 - t1)
        refused = sum(1 for s in res.setups if s["refused"])
        n_flag = sum(1 for f in flagged if f["outlier"])
        print(f"repeat {r}: stage 2 {t1 - t0:.1f} s (ESS {res.fit.ess:.0f}, {res.fit.n_steps} steps, {refused} setups "
              f"refused), outlier check {t2 - t1:.1f} s ({n_flag} flagged), load {os.getloadavg()[0]:.1f}")
    print(f"median: stage 2 {statistics.median(times):.1f} s, outlier check {statistics.median(loo_times):.1f} s")


def _target_quantiles(groups, hyper: Hyperprior, theta: np.ndarray, rng: np.random.Generator, n: int = 400_000):
    """Quantiles (0.05, 0.5, 0.95) of every sigma_tj and tau_b,j under stage 2's own target, by importance sampling.

    Proposal: a Student-t (5 degrees of freedom, covariance 1.5^2 x the chain's) on (ln sigma, ln tau_b) fitted to
    stage 2's draws ``theta``; the weights are ``log_posterior`` (with the Jacobian of ln tau_b) over the proposal
    density.  Independent of the chain's Monte Carlo error in the tails.  Returns (3, T d + d) in the sampler's
    order (ln sigma per type and coordinate, then tau_b) and the weights' effective sample size."""
    from scipy.stats import multivariate_t

    from bayes_rcsa.library.hierarchy import log_posterior

    k = theta.shape[1] - hyper.ndim  # number of ln sigma columns
    y0 = np.concatenate([theta[:, :k], np.log(theta[:, k:])], axis=1)
    prop = multivariate_t(y0.mean(axis=0), 2.25 * np.cov(y0, rowvar=False), df=5)
    ys, lws = [], []
    for _ in range(n // 50_000):
        y = prop.rvs(50_000, random_state=rng)
        th = np.concatenate([y[:, :k], np.exp(y[:, k:])], axis=1)
        lws.append(log_posterior(th, groups, hyper) + np.sum(y[:, k:], axis=1) - prop.logpdf(y))
        ys.append(np.concatenate([np.exp(y[:, :k]), np.exp(y[:, k:])], axis=1))
    v, lw = np.concatenate(ys), np.concatenate(lws)
    w = np.exp(lw - lw.max())
    w /= w.sum()
    q = np.empty((3, v.shape[1]))
    for j in range(v.shape[1]):
        o = np.argsort(v[:, j])
        q[:, j] = np.interp([0.05, 0.5, 0.95], np.cumsum(w[o]) - 0.5 * w[o], v[o, j])
    return q, float(1.0 / np.sum(w * w))


def joint_check(replicates: int = 5, runs: int = 4, steps: int = 48000, seed: int = 5200, sampler: str = "emcee") -> None:
    """Two holder types of two combinations each (4 in all), two pooled coordinates: per type (a, b, sigma) of
    both coordinates and the slopes' spread tau_b, 14 hyperparameters.  Stage 2 runs to an ESS of 12,000; the
    joint reference is ``runs`` independent emcee ensembles (64 walkers x ``steps`` after 8,000 of burn-in
    from over-dispersed prior starts; half with the setups' laws non-centred, half centred), pooled, and the
    between-run spread of each interval end is its Monte Carlo standard error.  Stage 2's own target is also
    computed by importance sampling (:func:`_target_quantiles`, for the spreads and tau_b, whose upper ends are the
    hard ones): "target vs joint" is the comparison without stage 2's chain noise, "chain vs target" that noise.
    ``runs = 0`` skips the joint reference (stage 2 and its target only).  ``sampler = "gibbs"``: the joint
    reference is Metropolis-within-Gibbs instead, ``runs`` chains of ``steps`` iterations after ``steps / 4``
    (the laws starting at the stage-1 draws); its R-hat and ESS (over the chains) are printed too."""
    names = ("k_xf", "g_xf")
    box = np.array([[4.0, 10.0], [0.0, 1.5]])
    hyper = Hyperprior.from_box(names, box, 1.5)
    dia = np.array([0.006, 0.013, 0.009, 0.018])
    types = np.array([0, 0, 1, 1])
    x = covariate(dia)
    labels = [f"{p}_{n}[T{t}]" for t in (0, 1) for p in ("a", "b", "sigma") for n in names] + \
        [f"tau_b_{n}" for n in names]
    worst = []
    ref = (f"Gibbs, {runs} chains x {steps} iterations" if sampler == "gibbs" else
           f"{runs} emcee runs of 64 walkers x {steps} steps")
    print(f"seeds {seed}-{seed + replicates - 1}; joint reference: {ref} per replicate")
    print("replicate  max |d median| / sd  max |d end| / width  worst end (stage 2, joint +- MC se)  "
          "ends > 10 %: of them beyond 2 se  | spreads and tau_b, max |d end| / width: target vs joint, chain vs "
          "target [IS ESS]")
    for r in range(replicates):
        t0 = time.perf_counter()
        rng = np.random.default_rng(seed + r)
        exact = []
        for i in range(4):
            z = np.array([7.0 + 0.2 * types[i] + 1.5 * x[i], 0.6]) + np.array([0.15, 0.1]) * rng.standard_normal(2)
            C = np.array([[0.04, 0.015], [0.015, 0.02]]) * rng.uniform(0.5, 2.0)
            exact.append((z + np.linalg.cholesky(C) @ rng.standard_normal(2), C))
        groups, stage1 = [], {}
        for t in (0, 1):
            idx = np.flatnonzero(types == t)
            sur = []
            for i in idx:  # stage-1 draws of the exact likelihood under a flat prior, and their surrogate
                m, C = exact[i]
                draws = stage1[i] = m + rng.standard_normal((4000, 2)) @ np.linalg.cholesky(C).T
                sur.append(surrogate(SetupDraws(f"s{i}", f"T{t}", dia[i], draws, np.zeros(2), np.zeros((2, 2)),
                                                np.array([[-50.0, 50.0], [-50.0, 50.0]])))[:2])
            groups.append(Group(f"T{t}", tuple(f"s{i}" for i in idx), x[idx], np.array([v[0] for v in sur]),
                                np.array([v[1] for v in sur])))
        fit = fit_hyper(groups, hyper, rng, Stage2Settings(ess_target=12000))
        sel = [4, 5, 10, 11, 12, 13]  # sigma of both coordinates per type, tau_b: the sampler's order
        q2 = np.quantile(np.concatenate([fit.types["T0"].flat, fit.types["T1"].flat, fit.tau_b], axis=1),
                         [0.05, 0.5, 0.95], axis=0)
        qt, is_ess = _target_quantiles(groups, hyper, fit.theta, np.random.default_rng([seed + r, 1]))
        chain_vs_target = float(np.max(np.abs(q2[[0, 2]][:, sel] - qt[[0, 2]]) / (qt[2] - qt[0])))
        if runs == 0:
            ends = ", ".join(f"{labels[c]} {q2[2, c]:.3f} / {qt[2, i]:.3f}" for i, c in enumerate(sel))
            print(f"{r:9d}  chain vs target {chain_vs_target:.3f} [IS ESS {is_ess:.0f}]; upper ends, chain / "
                  f"target: {ends}", flush=True)
            continue
        lls = [gaussian_log_likelihood(m, C) for m, C in exact]
        mixing = ""
        if sampler == "gibbs":
            joint = sample_gibbs(lls, types, x, hyper, rng, [stage1[i] for i in range(4)], n_iter=steps,
                                 n_burn=steps // 4, n_chains=runs)
            dg = chain_diagnostics(np.swapaxes(joint["chains"], 0, 1))
            mixing = (f"  R-hat <= {dg['rhat'].max():.3f}, ESS bulk >= {dg['ess_bulk'].min():.0f}, tail >= "
                      f"{dg['ess_tail'].min():.0f}")
        else:
            half = [sample_joint(lls, types, x, hyper, rng, n_steps=steps, n_burn=8000, n_runs=k, centred=c)["runs"]
                    for k, c in ((runs - runs // 2, False), (runs // 2, True)) if k]
            joint = pool_runs(half[0] + (half[1] if len(half) > 1 else []))

        def columns(d):  # (N, 14) hyperparameter draws in the order of ``labels``
            return np.concatenate([d["types"][0], d["types"][1], d["tau_b"]], axis=1)

        two = columns({"types": [fit.types["T0"].flat, fit.types["T1"].flat], "tau_b": fit.tau_b})
        qj, se = run_spread(joint, lambda d: np.quantile(columns(d), [0.05, 0.5, 0.95], axis=0))
        q2 = np.quantile(two, [0.05, 0.5, 0.95], axis=0)
        sd = np.std(columns(joint), axis=0)
        width = qj[2] - qj[0]
        dm = np.abs(q2[1] - qj[1]) / sd
        de = np.abs(q2[[0, 2]] - qj[[0, 2]]) / width  # (2, 14)
        se_e = se[[0, 2]] / width
        k = np.unravel_index(np.argmax(de), de.shape)
        over = de > 0.10
        n_beyond = int(np.sum(over & (de > 2 * se_e)))  # joint Monte Carlo error only
        target_vs_joint = float(np.max(np.abs(qt[[0, 2]] - qj[[0, 2]][:, sel]) / width[sel]))
        worst.append((float(dm.max()), float(de.max())))
        end = ("q05", "q95")[k[0]]
        print(f"{r:9d}  {dm.max():20.3f}  {de.max():19.3f}  {labels[k[1]]} {end}: {q2[2 * k[0], k[1]]:.3f}, "
              f"{qj[2 * k[0], k[1]]:.3f} +- {se[2 * k[0], k[1]]:.3f} ({se_e[k]:.3f} of the width)  "
              f"{int(over.sum())}: {n_beyond}  | {target_vs_joint:.3f}, {chain_vs_target:.3f} [{is_ess:.0f}]   "
              f"[{time.perf_counter() - t0:.0f} s]{mixing}", flush=True)
    if worst:
        print(f"largest: {max(w[0] for w in worst):.3f} sd, {max(w[1] for w in worst):.3f} of the width "
              "(acceptance: 0.2 sd, 0.10)")


def joint_real(library: str, stage1: str, picks: str, runs: int = 4, steps: int = 6000, thin: int = 4,
               seed: int = 5300, likelihood: str = "real", sampler: str = "emcee", cache: str = "", tail: str = "") -> None:
    """Stage 2 against the joint model with REAL identify posteriors: four combinations (``picks``, comma-separated
    names of two holder types) of a ``benchmarks/library.py`` library (``library``: its folder with
    ``manifest.toml``; ``stage1``: its finished ``bayes-rcsa batch`` folder).

    Stage 2 as ``bayes-rcsa library`` runs it (surrogates of the stored draws, ESS target 12,000).  The joint
    model samples every hyperparameter, every setup's contact law (centred, in population coordinates) and its
    noise scales, with each setup's own tempered FRF likelihood and stage-1 prior box (the stage-1 log posterior
    that identify sampled, rebuilt from the setup file and checked against the stored ``lp`` of its draws), in
    ``runs`` independent ensembles of ``2 ndim + 8`` walkers, ``steps x thin`` steps after ``steps`` of burn-in,
    the laws and noise scales starting at random stage-1 draws.

    ``likelihood = "surrogate"`` is the control: the same library, each setup's Gaussian surrogate as its exact
    likelihood (no noise scales), where stage 2's target is exact; a gap there is the joint sampler's.

    ``sampler = "gibbs"``: the joint model by Metropolis-within-Gibbs (:func:`~bayes_rcsa.library.joint.sample_gibbs`)
    instead of emcee, ``runs`` independent chains of ``steps`` kept iterations (every ``thin``-th) after
    ``max(500, steps / 4)`` of burn-in; R-hat and bulk/tail ESS per hyperparameter over the chains, and the
    Monte Carlo error of each end from the spread between four groups of chains.  Stage 2's own target is also
    importance-sampled for the spreads and tau_b (the "IS" columns; with ``surrogate`` the joint model's exact
    answer).

    Stage 2 is compared twice, with the same chain: as the Gaussian surrogates give it (``exact=False``) and
    re-weighted to the exact two-stage target (:func:`bayes_rcsa.library.exact.reweight_exact`, forced on; its
    weight ESS is printed).  The joint reference draws from its own stream (``[seed, 3]``); ``cache`` (a JSON
    path) keeps its quantiles, standard errors and diagnostics, and a later call with the same arguments reads
    them instead of sampling again."""
    import arviz as az

    from bayes_rcsa.batch.manifest import load_manifest
    from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
    from bayes_rcsa.io.setup import load_setup
    from bayes_rcsa.library.joint import JointModel
    from bayes_rcsa.library.stage1 import collect

    lib, s1 = Path(library), Path(stage1)
    pick = picks.split(",")
    jobs = [j for j in load_manifest(lib / "manifest.toml") if j.name in pick]
    # "tailfix": stage 1 as `bayes-rcsa library --tail-correct` pools it (a setup whose chain missed a tail of its
    # posterior contributes importance-sampling draws instead; docs/identification.md)
    st1 = collect(jobs, s1, tail_correct=tail == "tailfix", rng=np.random.default_rng([seed, 5]))
    for w in st1.warnings:
        print(w, flush=True)
    names, d = st1.names, len(st1.names)
    hyper = Hyperprior.from_box(names, st1.box, st1.growth[2])
    groups = sorted({s.holder_type for s in st1.setups})
    lls, laws, nuisance, types, x = [], [], [], [], []
    for s in st1.setups:
        if np.any(s.prior_precision):
            raise SystemExit(f"{s.name}: a Gaussian stage-1 prior; this check assumes the default flat ones")
        job = next(j for j in jobs if j.name == s.name)
        setup = load_setup(job.setup_file)
        folder = s1 / "setups" / s.name / "identify"
        summary = json.loads((folder / "summary.json").read_text())
        problem = build_problem_from_setup(setup, IdentificationOptions.from_setup(
            setup.extra, method=summary["method"], lengths=None, band=None))
        lp = problem.log_posterior(summary["likelihood"]["tempering"])
        pn = problem.priors.names
        iz = [pn.index(n) for n in names]
        iv = [i for i in range(len(pn)) if i not in iz]
        post = az.from_netcdf(folder / "posterior.nc")
        th = np.column_stack([np.asarray(problem.priors.priors[n].to_sampling(post.posterior[n].values.ravel()), float)
                              for n in pn])
        gap = float(np.max(np.abs(lp(th) - post.sample_stats["lp"].values.ravel())))
        if gap > 1e-6 or (tail != "tailfix" and np.max(np.abs(th[:, iz] - s.z)) > 1e-9):
            raise SystemExit(f"{s.name}: the rebuilt stage-1 log posterior differs from the stored one by {gap:g}")

        def f(z, v, lp=lp, iz=iz, iv=iv, k=len(pn)):
            theta = np.empty((z.shape[0], k))
            theta[:, iz], theta[:, iv] = z, v
            return lp(theta)

        lls.append(f)
        laws.append(np.column_stack([th[:, iz], th[:, iv]]))
        nuisance.append(len(iv))
        types.append(groups.index(s.holder_type))
        x.append(float(covariate(s.diameter)))
        print(f"{s.name}: {s.holder_type}, {s.diameter * 1e3:.0f} mm, tempering {summary['likelihood']['tempering']:.3f}, "
              f"{len(pn)} parameters, {th.shape[0]} stage-1 draws", flush=True)
    if likelihood == "surrogate":
        lls = [gaussian_log_likelihood(*surrogate(s)[:2]) for s in st1.setups]
        laws, nuisance = [s.z for s in st1.setups], None
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    res = fit_population(st1.setups, hyper, rng, Stage2Settings(ess_target=12000), exact=False)
    fit = res.fit
    print(f"stage 2: {time.perf_counter() - t0:.0f} s, ESS {fit.ess:.0f}, {fit.n_steps} steps; per-setup importance "
          f"ESS of the re-weighted stage-1 draws {[round(r['ess']) for r in res.setups]}", flush=True)
    t0 = time.perf_counter()
    fit_x, info = reweight_exact(fit, st1.setups, np.random.default_rng([seed, 2]), True)
    print(f"exact two-stage re-weighting of the same draws: {time.perf_counter() - t0:.1f} s, used {info['used']}, "
          f"weight ESS {info['weight_ess']:.0f} of {info['n_draws']} ({info['weight_ess_fraction']:.2f}), smallest "
          f"median site ESS {info['site_ess_median_min']:.0f} ({info['site_ess_setup']}), {info['pairs']:.2g} kernel "
          f"evaluations; {info['reason'] or ''}", flush=True)
    model = JointModel(lls, types, x, hyper, True, nuisance)
    T, dd = len(groups), len(names)
    labels = [f"{p}_{n}[{g}]" for g in groups for p in ("a", "b", "sigma") for n in names] + \
        [f"tau_b_{n}" for n in names]

    def columns(dd):
        return np.concatenate(list(dd["types"]) + [dd["tau_b"]], axis=1)

    meta = {"library": str(lib), "stage1": str(s1), "picks": pick, "runs": runs, "steps": steps, "thin": thin,
            "seed": seed, "likelihood": likelihood, "sampler": sampler}
    if cache and Path(cache).exists() and json.loads(Path(cache).read_text())["meta"] == meta:
        ref = json.loads(Path(cache).read_text())
        print(f"joint reference read from {cache}", flush=True)
    else:
        # the reference's own stream: independent of how many numbers stage 2 drew
        jrng = np.random.default_rng([seed, 3])
        t0 = time.perf_counter()
        if sampler == "gibbs":
            n_burn = max(500, steps // 4)
            joint = sample_gibbs(lls, types, x, hyper, jrng, laws, n_iter=steps, n_burn=n_burn, n_chains=runs,
                                 nuisance=nuisance, thin=thin)
            diag = {k: v.tolist() for k, v in chain_diagnostics(np.swapaxes(joint["chains"], 0, 1)).items()}
            print(f"joint (Gibbs): {model.ndim} dimensions, {runs} chains x {steps * thin} iterations after "
                  f"{n_burn}, {time.perf_counter() - t0:.0f} s, law acceptance "
                  f"{np.round(joint['law_acceptance'], 3).tolist()}, slice updates at the shrinkage limit "
                  f"{joint['stuck']}", flush=True)
        else:
            W = 2 * model.ndim + 8
            joint = sample_joint(lls, types, x, hyper, jrng, n_steps=steps, n_burn=steps, n_walkers=W, n_runs=runs,
                                 centred=True, nuisance=nuisance, start_laws=laws, thin=thin)
            diag = None
            print(f"joint: {model.ndim} dimensions, {runs} runs of {W} walkers x {steps * thin} steps, "
                  f"{time.perf_counter() - t0:.0f} s, acceptance {[round(r['acceptance'], 3) for r in joint['runs']]}",
                  flush=True)
        qj, se = run_spread(joint, lambda dd: np.quantile(columns(dd), [0.05, 0.5, 0.95], axis=0))
        ref = {"meta": meta, "q": qj.tolist(), "se": se.tolist(), "sd": np.std(columns(joint), axis=0).tolist(),
               "diag": diag}
        if cache:
            Path(cache).write_text(json.dumps(ref))
    qj, se, sd, diag = np.array(ref["q"]), np.array(ref["se"]), np.array(ref["sd"]), ref["diag"]
    sel = [t * 3 * dd + 2 * dd + j for t in range(T) for j in range(dd)] + [T * 3 * dd + j for j in range(dd)]
    qt, is_ess = _target_quantiles(fit.groups, hyper, fit.theta, np.random.default_rng([seed, 1]), n=1_000_000)
    print(f"stage 2's target by importance sampling: ESS {is_ess:.0f}", flush=True)
    width = qj[2] - qj[0]
    out = {}
    for tag, f in (("surrogate", fit), ("exact", fit_x)):
        two = columns({"types": [f.types[g].flat for g in groups], "tau_b": f.tau_b})
        q2 = np.quantile(two, [0.05, 0.5, 0.95], axis=0)
        out[tag] = (q2, np.abs(q2[1] - qj[1]) / sd, np.abs(q2[[0, 2]] - qj[[0, 2]]) / width)
    for i, label in enumerate(labels):
        extra = ""
        if i in sel:
            k = sel.index(i)
            extra += (f" | IS {qt[0, k]:.4f} {qt[1, k]:.4f} {qt[2, k]:.4f}: joint vs IS ends "
                      f"{np.max(np.abs(qt[[0, 2], k] - qj[[0, 2], i])) / width[i]:.3f}")
        if diag is not None:
            extra += (f" | R-hat {diag['rhat'][i]:.3f}, ESS bulk {diag['ess_bulk'][i]:.0f}, "
                      f"tail {diag['ess_tail'][i]:.0f}")
        cells = " | ".join(f"{tag} {q2[0, i]:9.4f} {q2[1, i]:9.4f} {q2[2, i]:9.4f}: median {dm[i]:.3f} sd, ends "
                           f"{de[:, i].max():.3f}" for tag, (q2, dm, de) in out.items())
        print(f"{label:24s} {cells} | joint {qj[0, i]:9.4f} {qj[1, i]:9.4f} {qj[2, i]:9.4f} "
              f"(MC se {np.max(se[[0, 2], i]) / width[i]:.3f} of the width){extra}")
    for tag, (q2, dm, de) in out.items():
        print(f"{tag}: largest {dm.max():.3f} sd ({labels[int(dm.argmax())]}), {de.max():.3f} of the width "
              f"({labels[int(de.max(axis=0).argmax())]}); ends > 0.10: {int(np.sum(de > 0.10))} of {de.size} "
              "(acceptance: 0.2 sd, 0.10)")
    if diag is not None:
        print(f"R-hat at most {max(diag['rhat']):.3f}, ESS bulk at least {min(diag['ess_bulk']):.0f}, "
              f"tail at least {min(diag['ess_tail']):.0f}")


def two_stage(library: str, stage1: str, picks: str, seed: int = 11) -> None:
    """Stage 2 of four real identify posteriors against its own draws re-weighted to the exact two-stage target
    (:func:`bayes_rcsa.library.exact.two_stage_log_weights`): per type and coordinate the 90 % ends of the means
    and slopes."""
    from bayes_rcsa.batch.manifest import load_manifest
    from bayes_rcsa.library.stage1 import collect

    lib = Path(library)
    st1 = collect([j for j in load_manifest(lib / "manifest.toml") if j.name in picks.split(",")], Path(stage1))
    hyper = Hyperprior.from_box(st1.names, st1.box, st1.growth[2])
    res = fit_population(st1.setups, hyper, np.random.default_rng(seed), Stage2Settings(ess_target=3000), exact=False)
    lw, _ = two_stage_log_weights(res.fit, st1.setups)
    w = np.exp(lw - lw.max())
    w /= w.sum()
    print(f"stage 2 ESS {res.fit.ess:.0f}; two-stage weights: ESS {1 / np.sum(w * w):.0f} of {w.size}")
    d = hyper.ndim
    for t, tf in sorted(res.fit.types.items()):
        for k, lab in enumerate([f"{p}_{n}" for p in "ab" for n in st1.names]):
            v = tf.flat[:, k]
            o = np.argsort(v)
            cw = np.cumsum(w[o])
            qt = np.interp([0.05, 0.5, 0.95], cw - 0.5 * w[o], v[o])
            q2 = np.quantile(v, [0.05, 0.5, 0.95])
            print(f"{t:12s} {lab:12s} stage 2 {q2[0]:8.3f} {q2[1]:8.3f} {q2[2]:8.3f} | two-stage {qt[0]:8.3f} "
                  f"{qt[1]:8.3f} {qt[2]:8.3f} | ends {np.max(np.abs(q2[[0, 2]] - qt[[0, 2]])) / (qt[2] - qt[0]):.3f}"
                  " of the width")


if __name__ == "__main__":
    if sys.argv[1:2] == ["joint"]:
        joint_check(*(int(v) for v in sys.argv[2:6]), *sys.argv[6:7])
    elif sys.argv[1:2] == ["joint-real"]:
        joint_real(*sys.argv[2:5], *(int(v) for v in sys.argv[5:9]), *sys.argv[9:13])
    elif sys.argv[1:2] == ["two-stage"]:
        two_stage(*sys.argv[2:5], *(int(v) for v in sys.argv[5:6]))
    else:
        main(*(int(v) for v in sys.argv[1:3]))
