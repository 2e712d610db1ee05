"""Progress output stays out of logs (#45 item 6): redrawn with carriage returns on a terminal only; on a file
or pipe nothing but one final line."""

from __future__ import annotations

import io
import sys

import numpy as np

from bayes_rcsa.inference.sampler import SamplerSettings, run_ensemble


class _Gaussian:
    """A 2-D standard normal: sampling it costs nothing next to the progress output under test."""

    ndim = 2

    def __call__(self, theta):
        return -0.5 * np.sum(np.asarray(theta) ** 2, axis=1)

    def check_inside(self, theta, what):
        return None


def _sample(stream, monkeypatch) -> str:
    monkeypatch.setattr(sys, "stderr", stream)
    settings = SamplerSettings(n_walkers=8, max_steps=400, check_every=100, ess_min=1e12, checkpoint_interval=1e9)
    rng = np.random.default_rng(0)
    run_ensemble(_Gaussian(), settings, initial=rng.normal(size=(8, 2)), rng=rng)
    return stream.getvalue()


def test_sampling_progress_in_a_log_file_is_one_final_line(monkeypatch):
    text = _sample(io.StringIO(), monkeypatch)  # not a terminal, like stderr redirected to a file
    lines = [line for line in text.splitlines() if line.startswith("sampling")]
    assert "\r" not in text
    assert len(lines) == 1 and lines[0].startswith("sampling [") and "400/400" in lines[0], text


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_sampling_progress_on_a_terminal_is_redrawn_in_place(monkeypatch):
    text = _sample(_Terminal(), monkeypatch)
    assert text.count("\r") >= 4 and text.endswith("\n") and text.count("\n") == 1


def test_every_progress_helper_writes_one_plain_line_to_a_file():
    """The other progress helpers (predict/lobes/spindle ...): one line, no carriage return, in a log."""
    from bayes_rcsa.io.progress import Heartbeat
    from bayes_rcsa.stability.progress import ProgressBar

    log = io.StringIO()
    with Heartbeat("predict: 10 draws", stream=log, quiet_seconds=0.0, interval=0.001):
        pass
    bar = ProgressBar("lobes", stream=log, quiet_seconds=0.0, interval=0.0)
    for k in range(20):
        bar(k / 20)
    bar.close()
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and len(lines) == 2, lines
    assert lines[0].startswith("predict: 10 draws ...") and lines[1].startswith("lobes [")
