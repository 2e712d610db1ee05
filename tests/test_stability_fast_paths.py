"""The compiled/vectorised lobes paths (issue #44) against the implementations they replaced.

The ZOA lower envelope (compiled loop), the P(stable) map (histogram of searchsorted counts), the level limit
(partial sort), the window minimum of the recommendation (sparse table) and the order statistics shared by
the whole pipeline must give exactly what the earlier numpy code gave.  The earlier code is the slow reference:
here for the map, the level limit and the window minimum, and for the envelope ``zoa._envelope_numpy`` (the
7337b3c algorithm, materialising every (segment, grid speed) pair and sorting them; still used for jobs too
small to pay for loading numba); :func:`test_pipeline_equals_the_reference_pipeline` runs ``lobes_from_frf_draws`` once with the
reference functions patched in and once as shipped, on the bundled measured files with their random error.
"""

from __future__ import annotations

import importlib
import math
from pathlib import Path

import numpy as np
import pytest

from bayes_rcsa.stability import CuttingConditions, Tolerances, lobes_from_frf_draws
from bayes_rcsa.stability.cutting import mean_directional_matrix
from bayes_rcsa.stability.posterior_frf import measured_frf_draws

# the modules (the package exports functions named like some of them)
probabilistic = importlib.import_module("bayes_rcsa.stability.probabilistic")
recommend = importlib.import_module("bayes_rcsa.stability.recommend")
zoa = importlib.import_module("bayes_rcsa.stability.zoa")

EXAMPLE = Path(__file__).resolve().parent.parent / "bayes_rcsa" / "data" / "example"
CUT = CuttingConditions(kt=790e6, kr=230e6, flutes=4, milling="down", feed="y", radial_immersion=0.95)


# ------------------------------------------------------------------------------------------ slow references
def _reference_envelope_of_ends(depth_pts, eps, f, flutes, speeds, K, track=True):
    """The numpy envelope (materialise every (segment, grid speed) pair, sort, keep the lowest), as in 7337b3c."""
    depth, chat, lob = zoa._envelope_numpy(depth_pts, eps, np.asarray(f, dtype=float), flutes, speeds, K)
    return (depth, chat, lob) if track else (depth, None, None)


def _reference_probability_map(depth_limit_m, depth_m, chunk=64):
    lim = np.atleast_2d(np.asarray(depth_limit_m, dtype=float))
    a = np.asarray(depth_m, dtype=float)
    return np.mean(a[None, None, :] < lim[:, :, None], axis=0)


def _reference_level_limit(depth_limit_m, level, presorted=False):
    lim = np.atleast_2d(np.asarray(depth_limit_m, dtype=float))
    k = int(math.ceil(level * lim.shape[0] - 1e-9))
    return -np.sort(-lim, axis=0)[k - 1]


def _reference_window_min(n, a, tol):
    lo = np.searchsorted(n, n * (1 - tol) - 1e-9 * n, side="left")
    hi = np.searchsorted(n, n * (1 + tol) + 1e-9 * n, side="right")
    return np.array([a[lo[i]:hi[i]].min() for i in range(n.size)])


def _draws(n_draws, seed=3):
    return measured_frf_draws(str(EXAMPLE / "tip_x_30mm.csv"), str(EXAMPLE / "tip_y_30mm.csv"), None, n_draws,
                              np.random.default_rng(seed))


