"""A tool library's law shape as the unexplained remainder's prior (issue #43 item 6): held-out width and coverage.

A small library of one holder type (``ER32``) on the independent rotor bench (``bayes_rcsa.synthetic.rotor``):
``--combinations`` clean combinations (tool diameters 7-10 mm, contact stiffness ~ d^2 with a 10 % scatter,
growth 0.40 with a 5 % scatter: the bench's law is the parallel, linear one, u = 0), each tapped at 25, 30, 35 and
40 mm (x) and identified with ``[model] terms = ["law_shape_uncertainty"]``, so that stage 1 samples the law's
bend ``u``; ``bayes-rcsa library`` pools it.  Then ``--campaigns`` out-of-library campaigns with a slotted holder
(``slotted_holder``, the bench's default tool of 7.94 mm in the same holder type), fitted at 25 and 40 mm and held
out at 30 and 35 mm, each run twice through ``check_model``: without a library (the physics envelope, ``u``
uniform on [0, 1]) and with ``library=population.nc``.  Printed per campaign and pooled: the final model, the
prior of the law's shape, the held-out 90 % model intervals' median width (Hz) and their coverage of the noise-free
truth (mode k of the truth against mode k of the measurement: ``discrepancy_generators.mode_coverage``).

Seeds: library combination ``i`` 58010 + i, campaign ``s`` 58200 + s (fresh; a development run with the growth
at 0.45 x e^(0.1 z), which put two combinations' growth on its bound, used 58000-58003 and 58100-58104).

Run: ``OMP_NUM_THREADS=1 nice python benchmarks/library_law_shape.py --workdir /tmp/law_shape_bench
--combinations 6 --campaigns 20`` (the table in docs/discrepancy.md, "Benchmark: a tool library's law shape";
about 4 min for the library and 45 s per campaign pair on the shared machine; resumable: stage 1 is an ordinary
``bayes-rcsa library`` run kept under ``--workdir``).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from bayes_rcsa.cli.main import main as cli
from bayes_rcsa.io.toml_writer import dump_toml
from bayes_rcsa.synthetic import rotor

sys.path.insert(0, str(Path(__file__).resolve().parent))
from discrepancy_generators import FIT, Generator, frac, mode_coverage  # noqa: E402

SEED_LIBRARY = 58010
SEED_CAMPAIGN = 58200
HOLDER_TYPE = "ER32"
#: Shank diameters of the library's combinations, m (the campaigns' tool, 7.94 mm, lies inside).
DIAMETERS = (0.0070, 0.0080, 0.0090, 0.0100, 0.0075, 0.0095)
#: Median growth of the combinations' contact between 25 and 40 mm (the bench's is 0.45, its bound 0.5).
GROWTH = 0.40
#: Stage-1 sampler settings (as benchmarks/library.py).
IDENTIFY = {"method": "multi", "walkers": 24, "max_steps": 2500, "check_every": 250, "ess_min": 200,
            "predict": False, "lobes": False}


def _typed(setup: Path, terms: bool) -> Path:
    """The setup with its holder type (and, for the library, the law-shape term in ``[model]``)."""
    text = setup.read_text(encoding="utf-8").replace("\n[holder]\n", f'\n[holder]\ntype = "{HOLDER_TYPE}"\n', 1)
    if terms:
        text += '\n[model]\nterms = ["law_shape_uncertainty"]\n'
    setup.write_text(text, encoding="utf-8")
    return setup


def combination_config(i: int, rng: np.random.Generator):
    """Combination ``i``: its tool diameter, the holder's bore to match, its contact law (linear in length)."""
    base = rotor.rotor_bench_config()
    d = DIAMETERS[i % len(DIAMETERS)]
    bore = base.tool_diameter
    segments = tuple(rotor.config.HolderSegment(s.length, s.outer_diameter, d if s.inner_diameter == bore
                                                else s.inner_diameter) for s in base.holder_segments)
    scale = (d / base.tool_diameter) ** 2
    return rotor.rotor_bench_config(
        tool_diameter=d, holder_segments=segments, directions=("x",),
        k_xf=base.k_xf * scale * float(np.exp(0.1 * rng.standard_normal())),
        k_thetaM=base.k_thetaM * scale * float(np.exp(0.1 * rng.standard_normal())),
        # inside the setups' growth bound of 0.5 (a growth on the bound piles the stage-1 draws on its edge)
        growth=GROWTH * float(np.exp(0.05 * rng.standard_normal())),
        growth_thetaM=GROWTH * float(np.exp(0.05 * rng.standard_normal())))


def make_library(work: Path, n: int) -> Path:
    """Write the combinations and the manifest (once); returns the manifest."""
    manifest = work / "manifest.toml"
    if manifest.exists():
        return manifest
    rows = []
    for i in range(n):
        seed = SEED_LIBRARY + i
        rng = np.random.default_rng(seed)
        cfg = combination_config(i, rng)
        camp = rotor.generate_rotor_campaign(cfg, rng)
        name = f"c{i}_{round(cfg.tool_diameter * 1e4)}"
        _typed(rotor.write_rotor_campaign(camp, work / name, overwrite=True), terms=True)
        rows.append({"name": name, "file": f"{name}/setup.toml", "seed": i})
    manifest.write_text(dump_toml({"defaults": IDENTIFY, "setup": rows}), encoding="utf-8")
    return manifest


