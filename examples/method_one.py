"""Method I: identify one contact from several tools of equal shank diameter and different lengths.

With a single clamping length, tools of the same shank diameter share the
tool-holder contact (same collet, same clamped shank), so hammer tests on
several tool lengths constrain one contact ``K`` the way several clamping
lengths do in Method II -- with no growth law needed.  This script

1. makes one synthetic campaign per tool (the bench's end mill with its
   fluted section unchanged and its shank shortened or lengthened; all
   clamped 25 mm deep) and merges them into one setup with ``[tools.NAME]``
   tables and ``tool = NAME`` in every ``[[measurement]]`` (docs/data-formats.md);
2. identifies the shared contact from three tools (``method = "multi"`` with
   one clamping length is Method I);
3. predicts the dominant natural frequency of a fourth, held-out tool and
   compares it with its measurement.

Run::

    python examples/method_one.py            # converged fit, about a minute
    python examples/method_one.py --quick    # reduced run (coarse lines, short chains, X only)

(``BAYES_RCSA_QUICK=1`` also selects the reduced run.)
"""

from __future__ import annotations

import dataclasses
import os
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

from bayes_rcsa.inference import IdentificationOptions, SamplerSettings, build_problem_from_setup, identify
from bayes_rcsa.io import dump_toml, load_setup
from bayes_rcsa.model import Configuration
from bayes_rcsa.posterior import PredictionTarget, draws_from_result, parameter_identifiability, predict
from bayes_rcsa.posterior.identifiability import fmt_contraction
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

CLAMPING = 0.025  # m
#: tool name -> total length (m); the fluted 30 mm are the same for all, the shank length differs
TOOLS = {"em_90": 0.090, "em_102": 0.1016, "em_115": 0.115, "em_127": 0.127}
HELD_OUT = "em_115"


def quick_requested(argv=None) -> bool:
    """``--quick`` on the command line or ``BAYES_RCSA_QUICK=1`` in the environment."""
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK", "") not in ("", "0")


def tool_campaign(total_length: float, directions, step: float, seed: int):
    """Bench configuration and campaign of one tool length (same contact, same spindle)."""
    base = default_bench_config()
    flute, shank = base.tool_segments
    config = default_bench_config(
        clamping_lengths=(CLAMPING,), directions=directions, frequency_step=step, tool_total_length=total_length,
        tool_segments=(flute, dataclasses.replace(shank, length=total_length - flute.length)))
    return generate_campaign(config, np.random.default_rng(seed))


def merged_setup(root: Path, directions, step: float, seed: int) -> Path:
    """One setup with a ``[tools.NAME]`` table per tool and every tool's measurements."""
    doc = None
    measurements = []
    for i, (name, length) in enumerate(TOOLS.items()):
        setup_path = write_campaign(tool_campaign(length, directions, step, seed + i), root / name)
        d = tomllib.loads(setup_path.read_text())
        if doc is None:
            # spindle files, holder, materials and contact priors of the first campaign
            doc = {k: v for k, v in d.items() if k not in ("tool", "measurement")}
            doc["spindle"] = {k: f"{name}/{v}" for k, v in d["spindle"].items()}
            doc["tools"] = {}
        doc["tools"][name] = d["tool"]
        for m in d["measurement"]:
            measurements.append({**m, "file": f"{name}/{m['file']}", "tool": name})
    doc["measurement"] = measurements
    doc["name"] = "Method I: four end mills of 7.94 mm shank in one ER32 collet"
    path = root / "setup.toml"
    path.write_text(dump_toml(doc))
    return path


def main(quick: bool | None = None, seed: int = 0) -> dict:
    """Identify from three tools, predict the fourth.

    Returns
    -------
    dict with ``frequencies`` ({tool: (measured, q05, q50, q95) Hz}, X direction) and
    ``identifiability`` (:func:`bayes_rcsa.posterior.parameter_identifiability` of the fit).
    """
    quick = quick_requested() if quick is None else quick
    directions = ("x",) if quick else ("x", "y")
    with tempfile.TemporaryDirectory() as tmp:
        setup = load_setup(merged_setup(Path(tmp), directions, 8.0 if quick else 2.0, seed))
        fit_tools = [t for t in TOOLS if t != HELD_OUT]
        keep = [m for m in setup.measurements if m.tool in fit_tools]
        fit_setup = dataclasses.replace(setup, measurements=tuple(keep))
        options = IdentificationOptions.from_setup(fit_setup.extra, method="multi")
        settings = (SamplerSettings(max_steps=80, check_every=80, progress=False) if quick
                    else SamplerSettings(progress=False))
        result = identify(build_problem_from_setup(fit_setup, options), seed=seed, settings=settings)
        p = result.summary["parameters"]
        print(f"Method I from tools {', '.join(fit_tools)} at {CLAMPING * 1e3:g} mm "
              f"(converged: {result.summary['converged']}):")
        ident = parameter_identifiability(result.flat_theta, result.problem.priors)
        for name in ("k_xf", "k_thetaM"):
            e = ident[name]
            print(f"  {name:9s} median {p[name]['q50']:.4g} [{p[name]['q05']:.4g}, {p[name]['q95']:.4g}] "
                  f"{'N/m' if name == 'k_xf' else 'N m/rad'}: {e['verdict']} ({fmt_contraction(e['contraction'])}, "
                  f"marginal / conditional width {e['width_ratio']:.2g})")
        print("  (tools of different length weigh the two stiffnesses differently, so one clamping length separates "
              "them)\n")
        draws = draws_from_result(result).subset(300, np.random.default_rng(seed))
        model = setup.model()
        freqs = {}
        rows = []
        for m in setup.measurements:
            target = PredictionTarget(Configuration(CLAMPING, m.direction, m.tool), m.frf.frequency_hz, m.frf)
            mode = next(md for md in predict(draws, model, [target]).modes if md.dominant)
            q = mode.natural_frequency_hz
            if m.direction == "x":
                freqs[m.tool] = (mode.measured_hz, q["q05"], q["q50"], q["q95"])
            rows.append((m.tool, TOOLS[m.tool], m.direction, mode.measured_hz, q,
                         "held out" if m.tool == HELD_OUT else "fitted"))
        print(f"{'tool':8s} {'length (mm)':>11s} {'dir':>3s} {'measured (Hz)':>13s} "
              f"{'predicted median [90 %] (Hz)':>30s} {'error (%)':>9s}")
        for tool, length, d, meas, q, tag in rows:
            print(f"{tool:8s} {length * 1e3:11.1f} {d:>3s} {meas:13.1f} "
                  f"{q['q50']:10.1f} [{q['q05']:.1f}, {q['q95']:.1f}] {100 * (q['q50'] - meas) / meas:+9.2f}  {tag}")
    return {"frequencies": freqs, "identifiability": ident}


if __name__ == "__main__":
    main()
