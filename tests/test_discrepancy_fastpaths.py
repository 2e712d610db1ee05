"""The discrepancy workflow's fast paths give the same numbers, bit for bit, as the computations they replace.

Each fast path batches or reuses work (a tool two-port per clamping length on the union of its lines, the
model FRFs of a Jacobian batch reused when only the noise coordinates changed, the mode-bias quantiles of all
rows in one call, the predictive noise without repeated arrays); each test here compares it with the direct
computation on small inputs, with ``==`` (no tolerance).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayes_rcsa.data import example_dir
from bayes_rcsa.discrepancy import DiscrepancyOptions
from bayes_rcsa.discrepancy import evaluate as ev
from bayes_rcsa.discrepancy import fit as fit_mod
from bayes_rcsa.discrepancy import mode_bias as mb
from bayes_rcsa.discrepancy.workflow import _problem, validate
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.model.assembly import Configuration
from bayes_rcsa.model.geometry import tool_overhang_segments
from bayes_rcsa.model.timoshenko import free_free_receptances
from bayes_rcsa.params.terms import Substructures, TermContext, make_term
from bayes_rcsa.params.terms.fluted_section import FLUTE_LENGTH
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign


@pytest.fixture(scope="module")
def example():
    setup = load_setup(example_dir() / "setup.toml")
    _, base_opts, _ = validate(setup, DiscrepancyOptions(lengths=(0.025, 0.030, 0.040)))
    return setup, base_opts


def _context(model, lines_by_config):
    cfgs = tuple(c for c, _ in lines_by_config)
    f = np.concatenate([f for _, f in lines_by_config])
    idx = np.concatenate([np.full(f.size, j) for j, (_, f) in enumerate(lines_by_config)])
    return TermContext(model=model, configurations=cfgs, frequency_hz=f, omega=2 * np.pi * f, line_config=idx,
                       lengths=np.array(sorted({c.clamping_length for c in cfgs})), l_a=0.025, l_b=0.040)


def _tool_substructures(model, ctx, n_sets):
    parts = []
    for j, c in enumerate(ctx.configurations):
        segs = tool_overhang_segments(model.holder, model.tool(c.tool), c.clamping_length)
        parts.append(free_free_receptances(segs, ctx.omega[ctx.line_config == j]))
    from bayes_rcsa.model.timoshenko import TwoPort

    tool = TwoPort(*(np.repeat(np.concatenate([getattr(p, k) for p in parts])[None], n_sets, axis=0)
                     for k in ("r11", "r12", "r21", "r22")))
    return Substructures(None, None, tool)


def _check_fluted_union(model, values, n_sets):
    # the two directions of a clamping length on different, overlapping lines (a repeated tap at 30 mm too)
    rng = np.random.default_rng(1)
    lines = []
    for length in (0.025, 0.030, 0.040):
        base = np.arange(700.0, 1500.0, 4.0) + 1e3 * (length - 0.025)
        lines.append((Configuration(length, "x"), base[rng.random(base.size) < 0.8]))
        lines.append((Configuration(length, "y"), base[rng.random(base.size) < 0.6]))
    lines.append((Configuration(0.030, "x"), np.arange(650.0, 1300.0, 3.0)))
    term = make_term("fluted_section")
    ctx = _context(model, lines)
    got = term.substructures(values, _tool_substructures(model, ctx, n_sets), ctx).tool
    for j, (cfg, f) in enumerate(lines):  # the reference: each configuration on its own lines alone
        one = _context(model, [(cfg, f)])
        ref = term.substructures(values, _tool_substructures(model, one, n_sets), one).tool
        for k in ("r11", "r12", "r21", "r22"):
            assert np.array_equal(getattr(got, k)[:, ctx.line_config == j], getattr(ref, k)), (cfg, k)


def test_fluted_two_port_on_the_union_of_a_clamping_lengths_lines_is_each_configurations_own(example):
    setup, _ = example
    model = setup.model()
    # sets at the baseline (untouched), repeated and distinct
    values = {"flute_area_ratio": np.array([1.0, 0.8, 0.8, 0.9, 0.7]),
              "flute_inertia_ratio": np.array([1.0, 0.6, 0.6, 0.75, 0.5])}
    _check_fluted_union(model, values, 5)


def test_fluted_two_port_of_a_one_cylinder_tool_on_the_union_of_lines(tmp_path):
    cfg = default_bench_config(tool_declared="one_cylinder", frequency_step=8.0)
    path = write_campaign(generate_campaign(cfg, np.random.default_rng(0)), tmp_path / "c")
    model = load_setup(path).model()
    values = {"flute_area_ratio": np.array([0.8, 0.8, 0.9]), "flute_inertia_ratio": np.array([0.6, 0.6, 0.75]),
              FLUTE_LENGTH: np.array([2.0, 3.0, 3.0])}
    _check_fluted_union(model, values, 3)


def test_mode_bias_batched_row_statistics_are_the_row_by_row_ones():
    rng = np.random.default_rng(3)
    x = rng.normal(1000.0, 5.0, (6, 1600))
    x[2, 17] = np.nan
    x[4] = np.nan
    got = mb._row_quantiles(x)
    for r in range(x.shape[0]):
        ref = mb._quantiles(x[r])
        assert all(got[r][k] == ref[k] or (math.isnan(got[r][k]) and math.isnan(ref[k])) for k in ref)
    with np.errstate(invalid="ignore"), pytest.warns(RuntimeWarning):
        sds = mb._row_nanstd(x)
    with np.errstate(invalid="ignore"), pytest.warns(RuntimeWarning):
        ref_sds = [float(np.nanstd(row)) for row in x]
    assert np.array_equal(sds, ref_sds, equal_nan=True)
    rows = [rng.normal(0.0, 1.0, 200) for _ in range(3)]
    assert mb._robust_vars([0.25, *rows]) == [0.25, *(mb._robust_var(r) for r in rows)]
    rows[1][5] = np.inf  # a row with a non-finite value: the row-by-row path
    assert mb._robust_vars(rows + [0.5]) == [*(mb._robust_var(r) for r in rows), 0.5]
    lengths = np.array([0.025, 0.030, 0.040])
    p, a = mb._contrasts(tuple(lengths.tolist()), 1, 0.0075)
    h = mb._basis(lengths, float(np.mean(lengths)), max(float(np.ptp(lengths)), 1e-3), 1)
    q, _ = np.linalg.qr(h, mode="complete")
    assert np.array_equal(p, q[:, 2:])
    assert np.array_equal(a, q[:, 2:].T @ np.exp(-0.5 * ((lengths[:, None] - lengths[None, :]) / 0.0075) ** 2)
                          @ q[:, 2:])


def test_predictive_noise_copies_are_the_repeated_arrays_sum():
    rng = np.random.default_rng(4)
    hd = rng.normal(size=(7, 33)) + 1j * rng.normal(size=(7, 33))
    sd = rng.uniform(0.01, 0.3, (7, 33))
    r_ref, r_new = np.random.default_rng(9), np.random.default_rng(9)
    hd_rep, sd_rep = np.repeat(hd, ev.NOISE_REPLICATES, axis=0), np.repeat(sd, ev.NOISE_REPLICATES, axis=0)
    eps = (r_ref.standard_normal(hd_rep.shape) + 1j * r_ref.standard_normal(hd_rep.shape)) * (sd_rep / math.sqrt(2.0))
    assert np.array_equal(ev._with_noise(hd, sd, r_new), hd_rep + eps)
    assert r_ref.standard_normal() == r_new.standard_normal()  # the same stream consumed


def test_a_start_given_twice_is_polished_once_with_the_same_fit(example, monkeypatch):
    setup, base_opts = example
    p = _problem(setup, base_opts, [])
    b = np.array(p.priors.optimisation_bounds(), dtype=float)
    a, c = b[:, 0] + 0.45 * (b[:, 1] - b[:, 0]), b[:, 0] + 0.55 * (b[:, 1] - b[:, 0])
    runs, real = [], fit_mod._gauss_newton

    def counted(problem, theta0, *args, **kw):
        out = real(problem, theta0, *args, **kw)
        runs.append((theta0.copy(), out))
        return out

    monkeypatch.setattr(fit_mod, "_gauss_newton", counted)
    fit = fit_mod.fit_variant("baseline", p, np.array([a, a, c]), 0.5, n_polish=3)
    assert len(runs) == 2  # the repeated start once
    # the reference: each distinct start polished on its own, the better one kept, every polish counted
    lp = p.log_posterior()
    refs = [real(p, fit_mod.profile_noise(p, s)) for s in (a, c)]
    vals = [float(lp(t[None])[0]) for t, _ in refs]
    best = refs[int(np.argmax(vals))][0]
    ref = fit_mod._finish("baseline", p, best, 0.5, 3 + 2 * refs[0][1] + refs[1][1])
    assert np.array_equal(fit.theta, ref.theta) and fit.n_evaluations == ref.n_evaluations
    assert fit.log_evidence == ref.log_evidence and np.array_equal(fit.cov, ref.cov)


def test_fluted_two_port_with_cached_unchanged_segments_is_the_computed_one(example, monkeypatch):
    from bayes_rcsa.params.terms import fluted_section as fs

    setup, _ = example
    model = setup.model()
    values = {"flute_area_ratio": np.array([0.8, 0.9]), "flute_inertia_ratio": np.array([0.6, 0.75])}
    f = np.arange(700.0, 1500.0, 4.0)
    ctx = _context(model, [(Configuration(0.025, "x"), f), (Configuration(0.040, "y"), f + 2.0)])
    term = make_term("fluted_section")
    fs._CONSTANT_PIECES.clear()
    cold = term.substructures(values, _tool_substructures(model, ctx, 2), ctx).tool
    warm = term.substructures(values, _tool_substructures(model, ctx, 2), ctx).tool  # from the cache
    assert fs._CONSTANT_PIECES  # the unfluted segments were cached
    # the reference: every segment computed afresh
    monkeypatch.setattr(fs, "_constant_piece",
                        lambda length, props, omega: fs.batched_segment_stiffness(length, *props, omega))
    ref = term.substructures(values, _tool_substructures(model, ctx, 2), ctx).tool
    for k in ("r11", "r12", "r21", "r22"):
        assert np.array_equal(getattr(cold, k), getattr(ref, k)) and np.array_equal(getattr(warm, k), getattr(ref, k))
