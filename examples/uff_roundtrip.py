"""Measurements in universal files (UFF, dataset 58) instead of CSV.

Hammer-test software (LMS, m+p, Siemens, ...) exports FRFs as universal
files.  A setup's ``[[measurement]] file = ...`` may name a ``.uff``,
``.unv`` or ``.uf`` file as well as a CSV (docs/data-formats.md).  This
script

1. converts the bundled example's tool-point CSV files to UFF58
   (:func:`bayes_rcsa.io.write_frf_uff`, binary double precision: lossless);
2. writes a copy of the example setup whose measurements point at them;
3. identifies the contact from both setups with the same seed and shows
   that the results are identical (the files carry the same numbers).

Run::

    python examples/uff_roundtrip.py            # Method II from 25 and 40 mm, converged, about a minute each
    python examples/uff_roundtrip.py --quick    # single-length fits at 25 mm, short chains, ~10 s

(``BAYES_RCSA_QUICK=1`` also selects the reduced run.)
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import tomllib
from pathlib import Path

import numpy as np

from bayes_rcsa.data import example_dir, example_setup
from bayes_rcsa.inference import IdentificationOptions, SamplerSettings, build_problem_from_setup, identify
from bayes_rcsa.io import dump_toml, load_setup, read_frf, write_frf_uff


def quick_requested(argv=None) -> bool:
    """``--quick`` on the command line or ``BAYES_RCSA_QUICK=1`` in the environment."""
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK", "") not in ("", "0")


def uff_setup(root: Path) -> Path:
    """Copy the example's spindle files, convert its tool-point CSVs to UFF58; returns the new setup path."""
    doc = tomllib.loads(example_setup().read_text())
    for f in doc["spindle"].values():
        shutil.copy(example_dir() / f, root / f)
    for m in doc["measurement"]:
        csv = example_dir() / m["file"]
        uff = Path(m["file"]).with_suffix(".uff").name
        write_frf_uff(root / uff, read_frf(csv), direction=m["direction"], description=f"tool point {csv.name}")
        m["file"] = uff
    path = root / "setup.toml"
    path.write_text(dump_toml(doc))
    return path


def fit(setup_path: Path, quick: bool, seed: int):
    setup = load_setup(setup_path)
    method, lengths = ("single", (0.025,)) if quick else ("multi", (0.025, 0.040))
    options = IdentificationOptions.from_setup(setup.extra, method=method, lengths=lengths)
    settings = SamplerSettings(max_steps=80, check_every=80, progress=False) if quick else SamplerSettings(progress=False)
    return identify(build_problem_from_setup(setup, options), seed=seed, settings=settings)


def main(quick: bool | None = None, seed: int = 0) -> dict:
    """Fit from CSV and from UFF; returns {"csv": summary parameters, "uff": ..., "identical": bool}."""
    quick = quick_requested() if quick is None else quick
    with tempfile.TemporaryDirectory() as tmp:
        path = uff_setup(Path(tmp))
        files = sorted(p.name for p in Path(tmp).glob("*.uff"))
        print(f"wrote {len(files)} UFF58 files ({', '.join(files[:2])}, ...) and {path.name}")
        a, b = fit(example_setup(), quick, seed), fit(path, quick, seed)
    identical = bool(np.array_equal(a.flat_theta, b.flat_theta))
    print(f"{'parameter':10s} {'CSV median [90 %]':>34s} {'UFF58 median [90 %]':>34s}")
    for name, pa in a.summary["parameters"].items():
        pb = b.summary["parameters"][name]
        cell = lambda p: f"{p['q50']:.5g} [{p['q05']:.5g}, {p['q95']:.5g}]"  # noqa: E731
        print(f"{name:10s} {cell(pa):>34s} {cell(pb):>34s}")
    print(f"posterior draws identical: {identical}")
    return {"csv": a.summary["parameters"], "uff": b.summary["parameters"], "identical": identical}


if __name__ == "__main__":
    main()
