"""Tool-tip natural frequencies with credible intervals at any clamping length: a CSV table and a plot.

A shop sets tools at whatever clamping length the job needs, not only at the
lengths that were hammer-tested.  From a Method II posterior (25 and 40 mm
of the bundled example campaign, or ``--posterior FILE`` from
``bayes-rcsa identify``) this script predicts the dominant natural frequency
in X and Y at every 2.5 mm between 25 and 40 mm and writes

* ``natural_frequencies.csv``: one row per (clamping length, direction) with
  the 5/25/50/75/95 % posterior quantiles of the model's natural frequency
  (the noise-free tool-point FRF) and the 90 % posterior-predictive interval
  of the peak of a *new, noisy* measurement, plus the measurement where one
  exists;
* ``natural_frequencies.png``: the median and both bands against clamping
  length, measurements as points.

Run::

    python examples/credible_interval_report.py [--posterior FILE] [--out DIR]
    python examples/credible_interval_report.py --quick      # short chains (not converged)

(``BAYES_RCSA_QUICK=1`` also selects the reduced run; the default output
directory is ``credible_interval_report/`` in the current directory.)
"""

from __future__ import annotations

import csv
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from bayes_rcsa.data import example_setup
from bayes_rcsa.inference import IdentificationOptions, SamplerSettings, build_problem_from_setup, identify, write_outputs
from bayes_rcsa.io import load_setup
from bayes_rcsa.posterior import run_prediction

LENGTHS = tuple(np.round(np.arange(0.025, 0.04001, 0.0025), 6))  # m, inside the setup's clamping range
COLUMNS = ["clamping_length_mm", "direction", "q05_hz", "q25_hz", "q50_hz", "q75_hz", "q95_hz",
           "predictive_q05_hz", "predictive_q95_hz", "measured_hz"]


def quick_requested(argv=None) -> bool:
    """``--quick`` on the command line or ``BAYES_RCSA_QUICK=1`` in the environment."""
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK", "") not in ("", "0")


def _option(name: str):
    argv = sys.argv[1:]
    return Path(argv[argv.index(name) + 1]) if name in argv[:-1] else None


def identify_example(out_dir: Path, quick: bool, seed: int) -> Path:
    """Method II fit of the bundled example from 25 and 40 mm; returns the posterior.nc path."""
    setup = load_setup(example_setup())
    options = IdentificationOptions.from_setup(setup.extra, method="multi", lengths=(0.025, 0.040))
    settings = SamplerSettings(max_steps=80, check_every=80, progress=False) if quick else SamplerSettings(progress=False)
    write_outputs(identify(build_problem_from_setup(setup, options), seed=seed, settings=settings), out_dir, plots=False)
    return out_dir / "posterior.nc"


def table(setup, posterior: Path, seed: int) -> list[dict]:
    """One row per (clamping length, direction): quantiles of the dominant natural frequency (Hz)."""
    run = run_prediction(setup, posterior, LENGTHS, seed=seed)
    rows = []
    for mode in run.prediction.modes:
        if not mode.dominant:
            continue
        q, pp = mode.natural_frequency_hz, mode.predictive_peak_hz or {}
        rows.append({"clamping_length_mm": round(mode.configuration.clamping_length * 1e3, 3),
                     "direction": mode.configuration.direction,
                     **{f"{k}_hz": q[k] for k in ("q05", "q25", "q50", "q75", "q95")},
                     "predictive_q05_hz": pp.get("q05"), "predictive_q95_hz": pp.get("q95"),
                     "measured_hz": mode.measured_hz if mode.has_measurement else None})
    rows.sort(key=lambda r: (r["direction"], r["clamping_length_mm"]))
    return rows


def write_csv(rows: list[dict], path: Path) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows({k: ("" if v is None else v) for k, v in r.items()} for r in rows)


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, d in zip(axes, ("x", "y")):
        r = [row for row in rows if row["direction"] == d]
        if not r:
            continue
        length = np.array([row["clamping_length_mm"] for row in r])
        col = lambda k: np.array([np.nan if row[k] is None else row[k] for row in r], dtype=float)  # noqa: E731
        ax.fill_between(length, col("predictive_q05_hz"), col("predictive_q95_hz"), color="C1", alpha=0.25,
                        label="90 % predictive (new noisy measurement)")
        ax.fill_between(length, col("q05_hz"), col("q95_hz"), color="C0", alpha=0.5, label="90 % credible (model)")
        ax.plot(length, col("q50_hz"), "C0-", label="median")
        ax.plot(length, col("measured_hz"), "ko", label="measured")
        ax.set_title(f"direction {d}")
        ax.set_xlabel("clamping length (mm)")
    axes[0].set_ylabel("dominant natural frequency (Hz)")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(quick: bool | None = None, posterior: Path | None = None, out: Path | None = None, seed: int = 0) -> list[dict]:
    """Write the table and the plot; returns the table rows."""
    quick = quick_requested() if quick is None else quick
    posterior = posterior or _option("--posterior")
    out = Path(out or _option("--out") or "credible_interval_report")
    out.mkdir(parents=True, exist_ok=True)
    setup = load_setup(example_setup())
    with tempfile.TemporaryDirectory() as tmp:
        rows = table(setup, Path(posterior) if posterior else identify_example(Path(tmp), quick, seed), seed)
    write_csv(rows, out / "natural_frequencies.csv")
    plot(rows, out / "natural_frequencies.png")
    print(f"{'length (mm)':>11s} {'dir':>3s} {'median (Hz)':>11s} {'90 % credible (Hz)':>20s} "
          f"{'90 % predictive (Hz)':>20s} {'measured (Hz)':>13s}")
    for r in rows:
        pp = "" if r["predictive_q05_hz"] is None else f"[{r['predictive_q05_hz']:.1f}, {r['predictive_q95_hz']:.1f}]"
        meas = "" if r["measured_hz"] is None else f"{r['measured_hz']:.1f}"
        print(f"{r['clamping_length_mm']:11.1f} {r['direction']:>3s} {r['q50_hz']:11.1f} "
              f"{'[%.1f, %.1f]' % (r['q05_hz'], r['q95_hz']):>20s} {pp:>20s} {meas:>13s}")
    print(f"wrote {out / 'natural_frequencies.csv'} and {out / 'natural_frequencies.png'}")
    return rows


if __name__ == "__main__":
    main()