def fit_library(manifest: Path, out: Path) -> Path:
    if not (out / "population.nc").exists():
        code = cli(["library", str(manifest), "--out", str(out), "--workers", "2", "--quiet", "--no-plots",
                    "--max-steps", "30000"])
        if code != 0:
            raise SystemExit(f"bayes-rcsa library failed ({code})")
    return out / "population.nc"


def held_widths(res) -> list[float]:
    """Hz, the held-out modes' 90 % model interval widths."""
    return [md["model_interval"]["q95"] - md["model_interval"]["q05"]
            for m in res.report["measurements_after"] if not m["fitted"] for md in m["modes"]]


def campaigns(work: Path, population: Path, n: int) -> list[str]:
    from bayes_rcsa.workflows.model_check import check_model

    gen = Generator("rotor")
    pooled = {k: {"held": [0, 0], "width": [], "unusable": 0, "remainder": 0, "per_campaign": []}
              for k in ("envelope", "library")}
    for s in range(n):
        seed = SEED_CAMPAIGN + s
        setup, cfg = gen.campaign({"slotted_holder": True}, seed, work / "campaigns")
        path = _typed(Path(setup.path), terms=False)
        for kind, lib in (("envelope", None), ("library", population)):
            t0 = time.perf_counter()
            check = check_model(path, lengths=FIT, seed=seed, library=lib)
            res = check.computation
            r = res.report
            c = mode_coverage(gen, cfg, res)
            w = held_widths(res)
            p = pooled[kind]
            p["remainder"] += r["final_model"] == "statistical_discrepancy"
            p["per_campaign"].append(statistics.median(w) if w else float("nan"))
            if r["usable_for_prediction"]:
                p["held"][0] += c["held_model"][0]
                p["held"][1] += c["held_model"][1]
                p["width"] += w
            else:
                p["unusable"] += 1
            shape = (r.get("law_shape_prior") or {}).get("text")
            print(f"slotted_holder seed {seed} [{kind}]: final {r['final_model']}, usable {r['usable_for_prediction']}, "
                  f"law shape: {shape}; held out: covered {c['held_model'][0]}/{c['held_model'][1]}, widths "
                  f"{[round(v, 1) for v in w]} Hz ({time.perf_counter() - t0:.1f} s)", flush=True)
    rows = ["| prior of the law's shape | remainder | not usable | held out: model vs truth | held-out width, "
            "median (max) Hz |", "|---|---|---|---|---|"]
    for kind, p in pooled.items():
        wd = p["width"]
        width = f"{statistics.median(wd):.1f} ({max(wd):.1f})" if wd else "—"
        rows.append(f"| {kind} | {p['remainder']}/{n} | {p['unusable']}/{n} | {frac(*p['held'])} | {width} |")
    pairs = list(zip(pooled["envelope"]["per_campaign"], pooled["library"]["per_campaign"]))
    narrower = sum(b < 0.9 * a for a, b in pairs)
    rows.append(f"\nper campaign, median held-out width envelope -> library (Hz): "
                + ", ".join(f"{a:.1f} -> {b:.1f}" for a, b in pairs)
                + f"; narrower by more than 10 % in {narrower}/{len(pairs)}")
    return rows


def library_summary(population: Path) -> str:
    """The pooled bend for the campaigns' tool: the predictive's mean, sd and 90 % interval."""
    from bayes_rcsa.library.outputs import read_population
    from bayes_rcsa.library.predictive import law_shape_prior

    pop = read_population(population)
    prior, info, warns = law_shape_prior(pop, HOLDER_TYPE, rotor.rotor_bench_config().tool_diameter,
                                         np.random.default_rng(0))
    if prior is None:
        return f"library: {info['reason']}"
    return (f"library: {pop.names}, {info['n_combinations']} combinations; law bend at 7.94 mm: mean "
            f"{info['mean']:.3f}, sd {info['sd']:.3f}, 90 % {info['q05']:.3f}-{info['q95']:.3f} {warns}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workdir", type=Path, required=True)
    ap.add_argument("--combinations", type=int, default=4)
    ap.add_argument("--campaigns", type=int, default=5)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    work = args.workdir
    work.mkdir(parents=True, exist_ok=True)
    manifest = make_library(work / "library", args.combinations)
    population = fit_library(manifest, work / "lib")
    print(library_summary(population), flush=True)
    lib_doc = json.loads((work / "lib" / "library.json").read_text())
    for w in lib_doc.get("warnings", []):
        print(f"library warning: {w}")
    print(f"library: {time.perf_counter() - t0:.0f} s", flush=True)
    rows = campaigns(work, population, args.campaigns)
    print("\n".join(rows))
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
