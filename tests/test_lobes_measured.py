"""``lobes`` from measured FRFs with their random error (issue 22): error models, envelope, bad input.

Statistical tolerances are set from the sampling distribution of the checked
statistic at the fixed seed's sample size (stated at each check), so that a
correct implementation passes with a wide margin and a wrong factor (sqrt 2,
averages, R) fails.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.stability import CuttingConditions, ModalModel, lobes_from_frf_draws
from bayes_rcsa.stability.measured import (
    PRIOR_REPEATS,
    MeasuredDirection,
    bendat_piersol_error,
    draw_measured_frf,
    read_measured_direction,
    repeat_covariance,
)
from bayes_rcsa.stability.modal_fit import fit_modal_model
from bayes_rcsa.stability.modal_quality import RESIDUAL_THRESHOLD, modal_fit_quality
from bayes_rcsa.stability.plots import _reduce, display_blocks
from bayes_rcsa.stability.recommend import level_limit
from bayes_rcsa.stability.zoa import zoa_lobes

F = np.arange(500.0, 3000.0, 2.5)
MX = ModalModel([1287.0], [0.02], [1.0e6])
MY = ModalModel([1340.0], [0.03], [1.3e6])
CUT = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=0.7, milling="down", feed="y")
COMMON = ["--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.7", "--milling", "down", "--feed", "y"]
REL, FLOOR, N_AVG = 0.02, 1e-8, 5  # the bench's noise model (docs/synthetic.md)


def noisy(g, rng):
    """One averaged measurement of ``g`` with the bench's noise and its expected coherence."""
    sigma = REL * np.abs(g) + FLOOR
    z = rng.standard_normal((2, g.size))
    coh = np.abs(g) ** 2 / (np.abs(g) ** 2 + N_AVG * sigma**2)
    return g + sigma * (z[0] + 1j * z[1]) / np.sqrt(2), coh


def write_frf(path, f, g, coherence=None, header=()):
    lines = ["# synthetic tool-point FRF", *[f"# {h}" for h in header],
             "frequency_hz,real,imag" + (",coherence" if coherence is not None else "")]
    for k, (a, b) in enumerate(zip(f, g)):
        row = f"{float(a)!r},{float(b.real)!r},{float(b.imag)!r}"
        lines.append(row + (f",{float(coherence[k])!r}" if coherence is not None else ""))
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def run(argv, capsys, plots: bool = False):
    """``main(argv)`` and what it printed; a lobes run writes no lobes.png unless ``plots`` (one figure test
    checks it; the numbers are in lobes.json and p_stable.npz)."""
    if argv[0] == "lobes" and not plots:
        argv = [*argv, "--no-plots"]
    status = main(argv)
    cap = capsys.readouterr()
    return status, cap


# ------------------------------------------------------------------------------------- error models
def test_coherence_draws_match_bendat_piersol_variance():
    coh = np.array([0.999, 0.99, 0.9, 0.5])
    g = np.array([1e-6 - 2e-6j, -3e-7j, 2e-8 + 1e-8j, 5e-9 + 0j])
    d = MeasuredDirection(np.arange(1.0, 5.0), g, "coherence", ["a.csv"], epsilon=bendat_piersol_error(coh, 8))
    draws = draw_measured_frf(d, 40000, np.random.default_rng(1))
    rel = draws / g - 1.0
    eps2 = (1 - coh) / (2 * 8 * coh)  # Bendat & Piersol: eps(|H|)^2 = sigma(phase)^2 = (1 - g2)/(2 n g2)
    # sample variance of 40000 normals: relative sd sqrt(2/40000) = 0.7 %; 4 % is > 5 sd
    np.testing.assert_allclose(np.var(rel.real, axis=0), eps2, rtol=0.04)  # magnitude (in phase)
    np.testing.assert_allclose(np.var(np.angle(draws / g), axis=0)[:3], eps2[:3], rtol=0.04)  # phase
    assert np.all(np.abs(np.mean(rel, axis=0)) < 5 * np.sqrt(2 * eps2 / 40000))  # unbiased (5 sd)
    # the total complex variance is the bench's sigma^2 = (1 - g2)/(n g2) |H|^2
    np.testing.assert_allclose(np.mean(np.abs(draws - g) ** 2, axis=0), 2 * eps2 * np.abs(g) ** 2, rtol=0.04)


