"""The command line behaves the same in every command: closing summary, --json, --force, help layout, progress."""

from __future__ import annotations

import argparse
import io
import json
import time

import pytest

from bayes_rcsa.cli._common import Summary
from bayes_rcsa.cli.main import HELP_WIDTH, _run, build_parser, main
from bayes_rcsa.io.progress import Heartbeat

SIM = ["--clamping-length", "0.03", "--kx", "2e6", "--ktheta", "5e5", "--freq", "600,1200,5"]


def test_every_help_text_is_wrapped_to_the_help_width(capsys):
    parser = build_parser()
    names = list(parser._subparsers._group_actions[0].choices)
    for name in [None, *names]:
        with pytest.raises(SystemExit):
            main(["--help"] if name is None else [name, "--help"])
        text = capsys.readouterr().out
        long = [ln for ln in text.splitlines() if len(ln) > HELP_WIDTH]
        assert not long, (name, long)
        # a preformatted list stays a list (identify's method table keeps its columns)
        if name == "identify":
            assert "\n  multi          Bayesian" in text


def test_summary_is_one_stderr_line_and_json_only_on_request(example, tmp_path, capsys):
    out = tmp_path / "a.csv"
    assert main(["simulate", str(example), *SIM, "--out", str(out)]) == 0
    cap = capsys.readouterr()
    assert cap.out == ""  # nothing on stdout without --json
    assert cap.err.count("\n") == 1 and cap.err.startswith("bayes-rcsa simulate: wrote ")
    for argv in (["simulate", str(example), *SIM, "--out", str(tmp_path / "b.csv"), "--json"],
                 ["--json", "simulate", str(example), *SIM, "--out", str(tmp_path / "c.csv")]):
        assert main(argv) == 0
        cap = capsys.readouterr()
        doc = json.loads(cap.out)  # exactly one JSON document on stdout
        assert cap.out.count("\n") == 1
        assert doc["command"] == "simulate" and doc["n_lines"] == 121 and doc["warnings"] == []
        assert doc["out"].endswith(".csv") and cap.err.count("\n") == 1
    # a failure: the one error line, and with --json the error as the one JSON object
    assert main(["--json", "simulate", str(example), *SIM, "--kx", "-1", "--out", str(tmp_path / "d.csv")]) == 2
    cap = capsys.readouterr()
    assert json.loads(cap.out) == {"command": "simulate", "error": cap.err.split(": error: ", 1)[1].strip()}
    assert cap.err.count("\n") == 1 and not (tmp_path / "d.csv").exists()


def test_summary_warnings_and_status_and_commands_returning_an_int(capsys):
    args = argparse.Namespace(command="fake", json=True, json_global=False,
                              func=lambda a: Summary("done", {"x": 1}, warnings=("not converged",), status=3))
    assert _run(args) == 3
    cap = capsys.readouterr()
    assert cap.err.splitlines() == ["bayes-rcsa fake: warning: not converged", "bayes-rcsa fake: done"]
    assert json.loads(cap.out) == {"command": "fake", "x": 1, "warnings": ["not converged"]}
    # a command not converted yet prints its own lines and returns its exit status
    legacy = argparse.Namespace(command="old", json=True, json_global=False, func=lambda a: print("own") or 5)
    assert _run(legacy) == 5
    assert capsys.readouterr().out == "own\n"


def _occupied(path):
    path.mkdir(parents=True)
    (path / "earlier.txt").write_text("an earlier run\n")
    return path


def test_existing_outputs_are_refused_without_force_everywhere(example, tmp_path, capsys):
    setup = str(example)
    out = _occupied(tmp_path / "occupied")
    cases = {
        "identify": ["identify", setup, "--lengths", "0.025,0.040", "--out", str(out)],
        "predict": ["predict", setup, "--posterior", str(example.parent / "tip_x_25mm.csv"), "--out", str(out)],
        "synthesize": ["synthesize", str(tmp_path / "bench.toml"), "--out", str(out)],
        "identifiability": ["identifiability", setup, "--out", str(out)],
    }
    (tmp_path / "bench.toml").write_text('[campaign]\nclamping_lengths = [0.025]\ndirections = ["x"]\n')
    for name, argv in cases.items():
        t0 = time.monotonic()
        assert main(argv) == 2, name
        err = capsys.readouterr().err
        assert err.count("\n") == 1, (name, err)
        assert f"--out {out}: exists and is not empty; use --force" in err, (name, err)
        assert time.monotonic() - t0 < 20, name  # refused before any sampling
        assert sorted(p.name for p in out.iterdir()) == ["earlier.txt"], name
    assert "or --resume" in main_err(["identify", setup, "--out", str(out)], capsys)
    # an output file: the same rule
    f = tmp_path / "sim.csv"
    f.write_text("x\n")
    assert main(["simulate", setup, *SIM, "--out", str(f)]) == 2
    assert "use --force" in capsys.readouterr().err and f.read_text() == "x\n"
    assert main(["simulate", setup, *SIM, "--out", str(f), "--force"]) == 0
    assert f.read_text() != "x\n"
    # an empty directory is fine (and --force lets synthesize replace a full one)
    assert main(["synthesize", str(tmp_path / "bench.toml"), "--out", str(out), "--force"]) == 0
    assert (out / "setup.toml").is_file() and not (out / "earlier.txt").exists()


def test_identify_force_removes_the_earlier_runs_results(example, tmp_path, capsys):
    out = _occupied(tmp_path / "run")
    (out / "posterior.nc").write_text("posterior of an earlier Bayesian run")
    argv = ["identify", str(example), "--method", "deterministic", "--lengths", "0.025", "--no-plots", "--out", str(out)]
    assert main(argv) == 2 and "use --force" in capsys.readouterr().err
    assert main([*argv, "--force", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["method"] == "deterministic" and doc["posterior"] is None
    # the deterministic run has no posterior: the stale one is gone, the user's own file is kept
    assert sorted(p.name for p in out.iterdir()) == ["earlier.txt", "summary.json"]


def main_err(argv, capsys) -> str:
    assert main(argv) == 2
    return capsys.readouterr().err


class _Terminal(io.StringIO):
    """A text stream that says it is a terminal (the heartbeat redraws its line only there)."""

    def isatty(self):
        return True


def test_heartbeat_draws_only_for_long_jobs():
    stream = _Terminal()
    with Heartbeat("job", stream=stream, quiet_seconds=10.0):
        pass
    assert stream.getvalue() == ""  # a short job prints nothing
    stream = _Terminal()
    with Heartbeat("job", stream=stream, quiet_seconds=0.0, interval=0.01):
        time.sleep(0.1)
    text = stream.getvalue()
    assert text.startswith("\rjob ... ") and text.endswith(" done\n") and text.count("\r") >= 3
    log = io.StringIO()  # not a terminal (a redirected stderr): one plain line, no carriage return
    with Heartbeat("job", stream=log, quiet_seconds=0.0, interval=0.01):
        time.sleep(0.1)
    assert log.getvalue().startswith("job ... ") and log.getvalue().endswith(" done\n")
    assert "\r" not in log.getvalue() and log.getvalue().count("\n") == 1
    stream = _Terminal()
    with Heartbeat("job", stream=stream, quiet_seconds=0.0, enabled=False):
        time.sleep(0.02)
    assert stream.getvalue() == ""
