"""``fluted_section`` on a tool declared as one cylinder: a fluted tip of unknown length (issue #43 item 1).

The user writes the catalogue diameter and the total length; the tool is fluted at its tip all the same.  The
term then carries the fluted length (in tool diameters) as a parameter with a catalogue prior bounded so that the
flutes never reach into the holder.  Checked here: the parameter and its bounds (and the refusals), the exact
baseline whatever the fluted length, passivity and reciprocity, batching, and noise-free least-squares fits on
one-cylinder campaigns of BOTH benches (the project's FE bench and the independent rotor bench, written as a
user would and loaded from their setup files), which must remove the gap and recover the bench's fluted length.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import least_squares

from bayes_rcsa.errors import ModelError, SetupError
from bayes_rcsa.io.setup import load_setup
from bayes_rcsa.model import ConfigurationStack
from bayes_rcsa.model.assembly import Configuration, ToolPointModel
from bayes_rcsa.model.geometry import Tool, ToolSegment, tool_overhang_segments
from bayes_rcsa.model.timoshenko import TwoPort, free_free_receptances
from bayes_rcsa.params import ForwardModel, GrowthLaw, LogUniform, ParameterModel, Uniform, make_term
from bayes_rcsa.params.terms import Substructures, TermContext
from bayes_rcsa.params.terms.fluted_section import FLUTE_LENGTH, FLUTE_LENGTH_RANGE, grip_depth

STEP = 8.0  # Hz: noise-free lines; the tool modes' half-power widths are 20-60 Hz
BAND = (600.0, 2000.0)  # Hz: the tool modes of both benches at 25-40 mm
LENGTHS = (0.025, 0.040)
TERM = "fluted_section"


def _write(generator: str, root):
    """A noise-free one-cylinder campaign of ``generator`` ("fe" or "rotor"), loaded from its setup file."""
    common = dict(frequency_step=STEP, frequency_start=BAND[0], frequency_stop=BAND[1], noise_relative=0.0,
                  noise_floor=1e-30, clamping_lengths=LENGTHS, directions=("x",))
    if generator == "fe":
        from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

        cfg = default_bench_config(tool_declared="one_cylinder", **common)  # truth: 30-mm tip of ratio 0.80
        path = write_campaign(generate_campaign(cfg, np.random.default_rng(0)), root / "fe")
        flute = sum(s.length for s in cfg.tool_segments if s.diameter_ratio < 1) / cfg.tool_segments[0].diameter
        k = (cfg.k_xf, cfg.k_thetaM)
    else:
        from bayes_rcsa.synthetic import rotor

        cfg = rotor.rotor_bench_config({"fluted_section": 1.0}, fluted_declared="undeclared", **common)
        path = rotor.write_rotor_campaign(rotor.generate_rotor_campaign(cfg, np.random.default_rng(0)), root / "rotor")
        flute = cfg.flute_length / cfg.tool_diameter
        k = (cfg.k_xf, cfg.k_thetaM)
    return load_setup(path), flute, k, json.loads((path.parent / "truth.json").read_text())


@pytest.fixture(scope="module")
def benches(tmp_path_factory):
    root = tmp_path_factory.mktemp("one_cylinder")
    return {g: _write(g, root) for g in ("fe", "rotor")}


def _forward(setup, terms):
    model = setup.model()
    stack = ConfigurationStack([model.precompute(m.configuration, m.frf.frequency_hz) for m in setup.measurements])
    spec = setup.contact
    priors = {"k_xf": LogUniform(*spec.translational_stiffness), "k_thetaM": LogUniform(*spec.rotational_stiffness),
              "g_xf": Uniform(-0.5, 1.0), "g_thetaM": Uniform(-0.5, 1.0)}
    pm = ParameterModel.from_priors(GrowthLaw(*LENGTHS, 1.0), priors,
                                    {"c_xf": spec.translational_damping, "c_thetaM": spec.rotational_damping},
                                    terms=[make_term(t) for t in terms], model=model)
    return ForwardModel(pm, stack, model), np.concatenate([m.frf.values for m in setup.measurements])


def _values(setup, n, **term):
    spec = setup.contact
    v = {"k_xf": np.full(n, 2.5e6), "k_thetaM": np.full(n, 4.5e5), "g_xf": np.full(n, 0.45),
         "g_thetaM": np.full(n, 0.45), "c_xf": np.full(n, spec.translational_damping),
         "c_thetaM": np.full(n, spec.rotational_damping)}
    v.update({k: np.asarray(x, dtype=float) for k, x in term.items()})
    return v


def test_a_one_cylinder_tool_gets_a_fluted_length_whose_prior_keeps_the_flutes_outside_the_holder(benches):
    for name, (setup, flute, _, _) in benches.items():
        model = setup.model()
        tool = model.tool("tool")
        assert len(tool.segments) == 1  # the setup file declares one cylinder
        params = {p.name: p for p in make_term(TERM).parameters(model)}
        assert set(params) == {"flute_area_ratio", "flute_inertia_ratio", FLUTE_LENGTH}
        # declared at the nominal diameter (r = 1): the profile ranges themselves
        assert params["flute_area_ratio"].prior.bounds == (0.40, 1.0)
        assert params["flute_inertia_ratio"].prior.bounds == (0.25, 1.0)
        lo, hi = params[FLUTE_LENGTH].prior.bounds
        d = tool.segments[0].diameter
        grip = grip_depth(model.holder, tool)
        assert lo == FLUTE_LENGTH_RANGE[0] < flute < hi <= FLUTE_LENGTH_RANGE[1]  # the bench's flute is inside
        # at every clamping length up to the depth of the gripping bore the longest flute stays outside the holder
        for cl in np.linspace(0.001, grip, 50):
            assert hi * d <= tool.total_length - cl * (1 - 1e-12), (name, cl)
        lo_b, hi_b = params[FLUTE_LENGTH].prior.bounds
        assert lo_b <= params[FLUTE_LENGTH].baseline <= hi_b
    # the project's bench: the collet bore (59.5 mm) grips the shank and lowers the catalogue's 6 diameters to 5.30;
    # the rotor bench: the collet (42 mm) grips, not the 14-mm bore behind it (80 mm deep in all)
    fe, rotor = (benches[g][0].model() for g in ("fe", "rotor"))
    assert grip_depth(fe.holder, fe.tool("tool")) == pytest.approx(0.0595)
    assert make_term(TERM).parameters(fe)[2].prior.bounds[1] == pytest.approx((0.1016 - 0.0595) / 0.00794)
    assert grip_depth(rotor.holder, rotor.tool("tool")) == pytest.approx(0.042)
    assert rotor.holder.bore_depth == pytest.approx(0.080)


def test_the_benches_write_one_cylinder_keep_the_flute_in_the_truth_and_check_the_option(benches, tmp_path):
    from bayes_rcsa.synthetic import default_bench_config, load_bench_config
    from bayes_rcsa.synthetic import rotor

    fe, ro = benches["fe"][3], benches["rotor"][3]
    assert fe["tool_declared"] == "one_cylinder"
    assert fe["hidden_effect_details"]["fluted_section"]["true_flute_length"] == pytest.approx(0.030)
    assert fe["tool"]["segments"][0]["diameter_ratio"] == 0.8  # the truth keeps its fluted tip
    flute = ro["hidden_effect_details"]["fluted_section"]
    assert flute["declared"] == "undeclared" and flute["declared_flute_length"] is None
    assert flute["true_flute_length"] == pytest.approx(0.030)
    with pytest.raises(SetupError, match=r"tool_declared = 'cylinder': expected one of \('segments', 'one_cylinder'\)"):
        default_bench_config(tool_declared="cylinder")
    with pytest.raises(SetupError, match=r"fluted_declared = 'none': expected one of .*'undeclared'"):
        rotor.rotor_bench_config(fluted_declared="none")
    (tmp_path / "b.toml").write_text('[tool]\ndeclared = "one_cylinder"\n')
    assert load_bench_config(tmp_path / "b.toml").tool_declared == "one_cylinder"


def test_refusals_name_the_tool_and_the_fluted_length(benches):
    model = benches["fe"][0].model()
    carbide = model.tool("tool").material
    # 65 mm of tool in a 59.5-mm collet: 5.5 mm outside, less than one diameter
    short = ToolPointModel(model.holder, {"short": Tool(carbide, 0.065, (ToolSegment(0.065, 0.00794),), "short")},
                           model.spindle)
    with pytest.raises(ModelError, match=r"tool 'short' \(total_length 65 mm.*less than the shortest catalogue"):
        make_term(TERM).parameters(short)  # the discrepancy workflow reads this as "not applicable"
    # clamped deeper than the gripping bore (the rotor holder's 14-mm bore reaches 80 mm): a 5.9-diameter flute
    # would be clamped at 60 mm and is refused by value when evaluated
    setup = benches["rotor"][0]
    rmodel = setup.model()
    cfg = Configuration(0.060, "x")
    stack = ConfigurationStack([rmodel.precompute(cfg, np.array([800.0, 900.0]))])
    pm = ParameterModel.from_priors(GrowthLaw(*LENGTHS, 1.0), {}, {"k_xf": 3e6, "k_thetaM": 5e5, "g_xf": 0.4,
                                    "g_thetaM": 0.4, "c_xf": 10.0, "c_thetaM": 5e-4}, terms=[TERM], model=rmodel)
    fwd = ForwardModel(pm, stack, rmodel)
    v = _values(setup, 2, flute_area_ratio=[0.6, 0.6], flute_inertia_ratio=[0.4, 0.4], **{FLUTE_LENGTH: [3.0, 5.9]})
    with pytest.raises(ModelError, match=rf"{FLUTE_LENGTH} = 5.9 \(46.85 mm\) reaches into the holder.*60 mm"):
        fwd.frf(v)
    v[FLUTE_LENGTH] = np.array([3.0, 4.0])
    assert np.all(np.isfinite(fwd.frf(v)))


def test_exact_baseline_for_any_fluted_length_passive_reciprocal_and_batched(benches):
    setup, _, _, _ = benches["rotor"]
    fwd, _ = _forward(setup, [TERM])
    plain, _ = _forward(setup, [])
    lo, hi = fwd.parameters[FLUTE_LENGTH].prior.bounds
    lengths = np.array([lo, 2.7, hi, 2.7, 4.1])
    v = _values(setup, 5, flute_area_ratio=[1, 1, 1, 0.55, 0.9], flute_inertia_ratio=[1, 1, 1, 0.3, 0.97],
                **{FLUTE_LENGTH: lengths})
    h = fwd.frf(v)
    base = fwd.frf({k: x[:1] for k, x in v.items()})  # the term at its baseline alone: the substructures untouched
    ref = plain.frf({k: x[:1] for k, x in v.items()})
    np.testing.assert_allclose(base, ref, rtol=1e-12, atol=0)  # same physics as the model without the term
    for j in range(3):  # bit for bit, whatever the fluted length, also in a batch with sets that are not at it
        assert np.array_equal(h[j], base[0])
    for j in (3, 4):  # the flute changes the FRF, and a set in a batch is the set alone (no cross-talk)
        assert np.max(np.abs(h[j] - base[0])) > 0.05 * np.max(np.abs(base[0]))
        alone = fwd.frf({k: x[j:j + 1] for k, x in v.items()})
        np.testing.assert_allclose(h[j], alone[0], rtol=1e-12, atol=0)
    # repeated sets (a finite-difference Jacobian's batch, computed once per distinct set): each row is its own set's
    rep = [3, 4, 3, 0, 4, 3]
    np.testing.assert_allclose(fwd.frf({k: x[rep] for k, x in v.items()}), h[rep], rtol=1e-12, atol=0)
    # passive (e^{+i w t}: Im h <= 0) over the corners of the prior box
    corners = np.array(np.meshgrid(fwd.parameters["flute_area_ratio"].prior.bounds,
                                   fwd.parameters["flute_inertia_ratio"].prior.bounds, (lo, hi))).reshape(3, -1)
    hc = fwd.frf(_values(setup, corners.shape[1], flute_area_ratio=corners[0], flute_inertia_ratio=corners[1],
                         **{FLUTE_LENGTH: corners[2]}))
    assert np.all(hc.imag <= 1e-12 * np.abs(hc).max())
    # the recomputed tool two-port is reciprocal (symmetric receptance matrix) and dissipative (-Im >= 0)
    model, ctx = setup.model(), fwd.context
    lines = ctx.line_config == 0
    w = ctx.omega[lines]
    t0 = free_free_receptances(tool_overhang_segments(model.holder, model.tool("tool"), LENGTHS[0]), w)
    t0 = TwoPort(*(getattr(t0, k)[None] for k in ("r11", "r12", "r21", "r22")))
    one = TermContext(model, ctx.configurations[:1], ctx.frequency_hz[lines], w, np.zeros(w.size, dtype=int),
                      ctx.lengths[:1], ctx.l_a, ctx.l_b)
    tp = make_term(TERM).substructures({"flute_area_ratio": corners[0], "flute_inertia_ratio": corners[1],
                                        FLUTE_LENGTH: corners[2]}, Substructures(np.zeros((1, w.size, 2, 2)), t0, t0),
                                       one).tool
    full = np.block([[tp.r11, tp.r12], [tp.r21, tp.r22]])  # (n_sets, n_lines, 4, 4)
    big = np.abs(full).max()
    np.testing.assert_allclose(full, np.swapaxes(full, -1, -2), rtol=0, atol=1e-9 * big)
    assert np.all(np.linalg.eigvalsh(-(full - np.conj(np.swapaxes(full, -1, -2))) / 2j) >= -1e-9 * big)


def _fit(setup, terms, start: dict):
    """Least squares of contact (+ term) on the noise-free FRFs: relative RMS residual and the fitted values.

    In the prior's sampling coordinates, from ``start`` (physical values; without a term from the best point of a
    contact grid); the forward-difference Jacobian is one batched model evaluation (the term is vectorised over
    parameter sets).
    """
    fwd, data = _forward(setup, terms)
    pm = fwd.parameters
    bounds = np.array([pm[n].prior.bounds for n in pm.names])
    scale = np.linalg.norm(data)

    def res(x):
        return ((fwd.frf(pm.values(np.atleast_2d(x))) - data) / scale).view(float)

    def jac(x):
        h = 1e-7 * (bounds[:, 1] - bounds[:, 0])
        h = np.where(x + h > bounds[:, 1], -h, h)
        r = res(np.vstack([x, x + np.diag(h)]))
        return ((r[1:] - r[0]) / h[:, None]).T

    x0 = pm.sampling(start)
    if not terms:  # the model without the term: its best contact on a batched grid first (its misfit is multimodal)
        kx, kt, g = (a.ravel() for a in np.meshgrid(np.geomspace(3e5, 3e7, 17), np.geomspace(3e4, 3e7, 17),
                                                    (0.2, 0.5), indexing="ij"))
        grid = np.column_stack([pm.sampling({"k_xf": a, "k_thetaM": b, "g_xf": c, "g_thetaM": c})
                                for a, b, c in zip(kx, kt, g)]).T
        x0 = grid[int(np.argmin(np.sum(res(grid) ** 2, axis=1)))]
    r = least_squares(lambda x: res(x)[0], np.clip(x0, bounds[:, 0] + 1e-9, bounds[:, 1] - 1e-9), jac=jac,
                      bounds=bounds.T, x_scale=0.1 * (bounds[:, 1] - bounds[:, 0]), max_nfev=100)
    return float(np.sqrt(2 * r.cost)), {n: float(v[0]) for n, v in pm.values(r.x[None]).items()}


@pytest.mark.parametrize("generator", ["fe", "rotor"])
def test_noise_free_fit_removes_the_gap_and_recovers_the_fluted_length(benches, generator):
    """Contact alone, then contact + the term with its fluted length free, started a diameter short of the truth
    (the contact at the bench's, the ratios at a mid-range profile).

    The project's bench's flute is a circle of ratio 0.80 over 30 mm (3.78 diameters): exactly the term's form,
    so the fit must recover it within 1 % (measured 0.01 %: a = 0.640, i = 0.410).  The rotor bench's is a
    four-flute profile (A/A_s 0.634, I/I_s 0.472) with its own shear coefficient, which the term keeps at the
    circle's: measured 1 % short (3.74-3.75), the tolerance 3 % (0.9 mm, the fluted length to within a ninth of
    a diameter).
    """
    setup, flute, k, _ = benches[generator]
    contact = {"k_xf": k[0], "k_thetaM": k[1], "g_xf": 0.45, "g_thetaM": 0.45}
    before, _ = _fit(setup, [], contact)
    after, fitted = _fit(setup, [TERM], {**contact, "flute_area_ratio": 0.7, "flute_inertia_ratio": 0.5,
                                        FLUTE_LENGTH: flute - 1.0})
    # a one-cylinder model misses the flute by far more than a campaign's 2 % noise (measured 0.35 and 0.15)
    assert before > 0.1, before
    assert after < 0.01 * before, (before, after, fitted)  # measured 4e-6 and 2.7e-4
    tol = 0.01 if generator == "fe" else 0.03
    assert fitted[FLUTE_LENGTH] == pytest.approx(flute, rel=tol), fitted
    assert fitted["k_xf"] == pytest.approx(k[0], rel=0.1) and fitted["k_thetaM"] == pytest.approx(k[1], rel=0.25)
    assert not make_term(TERM).implausible(fitted)  # a flute profile, not a stand-in


def test_the_screen_s_batched_flute_length_grid_is_the_point_by_point_score_test(benches, monkeypatch):
    """On a one-cylinder tool the fluted length has no effect at the baseline (a = i = 1) and has no switch, so
    the score test differentiates the term at each point of the length grid: in batched model evaluations
    (``screen._grid_jacobians``), which must give the point-by-point Jacobians' statistic and starts."""
    from bayes_rcsa.discrepancy import DiscrepancyOptions, screen
    from bayes_rcsa.discrepancy import workflow as W
    from bayes_rcsa.discrepancy.fit import fit_baseline, whitened_residuals

    setup = benches["rotor"][0]
    _, base_opts, problem = W.validate(setup, DiscrepancyOptions(lengths=LENGTHS, candidates=(TERM,)))
    baseline = fit_baseline(problem)
    term_problem = W._problem(setup, base_opts, [TERM])
    calls = []
    batched_grid = screen._grid_jacobians

    def spy(problem, points, cols, h, floor=None):
        calls.append(points.shape[0])
        return batched_grid(problem, points, cols, h, floor)

    monkeypatch.setattr(screen, "_grid_jacobians", spy)
    fast = screen.score_test(baseline, term_problem, TERM)
    assert calls and calls[0] >= 100  # the grid path ran, over the fine grid of the fluted length

    def point_by_point(problem, points, cols, h, floor=None):
        out = []
        for theta, hk in zip(points, h):
            pts = np.repeat(theta[None], len(cols) + 1, axis=0)
            pts[1 + np.arange(len(cols)), cols] += hk
            z = whitened_residuals(problem, pts, floor)
            out.append(((z[1:] - z[0]) / hk[:, None]).T)
        return np.array(out)

    monkeypatch.setattr(screen, "_grid_jacobians", point_by_point)
    slow = screen.score_test(baseline, term_problem, TERM)
    assert fast.dof == slow.dof and fast.statistic > 0
    # a set's residuals do not depend on the batch it is evaluated in (rounding aside)
    np.testing.assert_allclose(fast.statistic, slow.statistic, rtol=1e-9)
    np.testing.assert_allclose(np.array(fast.starts), np.array(slow.starts), rtol=1e-9, atol=1e-12)