def test_bendat_piersol_refuses_nonpositive_averages():
    with pytest.raises(Exception, match="averages"):
        bendat_piersol_error(np.ones(3), 0)


def test_repeat_shrinkage_with_two_hits_is_weighted_to_the_pooled_target():
    rng = np.random.default_rng(2)
    g = MX.frf(F)
    hits = np.stack([noisy(g, rng)[0] for _ in range(2)])
    mean, cov, raw = repeat_covariance(hits)
    np.testing.assert_allclose(mean, hits.mean(axis=0))
    tot = raw[:, 0, 0] + raw[:, 1, 1]
    # weight of the target nu0/(nu0 + R - 1) = 0.8 with R = 2: Sigma - 0.2 S is isotropic
    iso = cov - (1 / (PRIOR_REPEATS + 1)) * raw
    scale = float(np.max(np.abs(raw)))
    np.testing.assert_allclose(iso[:, 0, 1], 0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(iso[:, 0, 0], iso[:, 1, 1], rtol=1e-10, atol=1e-12 * scale)
    # the shrunk total variance scatters far less from line to line than the raw one (1 degree of freedom)
    true = (REL * np.abs(g) + FLOOR) ** 2
    spread = lambda v: np.std(np.log(v / true))  # noqa: E731
    assert spread(cov[:, 0, 0] + cov[:, 1, 1]) < 0.5 * spread(tot)


def test_many_repeats_recover_an_anisotropic_covariance():
    rng = np.random.default_rng(3)
    true = np.array([[4.0, 1.2], [1.2, 1.0]]) * 1e-18
    L = np.linalg.cholesky(true)
    z = rng.standard_normal((400, 50, 2)) @ L.T
    hits = 1e-7 + z[..., 0] + 1j * z[..., 1]
    _, cov, _ = repeat_covariance(hits)
    # nu0 = 4 against 399 degrees of freedom: 1 % pull towards the isotropic target; sampling sd of each entry
    # about sqrt(2/399) = 7 % per line, 1 % averaged over 50 lines
    np.testing.assert_allclose(cov.mean(axis=0), true, rtol=0.06, atol=0.06e-18)


def test_repeat_draws_have_the_covariance_of_the_mean():
    rng = np.random.default_rng(4)
    g = MY.frf(F[::20])
    hits = np.stack([noisy(g, rng)[0] for _ in range(3)])
    mean, cov, _ = repeat_covariance(hits)
    from bayes_rcsa.stability.measured import _chol2

    d = MeasuredDirection(F[::20], mean, "repeats", ["a", "b", "c"], chol_mean=_chol2(cov / 3))
    draws = draw_measured_frf(d, 20000, np.random.default_rng(5))
    e = np.stack([(draws - mean).real, (draws - mean).imag], axis=-1)
    emp = np.einsum("dfi,dfj->fij", e, e) / draws.shape[0]
    tot = lambda c: c[:, 0, 0] + c[:, 1, 1]  # noqa: E731
    np.testing.assert_allclose(tot(emp), tot(cov) / 3, rtol=0.05)  # sd of the total ~ 1 % at 20000 draws


def test_repeats_coverage_of_the_truth_near_nominal():
    """Mean of 3 hits +- the band of the realisations covers the noise-free FRF at about the nominal rate."""
    rng = np.random.default_rng(6)
    g = MX.frf(F)
    inside = []
    for _ in range(40):
        hits = np.stack([noisy(g, rng)[0] for _ in range(3)])
        mean, cov, _ = repeat_covariance(hits)
        from bayes_rcsa.stability.measured import _chol2

        d = MeasuredDirection(F, mean, "repeats", ["a", "b", "c"], chol_mean=_chol2(cov / 3))
        dr = draw_measured_frf(d, 400, rng)
        lo, hi = np.quantile(dr.real, [0.05, 0.95], axis=0)
        inside.append((g.real >= lo) & (g.real <= hi))
    rate = np.mean(inside)
    # nominal 0.90; a plug-in variance with few hits undercovers somewhat (Student-t with ~ nu0 + 2 dof);
    # 40 x 1000 correlated indicators: the rate is known to about +-0.02
    assert 0.80 <= rate <= 0.96, rate


def test_coherence_band_covers_the_truths_lobe_and_the_robust_point_holds():
    """Reduced form of issue 22's bench acceptance (benchmarks/lobes_measured.py, 20 campaigns in docs/stability.md).

    8 measurements of the stand-in tool (one mode per direction, the bench's noise, 5 averages), 100 realisations
    each, ZOA at 80 speeds: the truth's depth limit (noise-free FRFs) inside the 90 % band, pooled; the
    deterministic limit of the same measurement; the recommended point at P(stable) >= 0.95 against the truth.
    """
    rng = np.random.default_rng(13)
    speeds = np.linspace(6000, 20000, 80)
    gx, gy = MX.frf(F), MY.frf(F)
    truth = zoa_lobes(gx, gy, F, CUT, speeds).depth_limit_m
    ok = np.isfinite(truth)
    inside, det_inside, held = [], [], []
    for _ in range(8):
        (mx, cx), (my, cy) = noisy(gx, rng), noisy(gy, rng)
        dx = MeasuredDirection(F, mx, "coherence", ["x"], epsilon=bendat_piersol_error(cx, N_AVG))
        dy = MeasuredDirection(F, my, "coherence", ["y"], epsilon=bendat_piersol_error(cy, N_AVG))
        res = lobes_from_frf_draws(draw_measured_frf(dx, 100, rng), draw_measured_frf(dy, 100, rng), F, CUT, speeds,
                                   level=0.95)
        inside.append((res.quantiles[0.05] <= truth) & (truth <= res.quantiles[0.95]))
        det = zoa_lobes(mx, my, F, CUT, speeds).depth_limit_m
        det_inside.append(det == truth)  # the deterministic "band" is one limit
        rec = res.recommended
        held.append(rec.depth_m < zoa_lobes(gx, gy, F, CUT, np.array([rec.spindle_speed_rpm])).depth_limit_m[0])
    rate = np.mean(np.array(inside)[:, ok])
    # nominal 0.90.  Speeds of one measurement share its noise (strongly dependent), so the pooled rate of 8
    # measurements scatters by ~0.03 between seeds: 0.86-0.91 on three other seeds, 0.94 on this one.  An error
    # sqrt(2) too small gives 0.75-0.77 and fails; sqrt(2) too large gives 0.96-0.98, too close to tell here (the
    # exact factor is pinned by test_coherence_draws_match_bendat_piersol_variance); 0.97 catches 2x and more
    assert 0.80 <= rate <= 0.97, rate
    assert np.mean(np.array(det_inside)[:, ok]) < 0.01
    assert all(held)  # the robust point is stable in the truth (its limit lies 33-48 % above it on other seeds)


# ------------------------------------------------------------------------------------- files and CLI
@pytest.fixture()
def measured(tmp_path):
    """Two hits per direction with coherence and an averages header, plus clean files without coherence."""
    rng = np.random.default_rng(7)
    files = {}
    for d, m in (("x", MX), ("y", MY)):
        for k in (1, 2, 3):
            v, c = noisy(m.frf(F), rng)
            files[f"{d}{k}"] = write_frf(tmp_path / f"tip_{d}_hit{k}.csv", F, v, c, header=[f"averages = {N_AVG}"])
        v, c = noisy(m.frf(F), rng)
        files[f"{d}_noavg"] = write_frf(tmp_path / f"tip_{d}_noavg.csv", F, v, c)
        files[f"{d}_plain"] = write_frf(tmp_path / f"tip_{d}_plain.csv", F, m.frf(F))
    return files


def test_coherence_without_averages_warns_with_the_assumption_and_stays_deterministic(tmp_path, measured, capsys):
    out = tmp_path / "o"
    status, cap = run(["lobes", "--measured-x", measured["x_noavg"], "--measured-y", measured["y_noavg"], *COMMON,
                       "--speeds", "6000:20000:80", "--out", str(out), "--json"], capsys)
    assert status == 0
    # one warning per file, naming it, the assumption used and how to give the averages
    warns = [ln for ln in cap.err.splitlines() if ": warning: " in ln]
    assert len(warns) == 2 and "tip_x_noavg.csv" in warns[0] and "tip_y_noavg.csv" in warns[1], cap.err
    for w in warns:
        assert "no number of averages" in w and "assumed: no random error" in w and "--averages N" in w
    text = [w.split(": warning: ", 1)[1] for w in warns]
    doc = json.loads((out / "lobes.json").read_text())
    assert [w for w in doc["warnings"] if "no number of averages" in w] == text  # printed AND in the files
    assert [w for w in json.loads(cap.out)["warnings"] if "no number of averages" in w] == text
    summary = [ln for ln in cap.err.splitlines() if "wrote" in ln]
    assert len(summary) == 1 and "deterministic" in summary[0] and "--averages N" in summary[0]
    assert doc["n_draws"] == 1 and doc["deterministic"] and doc["uncertainty"]["deterministic"]
    assert "tip_x_noavg.csv" in doc["uncertainty"]["note"]
    assert json.loads(cap.out)["deterministic"] is True
    p = np.load(out / "p_stable.npz")["p_stable"]
    assert set(np.unique(p)) <= {0.0, 1.0}
    env = np.array(doc["robust_envelope"]["depth_limit_m"], dtype=float)
    np.testing.assert_array_equal(env, np.array(doc["depth_limit_m"]["q50"], dtype=float))


def test_no_averages_warning_when_the_number_is_known_or_not_needed(tmp_path, measured, capsys):
    """--averages on the same files, files without coherence, and --deterministic raise no such warning."""
    base = [*COMMON, "--speeds", "6000:20000:20", "--depth-points", "20", "--quiet"]
    status, cap = run(["lobes", "--measured-x", measured["x_noavg"], "--measured-y", measured["y_noavg"], *base,
                       "--averages", "5", "--draws", "20", "--out", str(tmp_path / "a")], capsys)
    assert status == 0 and ": warning: " not in cap.err, cap.err
    doc = json.loads((tmp_path / "a" / "lobes.json").read_text())
    assert doc["uncertainty"]["x"]["model"] == "coherence" and not doc["warnings"]
    status, cap = run(["lobes", "--measured-x", measured["x_plain"], "--measured-y", measured["y_plain"], *base,
                       "--out", str(tmp_path / "b")], capsys)
    assert status == 0 and ": warning: " not in cap.err, cap.err  # no coherence: nothing to assume, the note says it
    assert "no random error is known" in cap.err
    # --deterministic on files WITH coherence and averages: the measured FRFs as they are, asked for, no warning
    status, cap = run(["lobes", "--measured-x", measured["x1"], "--measured-y", measured["y1"], *base,
                       "--deterministic", "--json", "--out", str(tmp_path / "c")], capsys)
    assert status == 0 and ": warning: " not in cap.err, cap.err
    doc = json.loads((tmp_path / "c" / "lobes.json").read_text())
    assert doc["n_draws"] == 1 and doc["deterministic"] and "--deterministic" in doc["uncertainty"]["note"]
    assert not doc["warnings"] and json.loads(cap.out)["deterministic"] is True
    from bayes_rcsa.io.frf_csv import read_frf_csv

    ref = zoa_lobes(read_frf_csv(measured["x1"]).values, read_frf_csv(measured["y1"]).values, F, CUT,
                    np.linspace(6000, 20000, 20)).depth_limit_m
    np.testing.assert_allclose(np.array(doc["depth_limit_m"]["q50"], dtype=float), ref, rtol=1e-12)


def test_bundled_example_files_carry_their_averages(tmp_path, capsys):
    """The bundled tip files state the 5 averages their bench used: coherence model, no false alarm."""
    from bayes_rcsa.data import example_dir

    truth = json.loads((example_dir() / "truth.json").read_text())
    n = truth["noise"]["n_averages"]
    files = sorted(example_dir().glob("tip_*.csv"))
    assert len(files) == 8
    for f in files:
        assert f"# averages = {n}" in f.read_text(encoding="utf-8").splitlines()[:4], f
    d = read_measured_direction(str(example_dir() / "tip_x_30mm.csv"), None)
    assert d.model == "coherence" and d.averages == n and not d.notes
    # the default run on them is probabilistic and warns about nothing (tiny grid: a cheap end-to-end check)
    out = tmp_path / "o"
    status, cap = run(["lobes", "--measured-x", str(example_dir() / "tip_x_30mm.csv"), "--measured-y",
                       str(example_dir() / "tip_y_30mm.csv"), *COMMON, "--speeds", "5000:30000:8",
                       "--depth-points", "8", "--draws", "10", "--quiet", "--out", str(out)], capsys)
    assert status == 0 and ": warning: " not in cap.err, cap.err
    doc = json.loads((out / "lobes.json").read_text())
    assert not doc["deterministic"] and doc["n_draws"] == 10 and not doc["warnings"]


def test_coherence_with_averages_gives_probabilistic_lobes_and_envelope(tmp_path, measured, capsys):
    out = tmp_path / "o"
    status, cap = run(["lobes", "--measured-x", measured["x1"], "--measured-y", measured["y1"], *COMMON,
                       "--speeds", "6000:20000:120", "--draws", "200", "--confidence", "0.9", "--out", str(out),
                       "--json"], capsys)
    assert status == 0, cap.err
    doc = json.loads((out / "lobes.json").read_text())
    assert doc["n_draws"] == 200 and not doc["deterministic"] and doc["level"] == 0.9
    assert doc["uncertainty"]["x"]["model"] == "coherence" and doc["uncertainty"]["x"]["averages"] == N_AVG
    q = {k: np.array(v, dtype=float) for k, v in doc["depth_limit_m"].items()}
    env = np.array(doc["robust_envelope"]["depth_limit_m"], dtype=float)
    ok = np.isfinite(env) & np.isfinite(q["q50"])
    assert ok.sum() > 100 and np.all(env[ok] <= q["q50"][ok]) and np.any(env[ok] < q["q50"][ok])
    assert doc["robust_envelope"]["confidence"] == 0.9
    p = np.load(out / "p_stable.npz")["p_stable"]
    assert np.any((p > 0) & (p < 1))
    rec, med = doc["recommended"], doc["median_recommended"]
    assert rec["mrr_index"] <= med["mrr_index"] and doc["confidence_cost"]["depth_m"] == pytest.approx(
        med["depth_m"] - rec["depth_m"])
    assert "costs" in cap.err and "coherence" in cap.err
    assert ": warning: " not in cap.err and not doc["warnings"]  # the header gave the averages: nothing assumed


def test_envelope_is_the_level_limit_in_posterior_like_draws():
    rng = np.random.default_rng(8)
    s = rng.normal(1.0, 0.02, 60)
    gx = np.array([ModalModel([1287 * a], [0.02], [1.0e6 * a**2]).frf(F) for a in s])
    gy = np.array([ModalModel([1340 * a], [0.03], [1.3e6 * a**2]).frf(F) for a in s])
    speeds = np.linspace(6000, 20000, 90)
    res = lobes_from_frf_draws(gx, gy, F, CUT, speeds, level=0.95)
    np.testing.assert_array_equal(res.envelope, level_limit(res.depth_limit_m, 0.95))
    ok = np.isfinite(res.envelope)
    assert np.all(res.envelope[ok] <= res.quantiles[0.5][ok])
    # P(stable) just below the envelope is >= the level at every speed (the definition)
    for j in np.nonzero(ok)[0][::9]:
        assert np.mean(res.envelope[j] * (1 - 1e-9) < res.depth_limit_m[:, j]) >= 0.95
    assert res.median_recommended.mrr_index >= res.recommended.mrr_index


def test_repeated_hits_and_disagreement_warning(tmp_path, measured, capsys):
    out = tmp_path / "o"
    xs = ",".join(measured[f"x{k}"] for k in (1, 2, 3))
    ys = ",".join(measured[f"y{k}"] for k in (1, 2, 3))
    status, cap = run(["lobes", "--measured-x", xs, "--measured-y", ys, *COMMON, "--speeds", "6000:20000:60",
                       "--draws", "100", "--out", str(out)], capsys)
    assert status == 0 and "warning" not in cap.err, cap.err
    doc = json.loads((out / "lobes.json").read_text())
    u = doc["uncertainty"]["x"]
    assert u["model"] == "repeats" and u["repeats"] == 3
    assert 1 / 3 < u["repeats_to_coherence_error_ratio"] < 3  # same setup: scatter ~ the coherence's error
    # hits of another setup (a 10 % stiffer tool) are flagged, in the output and in lobes.json
    other = write_frf(tmp_path / "other.csv", F, ModalModel([1350.0], [0.02], [1.1e6]).frf(F),
                      np.full(F.size, 0.999), header=[f"averages = {N_AVG}"])
    status, cap = run(["lobes", "--measured-x", f"{measured['x1']},{other}", "--measured-y", ys, *COMMON,
                       "--speeds", "6000:20000:60", "--draws", "100", "--out", str(tmp_path / "o2"), "--json"], capsys)
    assert status == 0
    warns = [ln for ln in cap.err.splitlines() if ": warning: " in ln]
    assert len(warns) == 1 and "not be repeats of one setup" in warns[0]
    assert any("not be repeats" in w for w in json.loads(cap.out)["warnings"])
    assert any("not be repeats" in w for w in json.loads((tmp_path / "o2" / "lobes.json").read_text())["warnings"])


def test_uff58_file_with_several_records_gives_repeats(tmp_path, measured):
    from bayes_rcsa.io.frf_csv import read_frf_csv
    from bayes_rcsa.io.uff58 import write_frf_uff
    from bayes_rcsa.model.receptance import FRF

    parts = []
    for k in (1, 2, 3):
        frf = read_frf_csv(measured[f"x{k}"])
        p = tmp_path / f"hit{k}.uff"
        write_frf_uff(p, FRF(frf.frequency_hz, frf.values, None, "x"), description=f"hit {k} averages=5")
        parts.append(p.read_bytes())
    both = tmp_path / "hits.uff"
    both.write_bytes(b"".join(parts))
    d = read_measured_direction(str(both), None)
    assert d.model == "repeats" and len(d.files) == 3 and d.averages == 5
    ref = np.mean([read_frf_csv(measured[f"x{k}"]).values for k in (1, 2, 3)], axis=0)
    np.testing.assert_allclose(d.mean, ref, rtol=1e-12)


@pytest.mark.parametrize("case, fragment", [
    ("different-lines", "different frequency lines"),
    ("same-file-twice", "given twice"),
    ("copy", "same FRF as"),
    ("averages-zero", "--averages '0'"),
    ("averages-and-deterministic", "contradict"),
    ("averages-negative", "--averages '-3'"),
    ("header-averages-zero", "averages = '0'"),
    ("confidence-and-level", "differ"),
    ("one-realisation", "--draws >= 2"),
])
def test_bad_input_one_line_exit_2(tmp_path, measured, capsys, case, fragment):
    x, y = measured["x1"], measured["y1"]
    extra = []
    if case == "different-lines":
        x = f"{x}," + write_frf(tmp_path / "coarse.csv", F[::2], MX.frf(F[::2]), np.full(F[::2].size, 0.99))
    elif case == "same-file-twice":
        x = f"{x},{x}"
    elif case == "copy":
        (tmp_path / "copy.csv").write_text((tmp_path / "tip_x_hit1.csv").read_text())
        x = f"{x},{tmp_path / 'copy.csv'}"
    elif case == "averages-zero":
        extra = ["--averages", "0"]
    elif case == "averages-and-deterministic":
        extra = ["--averages", "5", "--deterministic"]
    elif case == "averages-negative":
        extra = ["--averages=-3"]
    elif case == "header-averages-zero":
        x = write_frf(tmp_path / "zero.csv", F, MX.frf(F), np.full(F.size, 0.99), header=["averages = 0"])
    elif case == "confidence-and-level":
        extra = ["--confidence", "0.9", "--level", "0.8"]
    elif case == "one-realisation":
        extra = ["--draws", "1"]
    out = tmp_path / "o"
    status, cap = run(["lobes", "--measured-x", x, "--measured-y", y, *COMMON, "--speeds", "6000:20000:40", *extra,
                       "--out", str(out)], capsys)
    lines = cap.err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and "error" in lines[0] and fragment in lines[0], cap.err
    assert not out.exists()


# ------------------------------------------------------------------------------------- SDM modal fits
def test_modal_fit_quality_names_the_band_it_misses():
    two = ModalModel([900.0, 2200.0], [0.02, 0.03], [2e6, 1.5e6])
    g = two.frf(F)
    good = fit_modal_model(F, g, max_modes=4)
    resid, bands, warns = modal_fit_quality(F, g, good, "two.csv")
    assert not warns and resid.max() < 0.01
    one = fit_modal_model(F, g, max_modes=1)
    resid, bands, warns = modal_fit_quality(F, g, one, "two.csv")
    assert len(warns) == 1 and "two.csv" in warns[0]
    worst = bands[int(np.argmax(resid))]
    assert resid.max() > RESIDUAL_THRESHOLD and worst[0] <= 2200 <= worst[1] + 130  # the missed mode's window
    import re

    runs = [(float(a), float(b)) for a, b in re.findall(r"(\d+)-(\d+) Hz", warns[0])]
    assert any(a <= 2200 <= b for a, b in runs) and all(a > F[0] for a, _ in runs)  # where, not the whole band


def test_measured_sdm_reports_modal_spread_and_poor_fit(tmp_path, measured, capsys):
    out = tmp_path / "o"
    status, cap = run(["lobes", "--measured-x", measured["x1"], "--measured-y", measured["y1"], *COMMON,
                       "--speeds", "11000:14000:6", "--draws", "6", "--method", "sdm", "--out", str(out)], capsys)
    assert status == 0, cap.err
    doc = json.loads((out / "lobes.json").read_text())
    s = doc["modal_fit_spread"]["x"]
    assert s["n_draws"] == 6 and s["draws_used"] >= 4
    f = s["natural_frequency_hz"]
    assert f["q05"][0] <= f["median"][0] <= f["q95"][0] and abs(f["median"][0] - 1287) < 5
    assert doc["modal_fit"]["fitted_to"].startswith("measured")
    assert max(doc["modal_fit"]["x"]["residual_windows"]["normalised_residual"]) < RESIDUAL_THRESHOLD
    assert "misses" not in cap.err


# ------------------------------------------------------------------------------------- figure and bench
def test_figure_decimation_keeps_cusps_and_files_keep_every_speed(tmp_path, measured, capsys):
    a = np.array([5.0, 4.0, 1.0, 4.0, 5.0, 6.0, 7.0])
    np.testing.assert_array_equal(_reduce(a, 3, "min"), [1.0, 4.0, 7.0])
    assert display_blocks(1200) == 1 and display_blocks(25001) == 21
    out = tmp_path / "o"
    status, _ = run(["lobes", "--measured-x", measured["x_plain"], "--measured-y", measured["y_plain"], *COMMON,
                     "--speeds", "6000:20000:3001", "--out", str(out)], capsys, plots=True)
    assert status == 0
    assert np.load(out / "p_stable.npz")["p_stable"].shape[0] == 3001
    assert len(json.loads((out / "lobes.json").read_text())["spindle_speed_rpm"]) == 3001
    assert (out / "lobes.png").stat().st_size > 10_000


def test_synthesize_repeats_and_averages_header(tmp_path):
    from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign
    from bayes_rcsa.synthetic.config import load_bench_config

    cfg_path = tmp_path / "bench.toml"
    cfg_path.write_text("[campaign]\nclamping_lengths = [0.030]\ndirections = ['x']\nrepeats = 2\n")
    cfg = load_bench_config(cfg_path)
    assert cfg.repeats == 2
    camp = generate_campaign(cfg, np.random.default_rng(1000))
    d = write_campaign(camp, tmp_path / "c").parent
    a, b = d / "tip_x_30mm_hit1.csv", d / "tip_x_30mm_hit2.csv"
    assert a.exists() and b.exists() and a.read_bytes() != b.read_bytes()
    assert "# averages = 5" in a.read_text()
    m = read_measured_direction(f"{a},{b}", None)
    assert m.model == "repeats" and m.averages == 5 and 1 / 3 < m.coherence_ratio < 3
    assert read_measured_direction(str(a), None).model == "coherence"
    with pytest.raises(Exception, match="repeats"):
        default_bench_config(repeats=0)
