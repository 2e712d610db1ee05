"""A finished figure pickles and unpickles, in this process and in a fresh one (users pickle figures to ship them
from worker processes, e.g. a Dask batch, or to cache them in notebooks)."""

from __future__ import annotations

import pickle
import subprocess
import sys

import numpy as np

from bayes_rcsa.io.figures import finish, new_figure


def _figure():
    fig = new_figure(4.0, 3.0)
    ax = fig.add_subplot(111)
    ax.plot(np.linspace(0.2942, 0.2946, 5), np.arange(5.0))
    ax.set_xlabel("clamping length (m)")
    finish(fig)
    return fig


def test_finished_figure_pickles_with_its_tick_formatter():
    fig = _figure()
    labels = [t.get_text() for t in fig.axes[0].get_xticklabels()]
    assert labels == ["0.2940", "0.2942", "0.2944", "0.2946", "0.2948"]  # each tick its own number, no offset
    clone = pickle.loads(pickle.dumps(fig))
    formatter = clone.axes[0].xaxis.get_major_formatter()
    assert getattr(formatter, "plain", False)  # still the package's formatter, not a default
    formatter.set_locs(fig.axes[0].get_xticks())
    assert [formatter(v) for v in fig.axes[0].get_xticks()] == labels


def test_finished_figure_unpickles_in_a_fresh_process(tmp_path):
    path = tmp_path / "fig.pickle"
    path.write_bytes(pickle.dumps(_figure()))
    code = ("import pickle, sys; fig = pickle.load(open(sys.argv[1], 'rb')); "
            "print(type(fig.axes[0].xaxis.get_major_formatter()).__name__)")
    out = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "PlainFormatter"
