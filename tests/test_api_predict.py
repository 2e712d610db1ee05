"""``bayes_rcsa.workflows.{predict,design,report}``: the API results equal what the commands write, round-trip
through their files, and predict reads the setup once and posterior.nc once."""

from __future__ import annotations

import json

import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.workflows.experiment_design import Design, design_test
from bayes_rcsa.workflows.prediction import Prediction, predict
from bayes_rcsa.workflows.reporting import Report, make_report

from test_api_lobes import _count_reads
from test_params_posterior import fitted  # noqa: F401  (a small fit written to DIR/posterior.nc)


@pytest.fixture(scope="module")
def predicted(fitted, tmp_path_factory):  # noqa: F811
    setup_path, posterior, _ = fitted
    out = tmp_path_factory.mktemp("cli") / "predict"
    # --no-plots: no test reads the CLI's PNGs, and frequencies.json is the same without them; the three figures
    # were 2.1 s of the command's 2.2 s of CPU.  A prediction's plots: test_prediction_round_trip_figures_and_view.
    assert main(["predict", str(setup_path), "--posterior", str(posterior), "--lengths", "0.030,0.035",
                 "--max-draws", "30", "--quiet", "--no-plots", "--out", str(out)]) == 0
    return predict(setup_path, posterior, [0.030, 0.035], max_draws=30), out


def test_prediction_equals_the_cli_file(predicted):
    res, out = predicted
    assert isinstance(res, Prediction)
    assert res.to_dict() == json.loads((out / "frequencies.json").read_text())
    # the unconverged fixture fit: the warning is in the result and in the file
    assert any("did not converge; these intervals are not reliable" in w for w in res.warnings)
    assert res.to_dict()["warnings"] == list(res.warnings)
    assert res.summary_data() == {"n_draws": 30, "posterior_converged": False}


def test_prediction_round_trip_figures_and_view(predicted, tmp_path):
    res, _ = predicted
    res.save(tmp_path / "p", plots=False)
    assert not (tmp_path / "p" / "frf_bands.png").exists() and (tmp_path / "p" / "frf_bands.csv").is_file()
    back = Prediction.load(tmp_path / "p")
    assert back.to_dict() == res.to_dict() and back.summary_line() == res.summary_line()
    assert back.warnings == res.warnings
    figs = res.figures()
    assert set(figs) == {"frf_bands", "frf_zoom", "natural_frequencies"}
    assert all(f.axes for f in figs.values())
    html = res._repr_html_()
    dominant = [m for m in res.predictions if m["dominant"] and m["clamping_length"] == 0.030][0]
    assert f"{dominant['q50_hz']:.1f} Hz" in html and "30 mm" in html
    assert "k_xf" not in html and "q50_hz" not in html


def test_predict_reads_the_setup_once_and_posterior_nc_once(fitted, monkeypatch, tmp_path, capsys):  # noqa: F811
    setup_path, posterior, _ = fitted
    calls = _count_reads(monkeypatch)
    assert main(["predict", str(setup_path), "--posterior", str(posterior), "--lengths", "0.030", "--max-draws",
                 "20", "--no-plots", "--quiet", "--out", str(tmp_path / "p")]) == 0, capsys.readouterr().err
    assert calls == {"setup": 1, "posterior": 1}, calls


@pytest.fixture(scope="module")
def designed(fitted, tmp_path_factory):  # noqa: F811
    setup_path, posterior, _ = fitted
    out = tmp_path_factory.mktemp("cli") / "design"
    args = ["--target", "frequency@0.035", "--candidates", "0.027,0.038", "--draws", "100", "--truths", "8"]
    assert main(["design", str(setup_path), "--posterior", str(posterior), *args, "--out", str(out)]) == 0
    res = design_test(setup_path, posterior, target="frequency@0.035", candidates="0.027,0.038", draws=100, truths=8)
    return res, out


def test_design_equals_the_cli_file_and_round_trips(designed, tmp_path):
    res, out = designed
    assert isinstance(res, Design) and not res.next_cut
    assert res.to_dict() == json.loads((out / "design.json").read_text())
    assert res.best == res.to_dict()["best"]["test"] and res.summary_data()["verdict"] == res.verdict
    path = res.save(tmp_path / "d")
    assert (tmp_path / "d" / "design.png").is_file()
    back = Design.load(tmp_path / "d")
    assert back.to_dict() == res.to_dict() and back.summary_line() == res.summary_line()
    assert back.summary_data() == res.summary_data() and path == tmp_path / "d" / "design.json"
    assert set(back.figures()) == {"design"} and back.figures()["design"].axes
    html = res._repr_html_()
    assert res.verdict_text in html and "Hz" in html  # the JSON's verdict in the unit policy's words


def test_report_equals_the_cli_file_and_round_trips(fitted, designed, tmp_path):  # noqa: F811
    setup_path, posterior, _ = fitted
    (_, design_dir) = designed
    # the report draws one zoomed-FRF figure per predicted length and direction, once for the CLI's page and once
    # for the API's: a prediction of the fitted direction only, at the two lengths of `predicted`, makes a page of
    # 2 figures in 1.6 s of CPU (x and y: 4 figures, 3.0-3.8 s).  The page still embeds a folder's PNG (design.png).
    pred_dir = tmp_path / "predict"
    assert main(["predict", str(setup_path), "--posterior", str(posterior), "--lengths", "0.030,0.035",
                 "--directions", "x", "--max-draws", "30", "--quiet", "--no-plots", "--out", str(pred_dir)]) == 0
    cli_out = tmp_path / "cli.html"
    assert main(["report", str(pred_dir), str(design_dir), "--out", str(cli_out)]) == 0
    res = make_report([pred_dir, design_dir])
    assert isinstance(res, Report) and res.path is None
    path = res.save(tmp_path / "api.html", summary_md=tmp_path / "api.md")
    assert path.read_text() == cli_out.read_text() == res.html
    assert res.summary_line() == f"wrote {path} and {tmp_path / 'api.md'}"
    assert "api.html" in (tmp_path / "api.md").read_text()  # the summary links into the page
    assert Report.load(path).html == res.html
    with pytest.raises(Exception, match="exists; use --force"):
        res.save(path)
