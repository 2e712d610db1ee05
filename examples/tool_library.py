"""A tool library: fit the contact population once, then a new holder-tool combination needs one hammer tap.

A shop with many tool-holder combinations taps each one at several clamping lengths once (stage 1: an
ordinary ``identify`` per combination, run by ``bayes-rcsa batch``), pools what they share per holder type
(stage 2: the population of the contact law, with the shank diameter as covariate), and from then on a new
combination of a known holder type needs ONE tap at one clamping length: its contact law's growth with
clamping length, which one tap cannot determine, comes from the population (docs/library.md).

Steps (the same commands a user types):

1. synthesize a small library (``bayes_rcsa.synthetic.library``: ER32 collets, shrink-fit and hydraulic
   chucks, tools of 6-20 mm, laws drawn from per-type populations) and hold one combination out of its
   manifest: that is the "new" tool;
2. ``bayes-rcsa library manifest.toml --out POP``: stage 1 for every listed combination and stage 2;
3. ``bayes-rcsa identify NEW/setup.toml --library POP/population.nc --lengths 0.025 --out FIT``: one tap;
4. ``bayes-rcsa predict NEW/setup.toml --posterior FIT/posterior.nc --lengths 0.02,...,0.045``;
5. the same tap without the library (``identify --method single``: a constant contact, the literature's
   single-length transfer) for comparison, and the truth (the noise-free FE bench).

Prints the dominant tool-point frequency at 20-45 mm for both, with the truth, and returns
``{"library": {length: (q05, q50, q95)}, "single": {...}, "truth": {length: Hz}}``.

Run: ``python examples/tool_library.py [--quick]`` (``--quick`` or ``BAYES_RCSA_QUICK=1``: two combinations
per holder type and 300-step chains, 13 min measured on the shared, heavily loaded two-core machine; its
chains are not converged and its numbers only illustrate the steps.  The full run has four per type and
the benchmark's 2500-step chains).  A quick run printed (ER32, 6 mm, seed 0): one tap + library within
0.0-0.9 % of the truth at 20-45 mm with 90 % intervals covering it; the tap alone, transferred as a
constant contact, 2.3-9.8 % off.

How it is exercised: not by tests/test_examples.py -- even ``--quick`` runs ten ``identify`` fits, far beyond
the test suite's budget.  ``benchmarks/library.py`` runs the
same commands (``identify --library``, ``--no-taps``, ``--method single``, ``predict``) on every held-out
combination of its libraries, and tests/test_library_bench.py checks the generator it starts from.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path

from bayes_rcsa.cli.main import main as cli
from bayes_rcsa.io.toml_writer import dump_toml
from bayes_rcsa.synthetic.library import LibrarySpec, generate_library, library_base_config, write_library

TAP = 0.025
LENGTHS = (0.020, 0.025, 0.030, 0.035, 0.040, 0.045)


def quick_requested(argv=None) -> bool:
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK") == "1"


def _settings(quick: bool) -> dict:
    # identify options of every fit: short chains suffice for these 3-7 parameter problems (tau ~ 30 steps)
    if quick:
        return {"walkers": 16, "max_steps": 300, "check_every": 100}
    return {"walkers": 24, "max_steps": 2500, "check_every": 250, "ess_min": 200}


def _frequencies(setup: Path, posterior: Path, out: Path, truth: dict) -> dict:
    """Model 90 % interval and median (Hz) of the mode holding the true dominant frequency, per length."""
    cli(["predict", str(setup), "--posterior", str(posterior), "--out", str(out), "--quiet", "--no-plots",
         "--lengths", ",".join(repr(x) for x in LENGTHS), "--directions", "x"])
    preds = json.loads((out / "frequencies.json").read_text())["predictions"]
    res = {}
    for length in LENGTHS:
        modes = [p for p in preds if abs(p["clamping_length"] - length) < 1e-9]
        pick = next((p for p in modes if p["band_lo_hz"] <= truth[length] <= p["band_hi_hz"]),
                    next(p for p in modes if p["dominant"]))
        res[length] = (pick["q05_hz"], pick["q50_hz"], pick["q95_hz"])
    return res


def main(quick: bool | None = None, seed: int = 0, workdir=None) -> dict:
    quick = quick_requested() if quick is None else quick
    opts = _settings(quick)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(workdir or tmp)
        # 1. a library of (per_type + 1) combinations per holder type; the last ER32 one is the new tool
        per_type = 2 if quick else 4
        spec = LibrarySpec(per_type=per_type + 1, identify={**opts, "seed": seed})
        base = library_base_config(frequency_step=8.0) if quick else library_base_config()
        library = generate_library(spec, base, seed=seed)
        lib_dir = root / "library"
        write_library(library, lib_dir)
        new = library.combinations[per_type]  # ER32 comes first: index per_type is its last combination
        manifest = library.manifest()
        manifest["setup"] = [s for s in manifest["setup"] if s["name"] != new.name]
        (lib_dir / "manifest.toml").write_text(dump_toml(manifest), encoding="utf-8")
        setup = lib_dir / new.name / "setup.toml"
        truth = {t["clamping_length"]: t["dominant_frequency_hz"] for t in new.campaign.truth["tool_point_frequencies"]}
        print(f"library: {len(manifest['setup'])} combinations of {', '.join(spec.holder_types)}; new tool: "
              f"{new.name} ({new.holder_type}, {new.diameter * 1e3:g} mm), one tap at {TAP * 1e3:g} mm")

        # 2. stage 1 + stage 2
        pop = root / "population"
        cli(["library", str(lib_dir / "manifest.toml"), "--out", str(pop), "--workers", "2", "--quiet"])

        # 3.-4. one tap with the population as prior, predicted at every length
        argv = ["--lengths", repr(TAP), "--no-plots", "--quiet", "--seed", str(seed),
                *(f"--{k.replace('_', '-')}={v}" for k, v in opts.items())]
        cli(["identify", str(setup), "--library", str(pop / "population.nc"), "--out", str(root / "fit"), *argv])
        with_library = _frequencies(setup, root / "fit" / "posterior.nc", root / "pred", truth)

        # 5. the same tap without the library: a constant contact
        cli(["identify", str(setup), "--method", "single", "--out", str(root / "single"), *argv])
        single = _frequencies(setup, root / "single" / "posterior.nc", root / "pred_single", truth)

    print(f"\n{'length':>7} {'truth':>8} | {'one tap + library (90 %)':>30} {'err':>6} | {'one tap alone':>13} {'err':>6}")
    for length in LENGTHS:
        lo, mid, hi = with_library[length]
        s = single[length][1]
        t = truth[length]
        mark = "tap" if abs(length - TAP) < 1e-9 else ""
        print(f"{length * 1e3:5.0f}mm {t:8.1f} | {mid:8.1f} [{lo:8.1f}, {hi:8.1f}] Hz {100 * (mid / t - 1):+5.1f}% | "
              f"{s:9.1f} Hz {100 * (s / t - 1):+5.1f}% {mark}")
    return {"library": with_library, "single": single, "truth": truth}


if __name__ == "__main__":
    main()
