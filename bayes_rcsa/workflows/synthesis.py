"""``synthesize``: a synthetic impact-hammer campaign (the test bench with hidden effects).

>>> bench = bayes_rcsa.synthesize("bench.toml", seed=3)          # tool-point FRFs, setup.toml, truth.json
>>> bench.save("campaign")
>>> bayes_rcsa.synthesize("bench.toml", artifact=True).save("artifact")   # hammer tests for identify_spindle
>>> bayes_rcsa.synthesize("library.toml").save("library")        # a [library] table: a whole tool library

The same files as ``bayes-rcsa synthesize CONFIG --out DIR`` (this call and
:meth:`Campaign.save`); the same CONFIG and seed give byte-identical files.
See docs/synthetic.md.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import ClassVar

import numpy as np

from ..errors import DataError, SetupError
from ..messages import warning_log
from .result import Result, check_output_directory

__all__ = ["synthesize", "Campaign"]

KINDS = ("campaign", "artifact", "library")


@dataclass
class Campaign(Result):
    """A synthetic campaign: tool-point hammer tests, standard-artifact tests or a tool library.

    Attributes
    ----------
    kind : {"campaign", "artifact", "library"}
        ``campaign``: spindle_<d>.csv, tip_<d>_<mm>mm.csv, setup.toml (what the user believes), truth.json
        (what is true) and, with cuts, cuts.csv and cuts_truth.json.  ``artifact``: artifact.toml,
        h11/h12/h21/h22_<d>.csv, spindle_true_<d>.csv and truth.json.  ``library``: one campaign folder
        per holder-tool combination, manifest.toml and library.json.
    seed : int, seed of the measurement noise
    document : dict
        truth.json (campaign, artifact) or library.json (library).
    frfs : dict of file name to FRF
        The simulated measurements, m/N (tool-point FRFs or artifact tests; empty for a library).
    n_spindle_files : int, flange receptance files of a campaign (the user's spindle)
    cuts_truth : dict or None, cuts_truth.json of a campaign with cutting tests
    holder_types : tuple of str, holder types of a library
    path : Path or None, the main file once saved or loaded (setup.toml, artifact.toml or manifest.toml)
    warnings : tuple of str
    generated : the generated objects (bayes_rcsa.synthetic Campaign and CutCampaign, ArtifactTests or
        Library); ``None`` when loaded from files, which then cannot be saved again.
    """

    title: ClassVar[str] = "Synthetic campaign"
    files: ClassVar[tuple[str, ...]] = ("setup.toml", "truth.json", "spindle_<d>.csv", "tip_<d>_<mm>mm.csv",
                                        "cuts.csv", "cuts_truth.json", "artifact.toml", "manifest.toml",
                                        "library.json")

    kind: str
    seed: int
    document: dict
    frfs: dict = field(default_factory=dict)
    n_spindle_files: int = 0
    cuts_truth: dict | None = None
    holder_types: tuple[str, ...] = ()
    path: Path | None = None
    warnings: tuple[str, ...] = ()
    generated: tuple | None = field(default=None, repr=False, compare=False)

    # -- numbers ---------------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """truth.json (campaign, artifact) or library.json (library)."""
        return self.document

    @property
    def hidden_effects(self) -> dict:
        """The hidden effects of a campaign and their magnitudes (empty for the others)."""
        return dict(self.document.get("hidden_effects", {})) if self.kind == "campaign" else {}

    @property
    def n_cuts(self) -> int:
        return 0 if self.cuts_truth is None else len(self.cuts_truth["cuts"])

    @property
    def specials(self) -> list[str]:
        """Names of a library's special combinations."""
        return [c["name"] for c in self.document.get("combinations", []) if c["special"]]

    def headline(self) -> list[tuple[str, str]]:
        if self.kind == "library":
            return [("holder-tool combinations", str(len(self.document["combinations"]))),
                    ("holder types", ", ".join(self.holder_types)),
                    ("special combinations", ", ".join(self.specials) or "no special combination"),
                    ("seed", str(self.seed))]
        rows = [("simulated FRFs", str(len(self.frfs)))]
        if self.kind == "campaign":
            lengths = sorted({m["clamping_length"] for m in self.document.get("measurements", [])
                              if "clamping_length" in m})
            if lengths:
                rows.append(("clamping lengths", ", ".join(f"{v * 1e3:g}" for v in lengths) + " mm"))
            rows.append(("hidden effects", _effects(self.hidden_effects) or "no hidden effect"))
            if self.cuts_truth is not None:
                stable = sum(c["stable"] for c in self.cuts_truth["cuts"])
                rows.append(("cutting tests", f"{self.n_cuts} ({stable} stable)"))
        return rows + [("seed", str(self.seed))]

    def summary_line(self) -> str:
        folder = None if self.path is None else self.path.parent
        if self.kind == "artifact":
            return (f"wrote {len(self.frfs)} artifact FRFs, the true flange receptances and artifact.toml to "
                    f"{folder} (seed {self.seed})")
        if self.kind == "library":
            return (f"wrote a tool library of {len(self.document['combinations'])} holder-tool combinations "
                    f"({', '.join(self.holder_types)}; special: {', '.join(self.specials) or 'no combination'}), "
                    "manifest.toml "
                    f"and library.json to {folder} (seed {self.seed})")
        effects = _effects(self.hidden_effects) or "no hidden effect"
        cuts = ""
        if self.cuts_truth is not None:
            stable = sum(c["stable"] for c in self.cuts_truth["cuts"])
            cuts = f"; {self.n_cuts} cuts ({stable} stable) in cuts.csv, their truth in cuts_truth.json"
        return (f"wrote {len(self.frfs)} tool-point FRFs, {self.n_spindle_files} spindle file(s), setup.toml and "
                f"truth.json to {folder} (seed {self.seed}; hidden effects: {effects})" + cuts)

    def summary_data(self) -> dict:
        if self.kind == "artifact":
            return {"n_frfs": len(self.frfs), "seed": self.seed}
        if self.kind == "library":
            return {"n_combinations": len(self.document["combinations"]), "holder_types": list(self.holder_types),
                    "special": self.specials, "seed": self.seed}
        return {"n_measurements": len(self.frfs), "seed": self.seed, "hidden_effects": self.hidden_effects,
                "n_cuts": self.n_cuts}

    # -- files -----------------------------------------------------------------------------------------------
    def save(self, folder, *, force: bool = False, plots: bool = True) -> Path:
        """Write the folder (replaced as a whole, atomically); returns setup.toml, artifact.toml or manifest.toml.

        ``plots`` is accepted for a uniform interface; the command writes no plot.
        """
        from ..io.atomic import directory_lock

        if self.generated is None:
            raise SetupError(f"save: this campaign was loaded from {self.path}; its generated objects are not in "
                             "memory (run synthesize again with the same configuration and seed)")
        check_output_directory(Path(folder), force)
        with directory_lock(folder):
            if self.kind == "artifact":
                from ..synthetic.artifact import write_artifact_tests

                path = write_artifact_tests(self.generated[0], folder, overwrite=force, seed=self.seed)
            elif self.kind == "library":
                from ..synthetic.library import write_library

                path = write_library(self.generated[0], folder, overwrite=force)
            else:
                from ..synthetic import write_campaign

                campaign, cuts = self.generated
                path = write_campaign(campaign, folder, overwrite=force)
                if cuts is not None:
                    from ..synthetic.cuts import write_cuts

                    write_cuts(cuts, path.parent, self.seed)
        self.path = path
        return path

    @classmethod
    def load(cls, folder) -> "Campaign":
        """Read a folder written by :meth:`save` (or by ``bayes-rcsa synthesize``)."""
        from ..io import read_frf

        folder = Path(folder).resolve()

        def read_json(name):
            try:
                return json.loads((folder / name).read_text(encoding="utf-8"))
            except FileNotFoundError:
                raise DataError(f"{folder}: no {name}; not written by bayes-rcsa synthesize") from None

        if (folder / "manifest.toml").is_file():
            doc = read_json("library.json")
            types = tuple(dict.fromkeys(c["holder_type"] for c in doc["combinations"]))
            return cls(kind="library", seed=doc["seed"], document=doc, holder_types=types,
                       path=folder / "manifest.toml")
        if (folder / "artifact.toml").is_file():
            doc = read_json("truth.json")
            frfs = {p.name: read_frf(p, point=p.name[1] == p.name[2]) for p in sorted(folder.glob("h[12][12]_*.csv"))}
            return cls(kind="artifact", seed=doc.get("seed"), document=doc, frfs=frfs, path=folder / "artifact.toml")
        doc = read_json("truth.json")
        try:
            setup = tomllib.loads((folder / "setup.toml").read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise DataError(f"{folder}: no setup.toml, artifact.toml or manifest.toml; not written by bayes-rcsa "
                            "synthesize") from None
        frfs = {m["file"]: read_frf(folder / m["file"]) for m in setup.get("measurement", [])}
        cuts = read_json("cuts_truth.json") if (folder / "cuts_truth.json").is_file() else None
        return cls(kind="campaign", seed=doc.get("seed"), document=doc, frfs=frfs,
                   n_spindle_files=len(setup.get("spindle", {})), cuts_truth=cuts, path=folder / "setup.toml")

    # -- pictures --------------------------------------------------------------------------------------------
    def figures(self) -> dict:
        """``{"frfs": Figure}``: |H| (m/N) of every simulated FRF over frequency (Hz); none for a library."""
        if not self.frfs:
            return {}
        from ..io.figures import finish, new_figure

        fig = new_figure(8, 5)
        ax = fig.subplots()
        for name, frf in self.frfs.items():
            ax.semilogy(frf.frequency_hz, np.abs(frf.values), lw=0.8, label=Path(name).stem)
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("|H| (m/N)")
        ax.legend(fontsize=8, ncol=2)
        ax.set_title(f"synthetic {'artifact hammer tests' if self.kind == 'artifact' else 'tool-point FRFs'} "
                     f"(seed {self.seed})", fontsize=10)
        finish(fig)
        return {"frfs": fig}


def _cut_plan(config, *, cuts, cut_length, cut_speeds, cut_depths, cut_kt, cut_kr, cut_kt_error, cut_kr_error,
              cut_flutes, cut_immersion, cut_milling, cut_feed, cut_label_noise, cut_layout):
    from ..synthetic.cuts import CutPlan

    length = config.clamping_lengths[0] if cut_length is None else float(cut_length)
    return CutPlan(n_cuts=cuts, clamping_length=length, speed_range=tuple(cut_speeds), depth_range=tuple(cut_depths),
                   kt_assumed=float(cut_kt), kr_assumed=float(cut_kr), kt_error=float(cut_kt_error),
                   kr_error=float(cut_kr_error), flutes=cut_flutes, radial_immersion=float(cut_immersion),
                   milling=cut_milling, feed=cut_feed, label_noise=float(cut_label_noise), layout=cut_layout)


def synthesize(config, *, seed: int | None = None, artifact: bool = False, cuts: int = 0,
               cut_length: float | None = None, cut_speeds: tuple[float, float] = (5000.0, 30000.0),
               cut_depths: tuple[float, float] = (1e-5, 1.5e-4), cut_kt: float = 790e6, cut_kr: float = 230e6,
               cut_kt_error: float = 0.2, cut_kr_error: float = 0.2, cut_flutes: int = 4, cut_immersion: float = 0.95,
               cut_milling: str = "down", cut_feed: str = "y", cut_label_noise: float = 0.0, cut_truth: str = "sdm",
               cut_layout: str = "random") -> Campaign:
    """Simulate impact-hammer tests with the bench's independent finite-element model.

    Parameters
    ----------
    config : path of a bench TOML file, a :class:`bayes_rcsa.synthetic.BenchConfig`, or the
        ``(BenchConfig, LibrarySpec)`` pair of :func:`bayes_rcsa.synthetic.library.load_library_config`
        (a file with a ``[library]`` table describes a tool library)
    seed : int >= 0, optional; seed of the measurement noise (default the config's ``[noise] seed``)
    artifact : bool, standard-artifact hammer tests of the bench's spindle instead (for ``identify_spindle``)
    cuts : int >= 0, also simulate this many test cuts labelled stable/chatter by the true structure
    cut_length : float, m, clamping length of the cuts (default the config's first)
    cut_speeds : (lo, hi) rpm, spindle-speed range of the cuts
    cut_depths : (lo, hi) m, axial-depth range of the cuts and of the truth map
    cut_kt, cut_kr : float, Pa, the cutting coefficients the user assumes
    cut_kt_error, cut_kr_error : float, true = assumed x (1 + error)
    cut_flutes : int; cut_immersion : radial immersion in (0, 1]; cut_milling : {"down", "up"}; cut_feed : {"x", "y"}
    cut_label_noise : float, sigma of a probit in ln(depth / limit) (0: exact labels)
    cut_truth : {"sdm", "zoa"}, stability method of the true limit
    cut_layout : {"random", "grid"}

    Returns
    -------
    Campaign
    """
    with warning_log() as log:
        from ..synthetic import generate_campaign, load_bench_config
        from ..synthetic.config import BenchConfig
        from ..synthetic.library import load_library_config

        library = None
        if isinstance(config, tuple):
            library = config
        elif not isinstance(config, BenchConfig):
            library = load_library_config(config)  # a [library] table: a tool library instead of one campaign
        if library is not None:
            if artifact or cuts:
                raise SetupError(f"{config if not isinstance(config, tuple) else '[library]'}: [library] writes a "
                                 f"tool library; it cannot be combined with {'--artifact' if artifact else '--cuts'}")
            return _library(*library, seed, log)
        config = config if isinstance(config, BenchConfig) else load_bench_config(config)
        seed = config.seed if seed is None else seed
        if seed < 0:
            raise SetupError(f"--seed {seed}: expected an integer >= 0")
        if artifact and cuts:
            raise SetupError("--cuts writes cutting tests of a tool-point campaign; it cannot be combined with "
                             "--artifact")
        if artifact:
            from ..synthetic.artifact import default_bench_artifact, generate_artifact_tests

            tests = generate_artifact_tests(config, default_bench_artifact(), np.random.default_rng(seed))
            return Campaign(kind="artifact", seed=seed, document=_plain({**tests.truth, "seed": int(seed)}),
                            frfs={frf.source: frf for frf in tests.frfs.values()}, warnings=tuple(log),
                            generated=(tests,))
        cut_campaign = None
        if cuts:  # before the hammer tests: a bad cut option costs nothing
            from ..synthetic.cuts import cuts_truth_document, generate_cuts

            plan = _cut_plan(config, cuts=cuts, cut_length=cut_length, cut_speeds=cut_speeds, cut_depths=cut_depths,
                             cut_kt=cut_kt, cut_kr=cut_kr, cut_kt_error=cut_kt_error, cut_kr_error=cut_kr_error,
                             cut_flutes=cut_flutes, cut_immersion=cut_immersion, cut_milling=cut_milling,
                             cut_feed=cut_feed, cut_label_noise=cut_label_noise, cut_layout=cut_layout)
            truth = {}
            if cut_truth == "sdm":
                from ..cuts.truth import SDM_TRUTH, sdm_true_limit

                truth = {"true_limit": sdm_true_limit(plan), "truth_method": SDM_TRUTH}
            elif cut_truth != "zoa":
                raise SetupError(f"cut_truth {cut_truth!r}: expected 'sdm' or 'zoa'")
            # the cuts' own stream (seed + 1 spawned) so that cuts do not change the hammer-test noise
            cut_campaign = generate_cuts(config, plan, np.random.default_rng([seed, 23]), **truth)
        campaign = generate_campaign(config, np.random.default_rng(seed))
        campaign = replace(campaign, truth={**campaign.truth, "seed": seed})
        return Campaign(
            kind="campaign", seed=seed, document=_plain(campaign.truth),
            frfs={frf.source: frf for _, frf in campaign.measurements}, n_spindle_files=len(campaign.spindle),
            cuts_truth=None if cut_campaign is None else _plain(cuts_truth_document(cut_campaign, seed)),
            warnings=tuple(log), generated=(campaign, cut_campaign))


def _plain(document: dict) -> dict:
    """``document`` as its JSON file reads back (lists, not tuples or arrays)."""
    from ..io.jsonable import dumps_strict

    return json.loads(dumps_strict(document))


def _library(base, spec, seed, log) -> Campaign:
    """A whole synthetic tool library (a ``[library]`` table)."""
    from ..synthetic.library import generate_library

    seed = base.seed if seed is None else seed
    library = generate_library(spec, base, seed)
    return Campaign(kind="library", seed=seed, document=_plain(library.record()),
                    holder_types=tuple(spec.holder_types), warnings=tuple(log), generated=(library,))


def _effects(hidden: dict) -> str:
    """The bench's hidden effects in words (``tip_mass=0.005`` -> ``mass at the tool tip = 0.005``)."""
    from ..units import num
    from ..vocabulary import EFFECTS, effect_name, parameter_name

    return ", ".join(f"{effect_name(k) if k in EFFECTS else parameter_name(k)} = {num(v)}" for k, v in hidden.items())
