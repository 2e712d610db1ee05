"""``bayes-rcsa update`` end to end on the example setup with a small stand-in posterior (#23).

The posterior is written directly (60 draws around the example's truth, no sampling) so the file costs a few
seconds; the cut outcomes come from the posterior's median limit with K_t 20 % above the assumed value.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_dir

CUT = ["--flutes", "4", "--immersion", "0.5"]
SPEEDS = np.array([7000.0, 9000.0, 11000.0, 13000.0, 15000.0, 17000.0])
# depth / true limit: the cuts between 0.83 and 1 would be stable with the assumed (20 % weaker) coefficients
FACTORS = np.array([0.7, 1.05, 0.9, 1.1, 0.95, 1.3])


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    from bayes_rcsa.inference.diagnostics import build_inference_data
    from bayes_rcsa.params import LogUniform, ParameterModel, Uniform
    from bayes_rcsa.params.growth import GrowthLaw
    from bayes_rcsa.stability import CuttingConditions, zoa_lobes
    from bayes_rcsa.stability.posterior_frf import posterior_frf_draws
    from bayes_rcsa.store import write_posterior

    root = tmp_path_factory.mktemp("cuts")
    shutil.copytree(example_dir(), root / "data")
    setup = root / "data" / "setup.toml"
    pm = ParameterModel.from_priors(GrowthLaw(0.025, 0.040, 0.5),
                                    {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e3, 1e8),
                                     "g_xf": Uniform(0, 0.5), "g_thetaM": Uniform(0, 0.5),
                                     "sigma_0": LogUniform(1e-4, 10)},
                                    {"c_xf": 10.0, "c_thetaM": 5e-4}, n_measurements=1)
    rng = np.random.default_rng(11)
    n = 60
    base = {"k_xf": 1.8e6, "k_thetaM": 4.5e5, "g_xf": 0.45, "g_thetaM": 0.45}
    post = {name: (base[name] * np.exp(rng.normal(0, 0.03, (1, n))) if name.startswith("k_") else
                   np.full((1, n), base.get(name, 0.01))) for name in pm.names}
    idata = build_inference_data(post, np.zeros((1, n)), np.zeros((1, n, 1)), np.ones(1, complex),
                                 {"fit_clamping_length": np.array([0.025, 0.03, 0.035, 0.04])},
                                 {"fit_clamping_length": ["fm"]}, {"fm": list("abcd")},
                                 {"method": "multi", "parameter_model": json.dumps(pm.to_dict())})
    write_posterior(idata, root / "posterior.nc")
    frf = posterior_frf_draws(setup, root / "posterior.nc", 0.03, n, np.random.default_rng(0))
    true = CuttingConditions(kt=1.2 * 600e6, kr=1.2 * 180e6, flutes=4, radial_immersion=0.5)
    a_true = np.median(zoa_lobes(frf.frf_x, frf.frf_y, frf.frequency_hz, true, SPEEDS).depth_limit_m, axis=0)
    depth = a_true * FACTORS
    rows = [f"{s:g},{d:.6g},{'chatter' if d > a else 'stable'}" for s, d, a in zip(SPEEDS, depth, a_true)]
    (root / "cuts.csv").write_text("spindle_speed_rpm,depth_m,outcome\n" + "\n".join(rows) + "\n")
    return root


def _update(world, out, *extra, cuts=None, capsys=None):
    argv = ["update", str(world / "data" / "setup.toml"), "--posterior", str(world / "posterior.nc"), "--cuts",
            str(cuts or world / "cuts.csv"), "--clamping-length", "0.03", *CUT, "--kt", "600e6±30%", "--kr",
            "180e6", "--draws", "60", "--particles", "16", "--min-ess", "5", "--out", str(out), *extra]
    return main(argv)


def test_update_writes_a_posterior_with_coefficients_that_lobes_uses(world, tmp_path, capsys):
    from bayes_rcsa.posterior import load_posterior
    from bayes_rcsa.stability.coefficients import read_coefficient_draws

    out = tmp_path / "upd"
    assert _update(world, out, "--speeds", "6000:18000:40", "--seed", "3") == 0
    doc = json.loads((out / "update.json").read_text())
    assert 5 <= doc["ess"]["draws"] <= 60 and doc["ess"]["n_particles"] == 60 * 16
    before, after = doc["kt_pa"]["before"], doc["kt_pa"]["after"]
    assert before[1] == pytest.approx(600e6, rel=0.05)
    assert after[1] > 1.08 * 600e6 and after[2] - after[0] < 0.8 * (before[2] - before[0])  # moved up, narrower
    assert len(doc["cuts"]) == 6 and all(c["moved"] is not None and "recommendation_moved" in c for c in doc["cuts"])
    assert doc["lobes"]["hammer_only"]["recommended"] is not None and doc["lobes"]["with_cuts"]["recommended"]
    draws = load_posterior(out / "posterior.nc")
    kt, kr = read_coefficient_draws(out / "posterior.nc")
    assert draws.n_draws == kt.size == 60 and np.allclose(kr / kt, 0.3)
    assert np.median(kt) == pytest.approx(after[1], rel=0.05)
    # lobes on the updated posterior: its per-draw K_t/K_r unless --kt/--kr are given (--no-plots: no test here
    # looks at lobes.png, whose drawing cost ~0.9 s of each ~1.2 s lobes run; the report below draws its figure)
    lob = ["lobes", str(world / "data" / "setup.toml"), "--posterior", str(out / "posterior.nc"), "--clamping-length",
           "0.03", *CUT, "--speeds", "6000:18000:40", "--draws", "60", "--quiet", "--depth-points", "20", "--no-plots"]
    assert main([*lob, "--out", str(tmp_path / "l1")]) == 0
    l1 = json.loads((tmp_path / "l1" / "lobes.json").read_text())
    assert l1["cutting_coefficients"]["kt_pa_q05_q50_q95"][1] == pytest.approx(np.median(kt), rel=1e-9)
    assert main([*lob, "--kt", "600e6", "--kr", "180e6", "--out", str(tmp_path / "l2")]) == 0
    l2 = json.loads((tmp_path / "l2" / "lobes.json").read_text())
    assert "cutting_coefficients" not in l2 and l2["cutting"]["kt_pa"] == 600e6
    # the report shows hammer only and hammer + 6 cuts side by side, and what each cut moved
    assert main(["report", str(out), "--out", str(tmp_path / "r.html")]) == 0
    html = (tmp_path / "r.html").read_text()
    assert 'id="cuts-1"' in html and "<th>hammer + 6 cuts</th>" in html and html.count("this cut moved") == 1
    before_rec = doc["lobes"]["hammer_only"]["recommended"]
    assert f"{before_rec['spindle_speed_rpm']:.0f}"[:3] in html and html.count('alt="hammer only vs hammer + cuts"') == 1


@pytest.mark.parametrize("row, message", [
    ("9000,2.5,chatter", "depth_m 2.5 m is implausible"),
    ("9000,0.0002,wobbly", "outcome 'wobbly', expected 'stable' or 'chatter'"),
    ("90000,0.0002,chatter", "outside the speed range the FRF band supports"),
])
def test_bad_cuts_exit_2_with_one_line_and_no_output(world, tmp_path, capsys, row, message):
    bad = tmp_path / "bad.csv"
    bad.write_text((world / "cuts.csv").read_text() + row + "\n")
    capsys.readouterr()
    assert _update(world, tmp_path / "out", cuts=bad) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("bayes-rcsa update: error: ") and message in err[0], err
    assert not (tmp_path / "out").exists()


def test_cuts_at_a_length_the_posterior_cannot_predict_exit_2(world, tmp_path, capsys):
    bad = tmp_path / "len.csv"
    bad.write_text("spindle_speed_rpm,depth_m,outcome,clamping_length_m\n9000,0.0002,stable,0.09\n")
    capsys.readouterr()
    assert _update(world, tmp_path / "out", cuts=bad) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "clamping length the posterior cannot predict" in err[0], err
    assert not (tmp_path / "out").exists()
    # lobes on a hammer-only posterior still needs --kt/--kr
    assert main(["lobes", str(world / "data" / "setup.toml"), "--posterior", str(world / "posterior.nc"),
                 "--clamping-length", "0.03", *CUT, "--speeds", "6000:18000:20", "--out", str(tmp_path / "l")]) == 2
    assert "carries no cutting-coefficient draws" in capsys.readouterr().err


def test_collapsed_reweighting_falls_back_to_mcmc_or_is_refused(world, tmp_path, capsys):
    from bayes_rcsa.posterior import load_posterior

    # --min-ess above the 60 draws forces the collapse; a short chain (the fallback's cost, not its accuracy)
    assert _update(world, tmp_path / "m", "--min-ess", "200", "--mcmc-steps", "30", "--mcmc-walkers", "8") == 0
    doc = json.loads((tmp_path / "m" / "update.json").read_text())
    assert doc["sampler"] == "mcmc" and doc["ess"]["importance_draws"] < 200
    assert any("sampled by MCMC" in w for w in doc["warnings"])
    assert doc["mcmc"]["parameters"] == ["k_xf", "k_thetaM", "g_xf", "g_thetaM", "log_level"]
    # the package's one sampler driver ran it (fixed steps) and reported, not assumed, its convergence
    assert doc["mcmc"]["convergence"].startswith("n_steps = 30 run: ")
    assert len(doc["mcmc"]["rhat"]) == len(doc["mcmc"]["ess_bulk"]) == len(doc["mcmc"]["autocorrelation_time"]) == 5
    assert doc["mcmc"]["converged"] is False and any("MCMC fallback (n_steps = 30 run: not converged" in w
                                                     for w in doc["warnings"])
    assert doc["kt_pa"]["after"][1] > 1.05 * 600e6  # the cuts' evidence for stronger coefficients survives
    hammer = load_posterior(world / "posterior.nc").values["k_xf"]
    new = load_posterior(tmp_path / "m" / "posterior.nc").values["k_xf"]
    assert new.size == 60 and not np.isin(new, hammer).all()  # new draws, not a re-weighting of the old ones
    capsys.readouterr()
    assert _update(world, tmp_path / "r", "--min-ess", "200", "--no-mcmc") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "effective sample size" in err[0] and not (tmp_path / "r").exists()


def test_identify_cuts_options_are_checked_before_sampling(world, tmp_path, capsys):
    base = ["identify", str(world / "data" / "setup.toml"), "--lengths", "0.03", "--quiet", "--no-plots"]
    cases = [(["--cut-kt", "600e6", "--out", str(tmp_path / "a")], "--cut-kt need(s) --cuts CSV"),
             (["--cuts", str(world / "cuts.csv"), "--method", "deterministic", "--out", str(tmp_path / "b")],
              "--cuts needs a Bayesian method"),
             (["--cuts", str(world / "cuts.csv"), "--cut-flutes", "4", "--out", str(tmp_path / "c")],
              "--cuts needs --cut-kt, --cut-kr")]
    for extra, message in cases:
        capsys.readouterr()
        assert main([*base, *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    assert not any((tmp_path / n).exists() for n in "abc")


def test_identify_with_cuts_samples_the_coefficients_with_the_contact_end_to_end(world, tmp_path, capsys):
    """``identify --cuts``: hammer FRF at 30 mm and the six cuts (made with K_t 20 % above the assumed 600e6)
    sampled together.  The default sampler keeps importance sampling here (Pareto k = -0.31, ESS 2718 of the 1000
    it needs), so no chain runs: 16 walkers and at most 200 steps only bound the MCMC fall-back.  Most of the cost
    is the cuts' stability limits at every evaluation (164 batches).  Its K_t moves up from the assumed value and
    covers the truth, the draws are in posterior.nc, and lobes uses them."""
    from bayes_rcsa.stability.coefficients import read_coefficient_draws

    out = tmp_path / "fit"
    argv = ["identify", str(world / "data" / "setup.toml"), "--lengths", "0.03", "--cuts", str(world / "cuts.csv"),
            "--cut-clamping-length", "0.03", "--cut-kt", "600e6±30%", "--cut-kr", "180e6", *[f"--cut-{a[2:]}" if
            a.startswith("--") else a for a in CUT], "--max-steps", "200", "--walkers", "16", "--quiet", "--no-plots",
            "--seed", "5", "--out", str(out)]
    assert main(argv) == 0
    cuts = json.loads((out / "summary.json").read_text())["cuts"]
    q05, q50, q95 = cuts["kt_pa_q05_q50_q95"]
    # prior median 600e6 (log-sd 0.26); the truth is 720e6: the cuts pull the median up and the interval covers it
    assert q50 > 1.05 * 600e6 and q05 < 720e6 < q95, cuts
    kt, kr = read_coefficient_draws(out / "posterior.nc")
    assert np.median(kt) == pytest.approx(q50, rel=0.05) and np.allclose(kr / kt, 0.3)
    lob = ["lobes", str(world / "data" / "setup.toml"), "--posterior", str(out / "posterior.nc"), "--clamping-length",
           "0.03", *CUT, "--speeds", "6000:18000:40", "--draws", "60", "--quiet", "--depth-points", "20",
           "--no-plots", "--out", str(tmp_path / "l")]
    assert main(lob) == 0
    doc = json.loads((tmp_path / "l" / "lobes.json").read_text())
    assert doc["cutting_coefficients"]["kt_pa_q05_q50_q95"][1] == pytest.approx(np.median(kt), rel=0.05)
