"""Start-search benchmark: the likelihood grid with and without forming the FRFs, and the whole optimum search.

The optimum search (``inference.sampler.find_optimum``) first evaluates the profile likelihood on a grid of
``(k_xf, k_thetaM)`` per clamping length (``inference.search``).  Printed, measured in the same run on the
bundled example's setup (all its measurements, at most 64 lines each):

* the grid maps through ``ForwardModel.grid_sums`` (the FRF of one translational joint is a Moebius map of the
  rotational one: no FRF is formed) against the chunked forward model followed by the residual sums (the path
  models with spindle, substructure or FRF terms still take), with the largest relative difference of the maps;
* the same for the exact grid (``ForwardModel.grid_profile_sums``: the likelihood's own variance of the model FRF,
  noise scales profiled), which ``find_optimum`` searches as well when a noise scale at its optimum exceeds 0.1;
* ``find_optimum`` (grid, candidates, L-BFGS-B polish) with each grid path.

Run:  python benchmarks/grid_search.py [--repeats 5]
"""

from __future__ import annotations

import argparse

import numpy as np

from _bench_setup import median_time
from bayes_rcsa.data import example_dir
from bayes_rcsa.inference import search
from bayes_rcsa.inference.problem import IdentificationOptions, build_problem_from_setup
from bayes_rcsa.inference.sampler import find_optimum
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.params import ForwardModel


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    problem = build_problem_from_setup(load_setup(example_dir() / "setup.toml"), IdentificationOptions())
    log_post = problem.log_posterior()
    captured = []
    original = search._length_maps

    def capture(*a, **k):
        captured.append((a, k))
        return original(*a, **k)

    search._length_maps = capture
    find_optimum(log_post)  # compiles the kernels and records the grid the search really uses
    search._length_maps = original
    a, k = captured[0]
    n_points, n_lines = a[1].size * a[2].size, sum(min(o.n_lines, a[4]) for o in a[0].observations)
    fused_maps = original(*a, **k)
    t_fused = median_time(lambda: original(*a, **k), args.repeats)
    t_fused_opt = median_time(lambda: find_optimum(log_post), args.repeats)
    bounds = [tuple(float(problem.priors[n].to_physical(u)) for u in problem.priors[n].optimisation_bounds())
              for n in a[0].parameters.noise_names]
    k_exact = {**k, "noise_bounds": bounds}
    exact_maps = original(*a, **k_exact)
    t_exact = median_time(lambda: original(*a, **k_exact), args.repeats)
    fused_path, profile_path = ForwardModel.grid_sums, ForwardModel.grid_profile_sums
    ForwardModel.grid_sums = lambda *_, **__: None  # every model then takes the chunked path
    ForwardModel.grid_profile_sums = lambda *_, **__: None
    try:
        chunked_maps = original(*a, **k)
        t_chunked = median_time(lambda: original(*a, **k), args.repeats)
        exact_chunked_maps = original(*a, **k_exact)
        t_exact_chunked = median_time(lambda: original(*a, **k_exact), args.repeats)
        t_chunked_opt = median_time(lambda: find_optimum(log_post), args.repeats)
    finally:
        ForwardModel.grid_sums, ForwardModel.grid_profile_sums = fused_path, profile_path
    diff = max(float(np.max(np.abs(fused_maps[L] - chunked_maps[L]) / np.abs(chunked_maps[L]))) for L in fused_maps)
    diff_exact = max(float(np.max(np.abs(exact_maps[L] - exact_chunked_maps[L]) / np.abs(exact_chunked_maps[L])))
                     for L in exact_maps)
    print(f"bundled example: {len(a[0].observations)} measurements, grid {a[1].size} x {a[2].size} = {n_points} "
          f"points, {n_lines} lines")
    print(f"{'quantity (median of ' + str(args.repeats) + ')':<50}{'value':>12}{'ratio':>8}")
    print(f"{'grid maps, fused (grid_sums), s':<50}{t_fused:>12.3f}{1.0:>8.1f}")
    print(f"{'grid maps, chunked forward + sums, s':<50}{t_chunked:>12.3f}{t_chunked / t_fused:>8.1f}")
    print(f"{'  per point-line: fused / chunked, ns':<50}{1e9 * t_fused / (n_points * n_lines):>12.1f}"
          f"{1e9 * t_chunked / (n_points * n_lines):>8.1f}")
    print(f"{'exact grid maps, fused (grid_profile_sums), s':<50}{t_exact:>12.3f}{1.0:>8.1f}")
    print(f"{'exact grid maps, chunked forward + sums, s':<50}{t_exact_chunked:>12.3f}{t_exact_chunked / t_exact:>8.1f}")
    print(f"{'find_optimum, fused grid, s':<50}{t_fused_opt:>12.3f}{1.0:>8.1f}")
    print(f"{'find_optimum, chunked grid, s':<50}{t_chunked_opt:>12.3f}{t_chunked_opt / t_fused_opt:>8.1f}")
    print(f"largest relative difference of the maps: {diff:.1e} (data-weighted), {diff_exact:.1e} (exact)")


if __name__ == "__main__":
    main()
