"""``example``: every file the documentation uses, in one folder (:func:`write_example_files`).

>>> files = bayes_rcsa.write_example_files("my-campaign")  # = bayes-rcsa example --out my-campaign
>>> files.setup                                           # my-campaign/setup.toml

The pages of docs/ start from this folder (``bayes-rcsa example --out .``), so
that every command they show runs as written:

- the bundled example campaign (``setup.toml``, ``spindle_x.csv``/``_y``, the
  tool-point FRFs ``tip_<d>_<mm>mm.csv`` and ``truth.json``; the demo's data);
- ``bench.toml``, the synthetic bench configuration
  (bayes_rcsa/synthetic/example_bench.toml) for ``bayes-rcsa synthesize``;
- ``artifact/``, standard-artifact hammer tests of that bench's spindle
  (``artifact/artifact.toml`` and its h11/h12/h21/h22 files) for
  ``bayes-rcsa spindle``;
- ``library.toml``, a batch/library manifest over the two set-ups of
  ``library/`` (a small synthetic ER32 tool library with coarse frequency
  lines, so that ``batch`` and ``library`` run in minutes);
- ``README.txt`` naming each of them.

The same seed gives byte-identical files.
"""

from __future__ import annotations

import shutil
from importlib import resources
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from ..errors import DataError
from ..messages import warning_log
from .result import Result, saving

__all__ = ["write_example_files", "ExampleFiles", "LIBRARY_LENGTHS"]

#: m, the hammer-test clamping lengths of the example library's set-ups (fitted by ``batch`` and ``library``)
LIBRARY_LENGTHS = (0.025, 0.045)
#: Combinations of the example library: one holder type (ER32) and the fewest the library command accepts, so that
#: a batch of them on two workers takes the time of one identify + predict + lobes
LIBRARY_SIZE = 2
#: Hz, frequency-line spacing of the example library's set-ups (coarse, so that a batch of them runs in minutes)
LIBRARY_LINE_SPACING = 8.0

#: The entries of the folder, in the order README.txt names them
ENTRIES = ("README.txt", "setup.toml", "spindle_x.csv", "spindle_y.csv", "tip_<d>_<mm>mm.csv", "truth.json",
           "bench.toml", "artifact/", "library.toml", "library/")

_README = """\
Example files of bayes_rcsa (written by `bayes-rcsa example`; the documentation's pages use them).
All values in SI units (m, N, rad, s, Hz, Pa).

setup.toml            the bundled example campaign (the demo's data): an ER32 collet chuck with a
spindle_x.csv           7.94 mm carbide end mill, hammer tests at 25, 30, 35 and 40 mm clamping in
spindle_y.csv           x and y, made by the project's independent finite-element bench
tip_x_25mm.csv ...      (tool-point FRFs, m/N; spindle flange receptances)
truth.json              what is true (the bench's contact, noise-free natural frequencies)
                        -> bayes-rcsa identify setup.toml --out fit --lengths 0.025,0.040

bench.toml            the synthetic bench configuration (a copy of
                        bayes_rcsa/synthetic/example_bench.toml)
                        -> bayes-rcsa synthesize bench.toml --out campaign

artifact/             standard-artifact hammer tests of that bench's spindle: artifact.toml,
                        h11/h12/h21/h22_<x|y>.csv, the true flange receptance spindle_true_<x|y>.csv
                        and truth.json (seed {seed})
                        -> bayes-rcsa spindle artifact/artifact.toml --out spindle

library.toml          a batch/library manifest over the set-ups of library/: identify at 25 and 45 mm,
library/                predict, lobes at 35 mm; library/ is a small synthetic ER32 tool library
                        ({n} holder-tool combinations, x and y, {step:g} Hz lines; the truth in
                        library/library.json and library/*/truth.json; seed {seed})
                        -> bayes-rcsa batch library.toml --out batch
                        -> bayes-rcsa library library.toml --out lib

See docs/getting-started.md.
"""

_MANIFEST = """\
# Batch / library manifest of the example tool library (docs/scaling-out.md, docs/library.md).
# Paths are relative to this file; every key is the option of the same name of identify, predict or lobes.

[defaults]
method = "multi"
lengths = [{lengths}]       # clamping lengths fitted, m
plots = false

[defaults.predict]
lengths = [{predict}]

[defaults.lobes]
clamping_length = {lobes_length}
flutes = 4
kt = "790e6"
kr = "230e6"
immersion = 0.95
speeds = "5000:30000:200"
draws = 100
{setups}"""


