"""Tool-library transfer (issue #20): the acceptance tables for docs/library.md, "Benchmarks".

Run: ``OMP_NUM_THREADS=1 nice python benchmarks/library.py --workdir /tmp/library_bench [--write-docs]``
(resumable: every stage-1 fit is an ordinary ``bayes-rcsa batch`` / ``identify`` run kept under
``--workdir``; about 30-60 min on the 2 shared cores).  ``--part stage1|loo|outliers`` runs one part (the
tables are written once both the loo and the outliers part have results in ``--workdir``).  Progress: one line per campaign / held-out case on stdout.

Libraries (seeds 5000, 5001, ...; development used seeds < 100)
---------------------------------------------------------------
``bayes_rcsa.synthetic.library`` with its three built-in holder types (ER32, shrink_fit, hydraulic), tools
of 6-20 mm, hammer tests at 25, 35 and 45 mm (x), truth at 20-45 mm.  The first
``max(--loo, --outliers)`` libraries have 12 combinations (4 per type): the first ``--loo`` of them serve the
transfer tables, and ``--outliers`` campaigns per kind take library ``i`` of them and make one combination
special: its contact 3x softer, or a hidden ``tip_mass`` (2 g).  ``--clean`` libraries in all (those included,
the rest of 6 combinations, to keep stage 1 affordable) give the false-flag count.  A
combination's data do not change when another is made special, so only the special one is fitted again.

Stage 1: ``bayes-rcsa batch`` with the manifest's settings (:data:`IDENTIFY`): 24 walkers, at most 2500
steps, convergence checked every 250 steps against a bulk ESS of 200.  Their R-hat, tau and ESS are
summarised in the first table.

Tables
------
1. One tap suffices: leave each combination of the LOO libraries out, fit the population on the rest,
   identify the left-out one from ONE tap (25 mm) with the population as prior, predict the dominant
   tool-point frequency at 20, 30, 35, 40, 45 mm: median absolute error against the truth (noise-free
   FE, the project's natural-frequency rule), coverage of the truth by the 90 % model interval
   (Clopper-Pearson 95 %), median interval width; the same for the single-length baseline
   (``identify --method single --lengths 0.025``, no library) and for zero taps (the population
   predictive for the holder type and diameter).
2. Outliers: flagged special combinations per kind, false flags in clean libraries; with ``--big-type N``
   the same in ``--big-campaigns`` single-type (ER32) libraries of N combinations (seeds 5100, ...), which
   shows how the leave-one-out check's power grows with the number of combinations per holder type.

The run in docs/library.md: ``--clean 10 --outliers 5 --loo 3 --big-type 8 --big-campaigns 3`` (stage 1 of
the 90 + 10 + 24 fits about 1.5 h of wall time on the shared machine; the outlier and transfer parts of model
version 2 then 15 and 6 min with stage 2's Gaussian surrogate; 23 and 26 min with the exact two-stage
re-weighting and its longer chain, the default since 2026-11-26).
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from bayes_rcsa.cli.main import main as cli
from bayes_rcsa.synthetic.library import LibrarySpec, Special, generate_library, write_library

sys.path.insert(0, str(Path(__file__).resolve().parent))
from discrepancy import clopper_pearson  # noqa: E402  (benchmarks share one Clopper-Pearson interval)

DOCS = Path(__file__).resolve().parent.parent / "docs" / "library.md"
SEED0 = 5000
#: Stage-1 sampler settings of every manifest (short: these problems have 3-7 parameters, tau ~ 30 steps).
IDENTIFY = {"walkers": 24, "max_steps": 2500, "check_every": 250, "ess_min": 200}
#: The single tap of a held-out combination and the lengths its prediction is scored at.
TAP = 0.025
SCORED = (0.020, 0.030, 0.035, 0.040, 0.045)
WORKERS = 2


def library_spec(per_type: int, specials=(), types=None) -> LibrarySpec:
    kw = {} if types is None else {"holder_types": tuple(types)}
    return LibrarySpec(per_type=per_type, specials=tuple(specials), identify={**IDENTIFY, "seed": 0}, **kw)


def make_library(root: Path, tag: str, seed: int, per_type: int, specials=(), types=None) -> Path:
    """Write (once) a library under ``root/tag``; returns its manifest."""
    folder = root / tag
    manifest = folder / "manifest.toml"
    if not manifest.exists():
        write_library(generate_library(library_spec(per_type, specials, types), seed=seed), folder)
    return manifest


def big_type(root: Path, n: int, campaigns: int) -> dict:
    """The outlier check in one holder type (ER32) of ``n`` combinations: clean, 3x softer, tip mass.

    ``campaigns`` libraries (seeds 5100, 5101, ...); the special combination is a different one in each.
    """
    from bayes_rcsa.batch.manifest import load_manifest

    counts = {"false flag": [0, 0, []], "3x softer": [0, 0, []], "tip mass 2 g": [0, 0, []]}
    for c in range(campaigns):
        seed = SEED0 + 100 + c
        tag = f"big{seed}"
        k = (1 + 3 * c) % n
        manifest = make_library(root, tag, seed, n, types=("ER32",))
        stage1(manifest, root / f"{tag}.stage1")
        rows = _flags(root / f"{tag}.stage1", manifest, seed)
        bad = [r["name"] for r in rows if r.get("outlier")]
        counts["false flag"][0] += bool(bad)
        counts["false flag"][1] += 1
        counts["false flag"][2].append(f"{tag}: {', '.join(_named(rows)) or 'none'}")
        print(f"big clean {tag}: flagged {bad or 'none'}", flush=True)
        for label, special in (("3x softer", {"softer": 3.0}), ("tip mass 2 g", {"hidden_effects": {"tip_mass": True}})):
            stag = f"{tag}.{'soft' if 'softer' in special else 'mass'}{k}"
            sman = make_library(root, stag, seed, n, [Special(k, **special)], types=("ER32",))
            name = load_manifest(sman)[k].name
            rows = _flags(special_stage1(root, stag, tag, sman, name), sman, seed + 1)
            row = next(r for r in rows if r["name"] == name)
            others = _named(rows, name)
            counts[label][0] += bool(row.get("outlier"))
            counts[label][1] += 1
            counts[label][2].append(_special(row, others))
            print(f"big {label} {stag}: {name} flagged {row.get('outlier')} (p = {row.get('p_value')}); others "
                  f"{others}", flush=True)
    return {f"{label}, one ER32 library of {n}": (k_, n_, "; ".join(d)) for label, (k_, n_, d) in counts.items()}


def stage1(manifest: Path, out: Path) -> dict:
    """``bayes-rcsa batch`` (resumable) and the stage-1 diagnostics of every setup."""
    t0 = time.perf_counter()
    rc = cli(["batch", str(manifest), "--out", str(out), "--workers", str(WORKERS), "--quiet"])
    diag = {}
    for summary in sorted((out / "setups").glob("*/identify/summary.json")):
        s = json.loads(summary.read_text())
        diag[summary.parent.parent.name] = s
    print(f"  stage 1 {manifest.parent.name}: batch exit {rc}, {len(diag)} fits, {time.perf_counter() - t0:.0f} s",
          flush=True)
    return diag


def stage1_diagnostics(diags: list[dict]) -> dict:
    """Max R-hat, min tau-based ESS and convergence over all stage-1 fits."""
    rhat, ess, tau, conv, steps = [], [], [], 0, []
    for s in diags:
        conv += bool(s.get("converged"))
        if s.get("n_steps") is not None:  # None: an importance-sampled fit (identify's default) has no chain
            steps.append(s["n_steps"])
        t = s.get("tau") or {}
        tau.append(max(t.values()) if t else float("nan"))
        for p in (s.get("parameters") or {}).values():
            if isinstance(p, dict):
                if p.get("rhat") is not None:
                    rhat.append(p["rhat"])
                if p.get("ess_bulk") is not None:
                    ess.append(p["ess_bulk"])
    return {"n": len(diags), "converged": conv, "steps_median": statistics.median(steps) if steps else 0,
            "tau_max_median": statistics.median(tau) if tau else float("nan"),
            "rhat_max": max(rhat) if rhat else float("nan"), "ess_min": min(ess) if ess else float("nan")}


def truth_frequencies(setup: Path) -> dict:
    truth = json.loads((setup.parent / "truth.json").read_text())
    return {round(t["clamping_length"], 6): t["dominant_frequency_hz"] for t in truth["tool_point_frequencies"]
            if t["direction"] == "x"}


def predicted(setup: Path, posterior: Path, out: Path, lengths, truth: dict) -> dict:
    """90 % interval and median of the mode that holds the true dominant frequency, per length."""
    rc = cli(["predict", str(setup), "--posterior", str(posterior), "--out", str(out), "--quiet", "--no-plots",
              "--max-draws", "500",
              "--force", "--lengths", ",".join(repr(x) for x in lengths), "--directions", "x", "--seed", "0"])
    if rc != 0:
        return {}
    doc = json.loads((out / "frequencies.json").read_text())
    res = {}
    for length in lengths:
        f_true = truth[round(length, 6)]
        modes = [p for p in doc["predictions"] if abs(p["clamping_length"] - length) < 1e-9]
        inside = [p for p in modes if p["band_lo_hz"] <= f_true <= p["band_hi_hz"]]
        pick = inside[0] if inside else next((p for p in modes if p["dominant"]), None)
        if pick is None or pick.get("q50_hz") is None:
            continue
        res[round(length, 6)] = (pick["q05_hz"], pick["q50_hz"], pick["q95_hz"], f_true)
    return res


def score(rows: list[dict]) -> dict:
    """Median |error| (%), coverage (all intervals; per case at 45 mm), median relative width (%)."""
    err, cover, width, far = [], [], [], []
    for r in rows:
        for length, (lo, mid, hi, truth) in r.items():
            err.append(abs(mid / truth - 1) * 100)
            cover.append(lo <= truth <= hi)
            width.append((hi - lo) / truth * 100)
            if abs(length - 0.045) < 1e-9:
                far.append(lo <= truth <= hi)
    k, n = int(sum(cover)), len(cover)
    kf, nf = int(sum(far)), len(far)
    return {"median_abs_error_pct": statistics.median(err) if err else float("nan"),
            "p90_abs_error_pct": float(np.percentile(err, 90)) if err else float("nan"),
            "coverage": (k, n, *clopper_pearson(k, n)) if n else (0, 0, float("nan"), float("nan")),
            "coverage_45mm": (kf, nf, *clopper_pearson(kf, nf)) if nf else (0, 0, float("nan"), float("nan")),
            "median_width_pct": statistics.median(width) if width else float("nan")}


def _quiet(argv: list[str]) -> int:
    return cli(argv + ["--quiet"])


def _case(job_setup: str, name: str, st1, work: str, seed: int, baseline: bool = True) -> dict:
    """One held-out combination: population without it, one tap with/without the library, zero taps.

    ``st1`` is the library's :class:`bayes_rcsa.library.stage1.Stage1` (read once per library).
    """
    import dataclasses

    from bayes_rcsa.library.workflow import fit_library, write_library as write_population_dir

    setup, work = Path(job_setup), Path(work)
    truth = truth_frequencies(setup)
    rest = dataclasses.replace(st1, setups=[s for s in st1.setups if s.name != name])
    t0 = time.perf_counter()
    fit = fit_library(rest, np.random.default_rng(seed), outliers=False)
    write_population_dir(work / "pop", fit, plots=False)
    t_stage2 = time.perf_counter() - t0
    pop = str(work / "pop" / "population.nc")
    opts = [f"--{k.replace('_', '-')}={v}" for k, v in IDENTIFY.items()]
    common = ["--no-plots", "--force", "--seed", str(seed), *opts]
    out = {}
    if _quiet(["identify", str(setup), "--library", pop, "--lengths", repr(TAP), "--out", str(work / "tap"),
               *common]) in (0, 1):
        out["library"] = predicted(setup, work / "tap" / "posterior.nc", work / "tap_pred", SCORED, truth)
    if baseline and _quiet(["identify", str(setup), "--method", "single", "--lengths", repr(TAP), "--out", str(work / "single"),
               *common]) in (0, 1):
        out["single"] = predicted(setup, work / "single" / "posterior.nc", work / "single_pred", SCORED, truth)
    if _quiet(["identify", str(setup), "--library", pop, "--no-taps", "--out", str(work / "zero"), "--no-plots",
               "--force", "--seed", str(seed)]) in (0, 1):
        out["zero"] = predicted(setup, work / "zero" / "posterior.nc", work / "zero_pred", SCORED, truth)
    (work / "case.json").write_text(json.dumps({k: {str(a): b for a, b in v.items()} for k, v in out.items()}))
    line = "  ".join(f"{k}: {statistics.median(abs(v[1] / v[3] - 1) * 100 for v in r.values()):.2f} %"
                     for k, r in out.items() if r)
    print(f"  {name}: stage 2 {t_stage2:.0f} s; median |error| {line}", flush=True)
    return out


def loo_cases(root: Path, tag: str, manifest: Path, baseline: bool = True) -> list[dict]:
    """Every combination of a library held out in turn (2 processes); the baseline fit only if ``baseline``."""
    from concurrent.futures import ProcessPoolExecutor

    from bayes_rcsa.batch.manifest import load_manifest

    from bayes_rcsa.library.stage1 import collect

    jobs = load_manifest(manifest)
    st1 = collect(jobs, root / f"{tag}.stage1")
    args = [(str(j.setup_file), j.name, st1, str(root / f"{tag}.loo" / j.name), SEED0 + i, baseline)
            for i, j in enumerate(jobs)]
    cached, todo = [], []
    for a in args:
        f = Path(a[3]) / "case.json"
        if f.exists():
            doc = json.loads(f.read_text())
            cached.append({k: {float(x): tuple(y) for x, y in v.items()} for k, v in doc.items()})
        else:
            todo.append(a)
    print(f"{tag}: {len(jobs)} held-out cases ({len(cached)} cached)", flush=True)
    with ProcessPoolExecutor(WORKERS) as ex:
        return cached + list(ex.map(_case_star, todo))


def _case_star(a):
    return _case(*a)


def _flags(stage1_dir: Path, manifest: Path, seed: int) -> list[dict]:
    """The library's outlier rows, with the components' p-values (``p_shift``, ``p_omnibus``, ``p_adequacy``)
    beside the combined ``p_value``: ``fit_library``'s check (:func:`bayes_rcsa.library.workflow.outlier_check`,
    the adequacy component from the stage-1 summaries in ``stage1_dir``), on the same generator in the same
    order (so the contact statistics are those of the two-statistic runs)."""
    from bayes_rcsa.batch.manifest import load_manifest
    from bayes_rcsa.library.stage1 import collect
    from bayes_rcsa.library.workflow import fit_library, outlier_check

    rng = np.random.default_rng(seed)
    st1 = collect(load_manifest(manifest), stage1_dir)
    fit = fit_library(st1, rng, outliers=False)
    rows, _ = outlier_check(fit.stage2, st1, stage1_dir, rng)
    return rows


def _by(row: dict) -> str:
    """Which component flagged a row: ``contact``, ``adequacy`` or ``contact + adequacy``."""
    reason = row.get("outlier_reason") or ""
    return " + ".join(w for w, key in (("contact", "contact disagrees"), ("adequacy", "not reproduced"))
                      if key in reason)


def _named(rows: list[dict], skip: str | None = None) -> list[str]:
    """Flagged rows other than ``skip``: ``NAME [component] p = ...``."""
    return [f"{r['name']} [{_by(r)}] {_p(r)}" for r in rows if r.get("outlier") and r["name"] != skip]


def _special(row: dict, others: list[str]) -> str:
    """One campaign's detail: the special combination's verdict and p-values, other flags."""
    verdict = f"[{_by(row)}]" if row.get("outlier") else "[missed]"
    return f"{row['name']} {verdict} {_p(row)}" + (f" (+ {'; '.join(others)})" if others else "")


def _p(row: dict) -> str:
    """``p = 3.1e-04 (shift 1.5e-04, omnibus 2.0e-02, adequacy 1.0e+00 at tau 1.0)``."""
    def f(v):
        return "-" if v is None else f"{v:.1e}"
    tau = row.get("residual_correlation_lines")
    return (f"p = {f(row.get('p_value'))} (shift {f(row.get('p_shift'))}, omnibus {f(row.get('p_omnibus'))}, "
            f"adequacy {f(row.get('p_adequacy'))}" + ("" if tau is None else f" at tau {tau:.1f}") + ")")


def special_stage1(root: Path, tag: str, base_tag: str, manifest: Path, special: str) -> Path:
    """Stage-1 folder of a special library: the clean library's fits (linked) and the special one refitted.

    The special library differs from the clean one only in the special combination's data (each
    combination has its own noise stream), so only that combination is identified again, with the
    manifest's own identify command.
    """
    from bayes_rcsa.batch.manifest import load_manifest

    out = root / f"{tag}.stage1"
    (out / "setups").mkdir(parents=True, exist_ok=True)
    for job in load_manifest(manifest):
        target = out / "setups" / job.name
        if job.name != special:
            if not target.exists():
                target.symlink_to(root / f"{base_tag}.stage1" / "setups" / job.name)
            continue
        if not (target / "identify" / "posterior.nc").exists():
            target.mkdir(parents=True, exist_ok=True)
            cli(job.argv("identify", target) + ["--no-plots", "--force"])
    return out


def outliers(root: Path, libs: list[tuple[str, Path]], n_campaigns: int) -> dict:
    """Flags of special combinations (3x softer; hidden tip mass) and false flags in the clean libraries."""
    from bayes_rcsa.batch.manifest import load_manifest

    res = {}
    clean_flags, clean_detail = 0, []
    for i, (tag, manifest) in enumerate(libs):
        rows = _flags(root / f"{tag}.stage1", manifest, SEED0 + i)
        bad = [r["name"] for r in rows if r.get("outlier")]
        clean_flags += bool(bad)
        clean_detail.append(f"{tag}: {', '.join(_named(rows)) or 'none'}")
        print(f"clean {tag}: flagged {bad or 'none'}", flush=True)
    res["clean libraries with a false flag"] = (clean_flags, len(libs), "; ".join(clean_detail))
    for kind, special in (("3x softer contact", {"softer": 3.0}), ("hidden tip mass 2 g", {"hidden_effects":
                                                                                           {"tip_mass": True}})):
        hits, detail = 0, []
        for i in range(n_campaigns):
            base_tag, base_manifest = libs[i % len(libs)]
            n = len(load_manifest(base_manifest))
            k = (3 * i + 1) % n  # a different combination (and holder type) in each campaign
            per_type = n // 3
            tag = f"{base_tag}.{'soft' if 'softer' in special else 'mass'}{k}"
            seed = SEED0 + (i % len(libs))
            manifest = make_library(root, tag, seed, per_type, [Special(k, **special)])
            name = load_manifest(manifest)[k].name
            rows = _flags(special_stage1(root, tag, base_tag, manifest, name), manifest, SEED0 + 100 + i)
            row = next(r for r in rows if r["name"] == name)
            others = _named(rows, name)
            hits += bool(row.get("outlier"))
            detail.append(_special(row, others))
            print(f"{kind} {tag}: {name} flagged {row.get('outlier')} (p = {row.get('p_value')}); others {others}",
                  flush=True)
        res[kind] = (hits, n_campaigns, "; ".join(detail))
    return res


def _cov(c) -> str:
    k, n, lo, hi = c
    return f"{k}/{n} = {k / n:.0%} [{lo:.2f}, {hi:.2f}]" if n else "-"


def render(s1: dict, transfer: dict, flags: dict, n_cases: int, seconds: float) -> str:
    """The Markdown tables of docs/library.md, "Benchmarks"."""
    lines = [
        "### Transfer, zero taps and outliers (`benchmarks/library.py`)",
        "",
        "Synthetic libraries from `bayes-rcsa synthesize` with a `[library]` table (docs/synthetic.md, \"Tool "
        "libraries\"): ER32 collets, shrink-fit and hydraulic chucks, carbide tools of 6-20 mm, each "
        "combination's true law drawn from its holder type's population (stiffness ~ d^1.8-2.2 and d^2.8-3.2, "
        "spreads 8-15 % in stiffness, growth 0.25-0.45 with logit spread 0.35), hammer tests at 25, 35 and 45 mm "
        "(x, 300-2600 Hz in 4 Hz lines, 2 % noise), seeds 5000 and up.  The truth is the noise-free "
        "finite-element bench's dominant frequency with the project's natural-frequency rule on the same lines; "
        "the prediction is the model interval of the predicted mode whose band holds it.  The population of a "
        "held-out case is fitted on the other 11 combinations of its library (stage 2 from their stage-1 fits, "
        "`bayes_rcsa.library.workflow.fit_library`); the held-out one is then identified with `identify "
        "--library` from its 25 mm tap only, or predicted with `identify --library --no-taps`.",
        "",
        f"Stage 1 ({s1['n']} fits, `bayes-rcsa batch`, {IDENTIFY['walkers']} walkers, at most "
        f"{IDENTIFY['max_steps']} steps): {s1['converged']}/{s1['n']} converged by the sampler's own rule "
        f"(bulk ESS >= {IDENTIFY['ess_min']}, R-hat < 1.01); median steps {s1['steps_median']:.0f}, median of the "
        f"largest tau {s1['tau_max_median']:.0f} steps, largest R-hat {s1['rhat_max']:.3f}, smallest bulk ESS "
        f"{s1['ess_min']:.0f}.",
        "",
        f"**One tap suffices** ({n_cases} held-out combinations, one tap at {TAP * 1e3:g} mm, scored at "
        f"{', '.join(f'{x * 1e3:g}' for x in SCORED)} mm; coverage with Clopper-Pearson 95 % interval; the 45 mm "
        "column counts one interval per case, i.e. independent trials):",
        "",
        "| prediction | median abs. error | 90th pct error | 90 % coverage (all lengths) | coverage at 45 mm | "
        "median 90 % width |",
        "|---|---|---|---|---|---|",
    ]
    names = {"library": "one tap + population prior", "single": "one tap alone (`--method single`, baseline; the first library's cases)",
             "zero": "zero taps (population predictive)"}
    for key in ("library", "single", "zero"):
        t = transfer.get(key)
        if not t or not t["coverage"][1]:
            continue
        lines.append(f"| {names[key]} | {t['median_abs_error_pct']:.2f} % | {t['p90_abs_error_pct']:.2f} % | "
                     f"{_cov(t['coverage'])} | {_cov(t['coverage_45mm'])} | {t['median_width_pct']:.2f} % |")
    lines += ["", "**Outliers** (`bayes_rcsa.library.workflow.fit_library` with its outlier check: flagged when "
              "p = min(p_shift / 0.45, p_omnibus / 0.45, p_adequacy / 0.1) < 0.05 / number of combinations, weighted "
              "Bonferroni over the three components and the library; the special combination's flag and its "
              "p-values (contact shift, omnibus distance, model adequacy at the residual correlation length tau of "
              "its stage-1 optimum, lines) per campaign, any flag in a clean library with the flagging component):",
              "",
              "| case | flagged | 95 % interval | detail |", "|---|---|---|---|"]
    for key, (k, n, detail) in flags.items():
        lo, hi = clopper_pearson(k, n) if n else (float("nan"), float("nan"))
        lines.append(f"| {key} | {k}/{n} | [{lo:.2f}, {hi:.2f}] | {detail} |")
    lines += ["", f"Wall time of the held-out cases (stage 2, two or three identify and predict runs each, two at a "
                  f"time): {seconds / 60:.0f} min on the shared 2-core machine."]
    return "\n".join(lines)


def replace_docs_block(marker: str, text: str) -> None:
    """Replace (or append) the block between ``<!-- marker:begin -->`` and ``<!-- marker:end -->``."""
    block = f"<!-- {marker}:begin -->\n{text}\n<!-- {marker}:end -->"
    doc = DOCS.read_text() if DOCS.exists() else "# Tool libraries\n"
    if f"<!-- {marker}:begin -->" in doc:
        doc = re.sub(rf"<!-- {marker}:begin -->.*?<!-- {marker}:end -->", lambda m: block, doc, flags=re.S)
    else:
        doc = doc.rstrip("\n") + "\n\n" + block + "\n"
    DOCS.write_text(doc)


def libraries(root: Path, n_full: int, n_clean: int) -> list[tuple[str, Path]]:
    """(tag, manifest) of the clean libraries: ``n_full`` of 12 combinations (4 per type: the LOO and the
    outlier campaigns' libraries) first, then 6-combination ones (false flags only).

    A 12-combination library of seed ``s`` is tagged ``lib{s}``; a 6-combination one ``lib{s}`` too, unless the
    workdir already holds a library of the other size under that tag (an earlier run), then ``lib{s}_{n}``.
    """
    out = []
    for i in range(n_clean):
        per_type = 4 if i < n_full else 2
        tag = f"lib{SEED0 + i}"
        existing = root / tag / "manifest.toml"
        if existing.exists() and len(re.findall(r"^\[\[setup\]\]", existing.read_text(), re.M)) != 3 * per_type:
            tag = f"{tag}_{3 * per_type}"
        out.append((tag, make_library(root, tag, SEED0 + i, per_type)))
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workdir", type=Path, required=True)
    ap.add_argument("--loo", type=int, default=3, help="12-combination libraries for the transfer tables")
    ap.add_argument("--clean", type=int, default=10, help="clean libraries in all (false flags)")
    ap.add_argument("--outliers", type=int, default=5, help="campaigns per outlier kind")
    ap.add_argument("--part", choices=("stage1", "loo", "outliers", "all", "none"), default="all",
                    help="stage1: libraries and stage 1 only; loo: the transfer cases; outliers: the flag counts; "
                         "all: everything (each part reuses what an earlier run left in --workdir)")
    ap.add_argument("--big-type", type=int, default=0, metavar="N",
                    help="also the outlier check in one ER32 library of N combinations (power against type size)")
    ap.add_argument("--big-campaigns", type=int, default=3, help="libraries of --big-type (seeds 5100, ...)")
    ap.add_argument("--write-docs", action="store_true")
    args = ap.parse_args(argv)
    root = args.workdir
    root.mkdir(parents=True, exist_ok=True)
    libs = libraries(root, max(args.loo, args.outliers), args.clean)
    parts = {"stage1", "loo", "outliers"} if args.part == "all" else {args.part} - {"none"}
    if "stage1" in parts:
        for tag, manifest in libs:
            stage1(manifest, root / f"{tag}.stage1")
    if "loo" in parts:
        for tag, manifest in libs[:args.loo]:
            stage1(manifest, root / f"{tag}.stage1")  # resumable: reuses the finished fits
        t0 = time.perf_counter()
        rows = {"library": [], "single": [], "zero": []}
        for i, (tag, manifest) in enumerate(libs[:args.loo]):
            # the single-length baseline is a reference number: the first library's cases give it
            for case in loo_cases(root, tag, manifest, baseline=i == 0):
                for key, res in case.items():
                    rows[key].append(res)
        transfer = {k: score(v) for k, v in rows.items()}
        # wall time accumulates over resumed runs (cached cases cost nothing the second time)
        before = json.loads((root / "transfer.json").read_text())["seconds"] if (root / "transfer.json").exists() else 0
        (root / "transfer.json").write_text(json.dumps({"transfer": transfer, "n_cases": len(rows["library"]),
                                                        "seconds": before + time.perf_counter() - t0}))
        print(json.dumps(transfer, indent=1), flush=True)
    if "outliers" in parts:
        for tag, manifest in libs:
            stage1(manifest, root / f"{tag}.stage1")
        flags = outliers(root, libs, args.outliers)
        (root / "outliers.json").write_text(json.dumps(flags))
    if args.big_type:
        flags = json.loads((root / "outliers.json").read_text()) if (root / "outliers.json").exists() else {}
        flags = {k: v for k, v in flags.items() if "one ER32 library" not in k}
        flags.update(big_type(root, args.big_type, args.big_campaigns))
        (root / "outliers.json").write_text(json.dumps(flags))
    diags = [s for tag, _ in libs for s in _summaries(root / f"{tag}.stage1")]
    s1 = stage1_diagnostics(diags)
    print("stage 1:", s1, flush=True)
    if (root / "transfer.json").exists() and (root / "outliers.json").exists():
        t = json.loads((root / "transfer.json").read_text())
        tables = render(s1, t["transfer"], json.loads((root / "outliers.json").read_text()), t["n_cases"],
                        t["seconds"])
        print(tables)
        if args.write_docs:
            replace_docs_block("library-bench", tables)


def _summaries(stage1_dir: Path) -> list[dict]:
    return [json.loads(p.read_text()) for p in sorted((stage1_dir / "setups").glob("*/identify/summary.json"))]


if __name__ == "__main__":
    main()
