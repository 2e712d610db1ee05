"""Stage 2 of a tool library at scale: 1,000 combinations in three holder types (issue #20, acceptance "Scale").

Stage-1 posteriors are synthetic (Gaussian draws around each combination's law, 1,000 draws of the six pooled
coordinates, as narrow as the bench's identify posteriors): the point is the time of stage 2 (surrogates, one
coupled emcee fit of all holder types, per-setup importance ESS and pooled estimates) and of the leave-one-out outlier check,
not the physics.  Seeds 5000+ (the development seeds were 0-99).

    python3 benchmarks/library_scale.py [N_COMBINATIONS] [REPEATS]
    python3 benchmarks/library_scale.py joint [REPLICATES] [RUNS] [STEPS] [SEED]

Prints one line per repeat and the median; the table goes to docs/library.md ("Scale").  ``joint`` checks
stage 2 against joint emcee on 4-combination stand-ins (two holder types of two, two pooled coordinates,
exactly Gaussian stage-1 likelihoods): per replicate the largest |median difference| / posterior sd and the
largest difference of a 90 % interval end / the joint interval's width over the 14 hyperparameters (a, b, sigma
per type and coordinate, tau_b per coordinate; docs/library.md, "Stage 2").
"""

from __future__ import annotations

import os
import statistics
import sys
import time

import numpy as np

from bayes_rcsa.library.hierarchy import Group, fit_hyper
from bayes_rcsa.library.joint import gaussian_log_likelihood, pool_runs, run_spread, sample_joint
from bayes_rcsa.library.outliers import flag_outliers, loo_p_values
from bayes_rcsa.library.population import COORDINATES, Hyperprior, covariate
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


def joint_check(replicates: int = 5, runs: int = 4, steps: int = 48000, seed: int = 5200) -> None:
    """Two holder types of two combinations each (4 in all), two pooled coordinates: per type (a, b, sigma) of
    both coordinates and the slopes' spread tau_b, 14 hyperparameters.  Stage 2 runs to an ESS of 12,000; the
    joint reference is ``runs`` independent emcee ensembles (64 walkers x ``steps`` after 8,000 of burn-in
    from over-dispersed prior starts; half with the setups' laws non-centred, half centred), pooled, and the
    between-run spread of each interval end is its Monte Carlo standard error."""
    names = ("k_xf", "g_xf")
    box = np.array([[4.0, 10.0], [0.0, 1.5]])
    hyper = Hyperprior.from_box(names, box, 1.5)
    dia = np.array([0.006, 0.013, 0.009, 0.018])
    types = np.array([0, 0, 1, 1])
    x = covariate(dia)
    labels = [f"{p}_{n}[T{t}]" for t in (0, 1) for p in ("a", "b", "sigma") for n in names] + \
        [f"tau_b_{n}" for n in names]
    worst = []
    print(f"seeds {seed}-{seed + replicates - 1}; {runs} joint runs of 64 walkers x {steps} steps per replicate")
    print("replicate  max |d median| / sd  max |d end| / width  worst end (stage 2, joint +- MC se)  "
          "ends > 10 %: of them beyond 2 se")
    for r in range(replicates):
        t0 = time.perf_counter()
        rng = np.random.default_rng(seed + r)
        exact = []
        for i in range(4):
            z = np.array([7.0 + 0.2 * types[i] + 1.5 * x[i], 0.6]) + np.array([0.15, 0.1]) * rng.standard_normal(2)
            C = np.array([[0.04, 0.015], [0.015, 0.02]]) * rng.uniform(0.5, 2.0)
            exact.append((z + np.linalg.cholesky(C) @ rng.standard_normal(2), C))
        groups = []
        for t in (0, 1):
            idx = np.flatnonzero(types == t)
            sur = []
            for i in idx:  # stage-1 draws of the exact likelihood under a flat prior, and their surrogate
                m, C = exact[i]
                draws = m + rng.standard_normal((4000, 2)) @ np.linalg.cholesky(C).T
                sur.append(surrogate(SetupDraws(f"s{i}", f"T{t}", dia[i], draws, np.zeros(2), np.zeros((2, 2)),
                                                np.array([[-50.0, 50.0], [-50.0, 50.0]])))[:2])
            groups.append(Group(f"T{t}", tuple(f"s{i}" for i in idx), x[idx], np.array([v[0] for v in sur]),
                                np.array([v[1] for v in sur])))
        fit = fit_hyper(groups, hyper, rng, Stage2Settings(ess_target=12000))
        lls = [gaussian_log_likelihood(m, C) for m, C in exact]
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
        worst.append((float(dm.max()), float(de.max())))
        end = ("q05", "q95")[k[0]]
        print(f"{r:9d}  {dm.max():20.3f}  {de.max():19.3f}  {labels[k[1]]} {end}: {q2[2 * k[0], k[1]]:.3f}, "
              f"{qj[2 * k[0], k[1]]:.3f} +- {se[2 * k[0], k[1]]:.3f} ({se_e[k]:.3f} of the width)  "
              f"{int(over.sum())}: {n_beyond}   [{time.perf_counter() - t0:.0f} s]", flush=True)
    print(f"largest: {max(w[0] for w in worst):.3f} sd, {max(w[1] for w in worst):.3f} of the width "
          "(acceptance: 0.2 sd, 0.10)")


if __name__ == "__main__":
    if sys.argv[1:2] == ["joint"]:
        joint_check(*(int(v) for v in sys.argv[2:6]))
    else:
        main(*(int(v) for v in sys.argv[1:3]))
