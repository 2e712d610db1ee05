"""``bayes-rcsa library``: a tool library's contact population (hierarchical model, two stages)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import SetupError
from ._common import Summary, command_warnings, merge_warnings, nonnegative_int, positive_int

__all__ = ["register", "run"]

DESCRIPTION = """\
Fit the contact-law population of a tool library: per holder type ([holder] type in each setup),
the contact parameters (log10 stiffness at the library's reference length, growth factors, log10
damping) are normal with a mean linear in ln(shank diameter / 10 mm) and a per-type spread.

Stage 1: every setup of MANIFEST (the 'batch' format) is identified on its own under its broad
prior, one task per setup on --workers local processes or a Dask cluster (--scheduler ADDRESS);
finished setups are reused (cached per setup), --force recomputes them.
Stage 2: the population's posterior from the stored stage-1 draws (Gaussian likelihood surrogates,
emcee per holder type), each setup's importance ESS, a leave-one-out outlier check.

Writes to --out: setups/<name>/identify/ (stage 1), population.nc (ArviZ; read by 'bayes-rcsa
identify --library'), laws.json and laws.csv (per holder type: the law at 10 mm, diameter slope and
spread with 90 % intervals), library.json (per setup: own and pooled estimates, ESS, outlier flag,
warnings) and shrinkage.png.  See docs/library.md.
"""


def register(subparsers) -> None:
    p = subparsers.add_parser("library", help="fit a tool library's contact population (hierarchical, two stages)",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("manifest", type=Path, metavar="MANIFEST", help="manifest TOML file (the 'batch' format)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR",
                   help="output directory (resumed when it holds an earlier library run)")
    p.add_argument("--workers", type=positive_int, default=None, metavar="N",
                   help="local worker processes for stage 1 (default: the number of CPU cores)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="Dask scheduler address: run stage 1 on that cluster instead")
    p.add_argument("--force", action="store_true", help="recompute every stage-1 setup, finished or not")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="random seed of stage 2 (default 0)")
    p.add_argument("--max-steps", type=positive_int, default=None, metavar="N",
                   help="stage 2 stops unconverged, with a warning, after N steps (default "
                        f"{_default_max_steps()}; a library of many holder types and setups may need more)")
    p.add_argument("--no-outliers", action="store_true", help="skip the leave-one-out outlier check")
    p.add_argument("--tail-correct", action="store_true",
                   help="check every stage-1 posterior's interval ends against importance sampling and pool "
                        "importance draws where the chain missed a tail (1e5 evaluations per setup; docs/library.md)")
    p.add_argument("--no-plots", action="store_true", help="skip shrinkage.png")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run)


def _default_max_steps() -> int:
    from ..library.defaults import STAGE2_MAX_STEPS

    return STAGE2_MAX_STEPS


def run(args: argparse.Namespace) -> Summary:
    import json

    import numpy as np

    from ..batch import load_manifest
    from ..io.atomic import atomic_write_text, directory_lock, new_output_directory
    from ..library.stage2 import Stage2Settings
    from ..library.stage1 import check_setups, collect, run_stage1
    from ..library.workflow import fit_library, write_library
    from ._arguments import prepare_run
    from .main import main as run_command

    jobs = load_manifest(args.manifest)
    try:
        check_setups(jobs)  # everything a setup can be refused for, before stage 1 runs
    except SetupError as exc:
        raise SetupError(f"{args.manifest}: {exc}") from None
    out, workers, client, executor = prepare_run(args, "library_run.json", "library")

    def progress(k, n, row):
        if not args.quiet:
            print(f"bayes-rcsa library: stage 1 [{k}/{n}] {row['name']}: {row['status']}"
                  + (f" ({row['error']})" if row.get("error") else ""), file=sys.stderr, flush=True)

    try:
        with directory_lock(out), new_output_directory(out):
            atomic_write_text(out / "library_run.json", json.dumps({"manifest": str(args.manifest.resolve()),
                                                                    "setups": [j.name for j in jobs]}, indent=1))
            result = run_stage1(jobs, out, run_command, executor=executor, workers=workers, force=args.force,
                                progress=progress)
            stage1 = collect(jobs, out, result.rows, tail_correct=args.tail_correct,
                             rng=np.random.default_rng([args.seed, 5]))
            settings = {} if args.max_steps is None else {"settings": Stage2Settings(max_steps=args.max_steps)}
            fit = fit_library(stage1, np.random.default_rng(args.seed), outliers=not args.no_outliers, stage1_dir=out,
                              **settings)
            fit.warnings[:0] = command_warnings()
            paths = write_library(out, fit, plots=not args.no_plots, attrs={"seed": args.seed})
    finally:
        if client is not None:
            client.close()
    warns = merge_warnings(fit.warnings)
    outliers = [r["name"] for r in fit.setups if r.get("outlier")]
    human = (f"{len(fit.setups)} combination(s) in {len(fit.population.holder_types)} holder type(s) "
             f"{list(fit.population.holder_types)}; outliers: {outliers or 'none'}; population in "
             f"{paths['population']}")
    return Summary(human, {"out": str(out), "population": str(paths["population"]), "laws": str(paths["laws_json"]),
                           "library": str(paths["json"]), "holder_types": list(fit.population.holder_types),
                           "outliers": outliers, "ran": result.ran, "reused": result.reused},
                   warnings=tuple(warns))
