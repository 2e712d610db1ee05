"""The reference paper's experiment, with credible intervals, on a synthetic campaign.

Zhao et al., "A Novel Method for Identifying Tool-Holder Interface Dynamics
Based on Receptance Coupling", *Machines* 2024, 12, 911, identify the
tool-holder contact of a collet chuck from tool-point hammer tests at two
clamping lengths (25 and 40 mm, their "new approach", here Method II) and
compare it with the literature method (one clamping length, the identified
contact transferred unchanged to the other lengths).  This script repeats
that study on a campaign from the synthetic finite-element bench built like
their set-up (paper Table 1: clamping lengths 25, 30, 35 and 40 mm, X and Y)
and prints the analogues of the paper's tables:

* Table 3 -- contact stiffness of every parameter set: Method II (25 + 40 mm,
  Bayesian), the literature method from 25 mm alone (set 1) and from 40 mm
  alone (set 2), each deterministic (the paper's fit) and Bayesian, with 90 %
  credible intervals;
* Tables 4-6 -- predicted dominant natural frequency of each set at every
  clamping length and direction against the measurement, with the error;
* Table 7 -- the errors of Tables 4-6 side by side;
* Table 9 -- for the paper's cutting cases a-d (Table 2: 4 flutes,
  Kt = 790 MPa, Kr = 230 MPa, feed in Y), the deviation of the lobes of each
  set from the lobes of the measured FRFs: the share of (speed, depth) grid
  points whose stable/unstable verdict differs
  (:func:`bayes_rcsa.stability.limits_disagreement`), for the Bayesian sets
  as the median and 90 % interval over posterior draws (probabilistic lobes).
  Lobes by the zero-order approximation (the paper used the semi-discretisation
  method; ``bayes_rcsa.stability`` has both, see docs/stability.md), on a grid
  of 5000-30000 rpm and 60 depths up to twice the deepest measured-FRF limit
  (the paper used the 75 points of its cutting tests per case).

Run::

    python examples/paper_study.py            # converged fits, about 6 minutes on two shared cores
    python examples/paper_study.py --quick    # reduced run (coarse lines, short chains), ~30 s

(``BAYES_RCSA_QUICK=1`` in the environment also selects the reduced run.)
The quick run's chains are not converged; its numbers show the shape of the
study, not its final digits.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from bayes_rcsa.inference import IdentificationOptions, SamplerSettings, build_problem_from_setup, identify
from bayes_rcsa.io import load_setup
from bayes_rcsa.model import Configuration
from bayes_rcsa.posterior import draws_from_result, predictive_frf
from bayes_rcsa.stability import CuttingConditions, limits_disagreement, zoa_lobes
from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

LENGTHS = (0.025, 0.030, 0.035, 0.040)  # m, paper Table 4
#: Paper Table 2: case -> (clamping length m, radial immersion)
CASES = {"a": (0.025, 0.70), "b": (0.030, 0.95), "c": (0.035, 0.70), "d": (0.040, 0.95)}
#: (label, method, lengths): the parameter sets of paper Table 3, each also fitted by Bayes
SETS = (
    ("Method II 25+40 mm (Bayes)", "multi", (0.025, 0.040)),
    ("set 1: 25 mm (Bayes)", "single", (0.025,)),
    ("set 1: 25 mm (deterministic)", "deterministic", (0.025,)),
    ("set 2: 40 mm (Bayes)", "single", (0.040,)),
    ("set 2: 40 mm (deterministic)", "deterministic", (0.040,)),
)


def quick_requested(argv=None) -> bool:
    """``--quick`` on the command line or ``BAYES_RCSA_QUICK=1`` in the environment."""
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK", "") not in ("", "0")


def _table(head, rows) -> None:
    widths = [max(len(str(r[i])) for r in [head] + rows) for i in range(len(head))]
    for r in [head, ["-" * w for w in widths]] + rows:
        print("  ".join(str(c).ljust(w) for c, w in zip(r, widths)))
    print()


def _interval(q, unit_scale=1.0, fmt="{:.3g}") -> str:
    lo, mid, hi = (unit_scale * v for v in q)
    return fmt.format(mid) if lo == hi else f"{fmt.format(mid)} [{fmt.format(lo)}, {fmt.format(hi)}]"


def identify_sets(setup, quick: bool, seed: int) -> dict:
    """Run every parameter set of :data:`SETS`; returns ``{label: IdentificationResult}``."""
    settings = (SamplerSettings(max_steps=80, check_every=80, progress=False) if quick
                else SamplerSettings(progress=False))
    out = {}
    for label, method, lengths in SETS:
        options = IdentificationOptions.from_setup(setup.extra, method=method, lengths=lengths)
        out[label] = identify(build_problem_from_setup(setup, options), seed=seed, settings=settings)
    return out


def table3(results: dict) -> dict:
    """Contact stiffness of each set at every clamping length: {label: {length: (k_xf q, k_thetaM q)}}."""
    print("Table 3 analogue: contact stiffness, median [90 % credible interval]")
    head = ["parameter set", "length (mm)", "k_xf (1e6 N/m)", "k_thetaM (1e5 N m/rad)"]
    rows, out = [], {}
    for label, result in results.items():
        # Method II: the growth law gives a contact per length; single-length sets have one constant contact
        lengths = LENGTHS if result.problem.method == "multi" else (result.problem.growth.l_a,)
        kx, kt = draws_from_result(result).contact(lengths)[:2]
        out[label] = {}
        for j, length in enumerate(lengths):
            qx = np.quantile(kx[:, j], [0.05, 0.5, 0.95])
            qt = np.quantile(kt[:, j], [0.05, 0.5, 0.95])
            out[label][float(length)] = (qx, qt)
            rows.append([label, f"{length * 1e3:g}", _interval(qx, 1e-6, "{:.4g}"), _interval(qt, 1e-5)])
    _table(head, rows)
    return out


def frequency_tables(results: dict) -> dict:
    """Tables 4-7: predicted vs measured dominant natural frequency; returns {label: {(length, dir): error %}}."""
    errors = {}
    for n, (label, result) in zip((4, 5, 5, 6, 6), results.items()):
        print(f"Table {n} analogue ({label}): dominant natural frequency, median [90 %] vs measured")
        rows, errors[label] = [], {}
        for e in result.summary["natural_frequencies"]:
            err = 100.0 * (e["q50_hz"] - e["measured_hz"]) / e["measured_hz"]
            errors[label][(round(e["clamping_length"], 6), e["direction"])] = err
            rows.append([f"{e['clamping_length'] * 1e3:g}", e["direction"], f"{e['measured_hz']:.1f}",
                         _interval((e["q05_hz"], e["q50_hz"], e["q95_hz"]), fmt="{:.1f}"), f"{err:+.2f}",
                         "fitted" if e["used_in_fit"] else "transferred"])
        _table(["length (mm)", "dir", "measured (Hz)", "predicted (Hz)", "error (%)", ""], rows)
    print("Table 7 analogue: |error| of the median natural frequency (%)")
    keys = sorted(next(iter(errors.values())))
    _table(["length (mm)", "dir"] + list(errors),
           [[f"{k[0] * 1e3:g}", k[1]] + [f"{abs(errors[s][k]):.2f}" for s in errors] for k in keys])
    return errors


def table9(setup, results: dict, quick: bool, seed: int) -> dict:
    """Lobe deviation of every set from the measured-FRF lobes for the paper's cases a-d (Table 9)."""
    rng = np.random.default_rng(seed)
    model = setup.model()
    speeds = np.linspace(5000.0, 30000.0, 120 if quick else 600)  # rpm
    measured = {(round(m.clamping_length, 6), m.direction): m.frf for m in setup.measurements}
    out = {}
    head = ["case (length, immersion)"] + list(results)
    rows = []
    for case, (length, immersion) in CASES.items():
        cut = CuttingConditions(kt=790e6, kr=230e6, flutes=4, radial_immersion=immersion, feed="y")
        fx, fy = measured[(length, "x")], measured[(length, "y")]
        f = fx.frequency_hz
        ref = zoa_lobes(fx.values, fy.values, f, cut, speeds).depth_limit_m
        finite = ref[np.isfinite(ref)]
        depths = np.linspace(0.0, 2.0 * float(np.max(finite)) if finite.size else 1e-3, 60)  # m, covers the lobes
        row, out[case] = [f"{case} ({length * 1e3:g} mm, {100 * immersion:g} %)"], {}
        for label, result in results.items():
            draws = draws_from_result(result).subset(20 if quick else 200, rng)
            hx = predictive_frf(draws, model, Configuration(length, "x"), f)
            hy = predictive_frf(draws, model, Configuration(length, "y"), f)
            lim = zoa_lobes(hx, hy, f, cut, speeds).depth_limit_m  # (n_draws, n_speed)
            dev = np.array([100.0 * limits_disagreement(l, ref, depths) for l in lim])
            q = np.quantile(dev, [0.05, 0.5, 0.95])
            out[case][label] = q
            row.append(_interval(q, fmt="{:.1f}"))
        rows.append(row)
    print("Table 9 analogue: deviation (%) of the predicted lobes from the lobes of the measured FRFs "
          "(ZOA, share of speed x depth grid points with a different verdict), median [90 %] over draws")
    _table(head, rows)
    return out


def main(quick: bool | None = None, seed: int = 0) -> dict:
    """Run the study; returns the numbers behind the printed tables.

    Returns
    -------
    dict with ``stiffness`` (Table 3), ``errors`` ({set: {(length m, dir): error %}}, Tables 4-7) and
    ``deviation`` ({case: {set: (q05, q50, q95) %}}, Table 9).
    """
    quick = quick_requested() if quick is None else quick
    # Paper Table 1 set-up; the quick run uses 8 Hz lines instead of 2 Hz (peaks are ~50 Hz wide).
    config = default_bench_config(clamping_lengths=LENGTHS, directions=("x", "y"),
                                  frequency_step=8.0 if quick else 2.0)
    with tempfile.TemporaryDirectory() as tmp:
        setup = load_setup(write_campaign(generate_campaign(config, np.random.default_rng(seed)), Path(tmp) / "campaign"))
        results = identify_sets(setup, quick, seed)
        stiffness = table3(results)
        errors = frequency_tables(results)
        deviation = table9(setup, results, quick, seed)
    return {"stiffness": stiffness, "errors": errors, "deviation": deviation}


if __name__ == "__main__":
    main()