@dataclass
class ExampleFiles(Result):
    """The folder of example files (see the module docstring).

    Attributes
    ----------
    folder : Path, the folder written
    seed : int, seed of the synthetic artifact tests and tool library
    library_setups : tuple of str, the names of the example library's set-ups (``library/<name>/setup.toml``)
    warnings : tuple of str
    """

    title: ClassVar[str] = "Example files"
    files: ClassVar[tuple[str, ...]] = ENTRIES

    folder: Path
    seed: int = 0
    library_setups: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    @property
    def setup(self) -> Path:
        """The bundled campaign's setup file."""
        return Path(self.folder) / "setup.toml"

    @property
    def bench(self) -> Path:
        return Path(self.folder) / "bench.toml"

    @property
    def artifact(self) -> Path:
        return Path(self.folder) / "artifact" / "artifact.toml"

    @property
    def manifest(self) -> Path:
        return Path(self.folder) / "library.toml"

    def to_dict(self) -> dict:
        return {"out": str(self.folder), "setup": str(self.setup), "bench": str(self.bench),
                "artifact": str(self.artifact), "manifest": str(self.manifest),
                "library_setups": list(self.library_setups), "seed": self.seed}

    def headline(self) -> list[tuple[str, str]]:
        return [("campaign", str(self.setup)), ("bench", str(self.bench)), ("artifact", str(self.artifact)),
                ("batch/library manifest", f"{self.manifest} ({len(self.library_setups)} set-ups)")]

    def summary_line(self) -> str:
        return (f"wrote the example campaign (setup.toml), bench.toml, artifact/artifact.toml and library.toml "
                f"({len(self.library_setups)} set-ups in library/) to {self.folder}; see {self.folder / 'README.txt'}")

    def summary_data(self) -> dict:
        return {k: v for k, v in self.to_dict().items() if k != "out"}

    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write the same files into ``folder`` (generated again from the seed); returns its README.txt."""
        again = write_example_files(folder, force=force, seed=self.seed)
        self.warnings = again.warnings
        return Path(folder) / "README.txt"

    @classmethod
    def load(cls, folder) -> "ExampleFiles":
        folder = Path(folder)
        missing = [n for n in ("README.txt", "setup.toml", "bench.toml", "artifact/artifact.toml", "library.toml")
                   if not (folder / n).is_file()]
        if missing:
            raise DataError(f"{folder}: not a folder of example files ({', '.join(missing)} missing; written by "
                            "'bayes-rcsa example')")
        names = tuple(sorted(p.parent.name for p in (folder / "library").glob("*/setup.toml")))
        return cls(folder=folder, library_setups=names)


def _predicted_lengths() -> tuple[float, float, float]:
    """m, the clamping lengths the manifest predicts: the fitted two and the one between (held out, lobes)."""
    a, b = LIBRARY_LENGTHS
    return (a, round((a + b) / 2, 6), b)


def _library_manifest(names) -> str:
    setups = "".join(f'\n[[setup]]\nname = "{n}"\nfile = "library/{n}/setup.toml"\nseed = {i}\n'
                     for i, n in enumerate(names))
    predicted = _predicted_lengths()
    return _MANIFEST.format(lengths=", ".join(f"{v:g}" for v in LIBRARY_LENGTHS),
                            predict=", ".join(f"{v:g}" for v in predicted), lobes_length=f"{predicted[1]:g}",
                            setups=setups)


def write_example_files(out, *, force: bool = False, seed: int = 0) -> ExampleFiles:
    """Write the example campaign, bench, artifact tests and tool-library manifest into ``out``.

    Parameters
    ----------
    out : path of the folder (new or empty unless ``force``)
    force : bool, write into a non-empty folder, replacing these files of an earlier run
    seed : int >= 0, seed of the synthetic artifact tests and tool library (the campaign is the bundled one)

    Returns
    -------
    ExampleFiles

    Raises
    ------
    SetupError
        ``out`` is not empty and ``force`` is false (before anything is generated).
    """
    from ..data import example_dir
    from ..errors import SetupError
    from ..synthetic.library import LibrarySpec, library_base_config
    from .result import check_output_directory
    from .synthesis import synthesize

    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SetupError(f"--seed {seed!r}: expected an integer >= 0")
    out = Path(out)
    check_output_directory(out, force)  # before the synthetic files are generated (again under the lock)
    bench = Path(str(resources.files("bayes_rcsa.synthetic") / "example_bench.toml"))  # installed as package data
    with warning_log() as log:
        artifact = synthesize(bench, artifact=True, seed=seed)
        # truth (noise-free dominant frequencies) at the lengths the manifest predicts: each costs FE solves
        spec = LibrarySpec(holder_types=("ER32",), per_type=LIBRARY_SIZE, clamping_lengths=LIBRARY_LENGTHS,
                           truth_lengths=_predicted_lengths())
        # both directions: lobes couple x and y (a set-up without [spindle] y is refused by lobes)
        base = library_base_config(frequency_step=LIBRARY_LINE_SPACING, directions=("x", "y"))
        library = synthesize((base, spec), seed=seed)
        names = tuple(c["name"] for c in library.document["combinations"])
        with saving(out, force, earlier_outputs=("README.txt", "bench.toml", "library.toml")):
            for f in sorted(example_dir().iterdir()):
                if f.is_file():
                    shutil.copyfile(f, out / f.name)
            shutil.copyfile(bench, out / "bench.toml")
            artifact.save(out / "artifact", force=True)
            library.save(out / "library", force=True)
            # library.toml (with predict and lobes) is the one manifest; the generator's identify-only one would
            # be a second, different answer to "which manifest?"
            (out / "library" / "manifest.toml").unlink()
            (out / "library.toml").write_text(_library_manifest(names), encoding="utf-8")
            (out / "README.txt").write_text(_README.format(seed=seed, n=len(names), step=LIBRARY_LINE_SPACING),
                                            encoding="utf-8")
        return ExampleFiles(folder=out, seed=seed, library_setups=names, warnings=tuple(log))