# ------------------------------------------------------------------------------------------ the pieces
@pytest.mark.parametrize("grid", ["uniform", "uneven"])
def test_compiled_envelope_is_the_numpy_envelope(grid, monkeypatch):
    pair = _draws(12)
    if grid == "uniform":
        speeds = np.linspace(6000.0, 24000.0, 1801)
    else:  # the binary-search branch of the kernel
        speeds = np.sort(np.random.default_rng(0).uniform(6000.0, 24000.0, 900))
    monkeypatch.setattr(zoa, "_COMPILED_ENVELOPE_CELLS", 1)  # the compiled loop even for this small job
    ends = zoa._segment_ends(mean_directional_matrix(CUT), pair.frf_x, pair.frf_y)
    K = zoa.lobe_count(pair.frequency_hz, CUT.flutes, speeds[0])
    new = zoa._envelope_of_ends(*ends, pair.frequency_hz, CUT.flutes, speeds, K)
    ref = _reference_envelope_of_ends(*ends, pair.frequency_hz, CUT.flutes, speeds, K)
    assert np.isfinite(new[0]).mean() > 0.9  # the band maps to most speeds: a real comparison
    np.testing.assert_array_equal(new[0], ref[0])
    np.testing.assert_array_equal(new[1], ref[1])
    np.testing.assert_array_equal(new[2], ref[2])
    depth_only = zoa._envelope_of_ends(*ends, pair.frequency_hz, CUT.flutes, speeds, K, track=False)
    np.testing.assert_array_equal(depth_only[0], ref[0])
    # zoa_lobes (the public function) goes through the same kernel
    res = zoa.zoa_lobes(pair.frf_x, pair.frf_y, pair.frequency_hz, CUT, speeds)
    np.testing.assert_array_equal(res.depth_limit_m, ref[0])
    np.testing.assert_array_equal(res.lobe, ref[2])


def test_map_level_and_window_equal_the_direct_forms(monkeypatch):
    rng = np.random.default_rng(5)
    lim = rng.lognormal(-8.0, 0.4, size=(37, 500))
    lim[rng.random(lim.shape) < 0.05] = np.inf  # speeds where a draw finds no chatter
    lim[:, 7] = np.inf
    depths = np.linspace(1e-5, 1e-3, 90)
    depths = np.append(depths, lim[0, 3])  # a depth exactly at a limit: a < a_lim is strict
    depths.sort()
    ref_map = _reference_probability_map(lim, depths)
    np.testing.assert_array_equal(probabilistic.probability_map(lim, depths), ref_map)
    monkeypatch.setattr(probabilistic, "_COMPILED_MAP_CELLS", 1)  # the compiled histogram of large maps
    np.testing.assert_array_equal(probabilistic.probability_map(lim, depths), ref_map)
    np.testing.assert_array_equal(probabilistic.probability_map(np.sort(lim, axis=0), depths), ref_map)
    ordered = np.sort(lim, axis=0)
    for level in (0.5, 0.8, 0.95, 1.0):
        ref = _reference_level_limit(lim, level)
        np.testing.assert_array_equal(recommend.level_limit(lim, level), ref)
        np.testing.assert_array_equal(recommend.level_limit(ordered, level, presorted=True), ref)
    q_new = probabilistic.depth_quantiles(ordered, presorted=True)
    q_ref = probabilistic.depth_quantiles(lim)
    for q in q_ref:
        np.testing.assert_array_equal(q_new[q], q_ref[q])
    n = np.linspace(5000.0, 30000.0, 500)
    a = lim[3]
    for tol in (0.0, 0.004, 0.02, 0.2):
        np.testing.assert_array_equal(recommend._window_min(n, a, tol), _reference_window_min(n, a, tol))
    uneven = np.sort(rng.uniform(5000.0, 30000.0, 500))
    np.testing.assert_array_equal(recommend._window_min(uneven, a, 0.03), _reference_window_min(uneven, a, 0.03))


# ------------------------------------------------------------------------------------------ end to end
def _result_arrays(res):
    rec, med = res.recommended, res.median_recommended
    return {"p_stable": res.p_stable, "depth_m": res.depth_m, "limits": res.depth_limit_m, "envelope": res.envelope,
            **{f"q{q}": v for q, v in res.quantiles.items()}}, (rec.as_dict(), med.as_dict(), res.pointwise.as_dict(),
                                                               res.alternatives)


