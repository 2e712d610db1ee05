"""``bayes-rcsa library``: a tool library's contact population (hierarchical model, two stages)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ._common import Summary, nonnegative_int, positive_int

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
    from ..library.defaults import STAGE2_MAX_STEPS  # a light module: the help text imports no sampler

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
                        f"{STAGE2_MAX_STEPS}; a library of many holder types and setups may need more)")
    p.add_argument("--no-outliers", action="store_true", help="skip the leave-one-out outlier check")
    p.add_argument("--tail-correct", action="store_true",
                   help="check every stage-1 posterior's interval ends against importance sampling and pool "
                        "importance draws where the chain missed a tail (1e5 evaluations per setup; docs/library.md)")
    p.add_argument("--no-plots", action="store_true", help="skip shrinkage.png")
    p.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> Summary:
    from ..workflows.library import build_library

    result = build_library(args.manifest, args.out, workers=args.workers, scheduler=args.scheduler, force=args.force,
                           seed=args.seed, max_steps=args.max_steps, outliers=not args.no_outliers,
                           tail_correct=args.tail_correct, plots=not args.no_plots, progress=not args.quiet)
    out = result.folder
    return Summary(result.summary_line(), {"out": str(out), "population": str(out / "population.nc"),
                                           "laws": str(out / "laws.json"), "library": str(out / "library.json"),
                                           **result.summary_data()},
                   warnings=result.warnings)