def test_pipeline_equals_the_reference_pipeline(monkeypatch):
    pair = _draws(60)
    speeds = np.linspace(9000.0, 21000.0, 2401)
    kw = dict(method="zoa", level=0.95, tolerances=Tolerances(0.02, 0.1, 0.0), depth_points=120)
    with monkeypatch.context() as m:
        m.setattr(zoa, "_COMPILED_ENVELOPE_CELLS", 1)  # the compiled envelope and map, as for a full-size job
        m.setattr(probabilistic, "_COMPILED_MAP_CELLS", 1)
        new = lobes_from_frf_draws(pair.frf_x, pair.frf_y, pair.frequency_hz, CUT, speeds, **kw)
    with monkeypatch.context() as m:
        m.setattr(zoa, "_envelope_of_ends", _reference_envelope_of_ends)
        m.setattr(probabilistic, "probability_map", _reference_probability_map)
        m.setattr(probabilistic, "level_limit", _reference_level_limit)
        m.setattr(recommend, "level_limit", _reference_level_limit)
        m.setattr(recommend, "_window_min", _reference_window_min)
        ref = lobes_from_frf_draws(pair.frf_x, pair.frf_y, pair.frequency_hz, CUT, speeds, **kw)
    arrays_new, points_new = _result_arrays(new)
    arrays_ref, points_ref = _result_arrays(ref)
    for name in arrays_ref:
        np.testing.assert_array_equal(arrays_new[name], arrays_ref[name], err_msg=name)
    assert points_new == points_ref
    # a probabilistic case: the map has uncertain cells, the recommendation holds the level
    assert new.recommended.p_stable_neighbourhood >= 0.95 and np.any((new.p_stable > 0) & (new.p_stable < 1))


def test_recommendation_does_not_depend_on_the_map_resolution():
    pair = _draws(40, seed=11)
    speeds = np.linspace(9000.0, 21000.0, 3001)
    runs = [lobes_from_frf_draws(pair.frf_x, pair.frf_y, pair.frequency_hz, CUT, speeds, depth_points=p)
            for p in (20, 300)]
    assert runs[0].p_stable.shape == (3001, 20) and runs[1].p_stable.shape == (3001, 300)
    for attr in ("recommended", "median_recommended", "pointwise"):
        assert getattr(runs[0], attr) == getattr(runs[1], attr), attr
    assert runs[0].alternatives == runs[1].alternatives
    np.testing.assert_array_equal(runs[0].envelope, runs[1].envelope)
    from bayes_rcsa.stability.outputs import lobes_document
    from bayes_rcsa.stability.plots import display_map

    for res, p in zip(runs, (20, 300)):
        doc = lobes_document(res, CUT, {})
        assert doc["p_stable_map"]["speeds"] == 3001 and doc["p_stable_map"]["depths"] == p
        shown_n, shown_p, block = display_map(res.speed_rpm, res.p_stable, max_columns=1200)
        assert block == doc["p_stable_map"]["display_speed_block"] == 3
        assert shown_p.shape == (doc["p_stable_map"]["display_columns"], p) == (1001, p)
        np.testing.assert_allclose(shown_p[5], res.p_stable[15:18].mean(axis=0))


def test_the_warm_up_loads_the_kernels_with_the_signatures_the_job_calls():
    """bayes_rcsa.stability.warmup calls the compiled envelope and map on tiny inputs to load their cached machine
    code beside the job; inputs of other types would make numba compile a second version instead (seconds of
    interpreter time taken from the job).  After the warm-up, a job on the compiled path adds no signature."""
    from bayes_rcsa.stability import _zoa_kernel, warmup
    from bayes_rcsa.stability.modal_fit import ModalModel

    warmup.start(kernels=True, figure=False).join(120)
    before = {k: list(getattr(_zoa_kernel, k).signatures) for k in ("lower_envelope", "stable_fractions")}
    assert all(len(v) >= 1 for v in before.values()), before
    f = np.arange(600.0, 3000.0, 8.0)
    rng = np.random.default_rng(5)
    gx = np.array([ModalModel([1287 * a], [0.02], [1.0e6]).frf(f) for a in rng.normal(1, 0.01, 60)])
    gy = np.array([ModalModel([1340 * a], [0.03], [1.3e6]).frf(f) for a in rng.normal(1, 0.01, 60)])
    lobes_from_frf_draws(gx, gy, f, CUT, np.linspace(5000, 30000, 4000))  # 60 x 4000 cells: compiled
    after = {k: list(getattr(_zoa_kernel, k).signatures) for k in ("lower_envelope", "stable_fractions")}
    assert after == before
