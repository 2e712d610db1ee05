"""A synthetic tool library: many holder-tool combinations, each a full bench campaign (issue #20).

A library has several holder types (:mod:`bayes_rcsa.synthetic.library_population`); each holds
several carbide tools of 6-20 mm shank diameter, and every combination's true contact law is drawn
from its holder type's population (medians depending on the shank diameter).  Each combination is
an ordinary bench campaign (:func:`bayes_rcsa.synthetic.generate_campaign`: the finite-element
bench, its noise and every hidden effect) with hammer tests at a few clamping lengths.  One or
more combinations can be made *special*: a contact ``softer`` times softer than its population (a
badly clamped tool) and/or hidden effects of its own.

:func:`write_library` writes::

    DIR/manifest.toml            the `bayes-rcsa batch` / `bayes-rcsa library` manifest
    DIR/library.json             populations, combinations and their true laws
    DIR/<name>/setup.toml        with [holder] type = "<holder type>"
    DIR/<name>/tip_x_25mm.csv ... and spindle_x.csv
    DIR/<name>/truth.json        the campaign's truth plus "library" (true law, population median,
                                 specials) and "tool_point_frequencies" (noise-free dominant
                                 frequency at every length of ``truth_lengths``)

``bayes-rcsa synthesize CONFIG --out DIR`` writes a library when CONFIG has a ``[library]`` table
(docs/synthetic.md, "Tool libraries").
"""

from __future__ import annotations

import dataclasses
import math
import re
import shutil
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import SetupError
from ..model.assembly import Configuration
from ..model.geometry import ToolSegment
from ..model.natural_frequencies import natural_frequency
from .campaign import Campaign, _replace_dir, generate_campaign, measured_mean_frf, write_campaign
from .config import BenchConfig, _from_dict, default_bench_config
from .effects import normalise_effects
from .library_population import (D_REF, GROWTH_CEILING, HOLDER_TYPES, LAW_NAMES, HolderPopulation, LawPopulation,
                                 draw_law, median_law)

__all__ = ["Special", "LibrarySpec", "Combination", "Library", "LIBRARY_FORMAT", "DAMPING_MODES",
           "generate_library", "write_library", "load_library_config", "library_base_config"]

LIBRARY_FORMAT = "bayes_rcsa.synthetic.library/1"
#: How the user's setup states the contact damping: the combination's true value (fixed, as the
#: single-campaign bench does) or a broad common log-uniform prior (sampled).
DAMPING_MODES = ("fixed", "sampled")
#: Broad common damping priors of ``damping = "sampled"`` (N s/m, N m s/rad).
SAMPLED_DAMPING = {"translational_damping": [0.5, 500.0], "rotational_damping": [1e-5, 1e-1]}
_DIAMETER_RANGE = (0.006, 0.020)
# bench fields a library sets per combination: a [holder], [tool], [contact] or [campaign] table in a
# library configuration would be overwritten, so it is refused rather than silently ignored
_PER_COMBINATION_TABLES = ("holder", "tool", "contact", "campaign")


@dataclass(frozen=True)
class Special:
    """A combination that departs from its population.

    Attributes
    ----------
    combination : int
        0-based index in manifest order.
    softer : float
        >= 1: k_xf and k_thetaM are this many times smaller than the drawn law (3 = "3x softer").
    hidden_effects : dict of str to float
        Bench hidden effects of this combination only (added to the library's own).
    """

    combination: int
    softer: float = 1.0
    hidden_effects: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "hidden_effects", normalise_effects(self.hidden_effects, "special.hidden_effects"))
        if isinstance(self.combination, bool) or not isinstance(self.combination, int) or self.combination < 0:
            raise SetupError(f"special combination = {self.combination!r}: expected an integer >= 0")
        if isinstance(self.softer, bool) or not isinstance(self.softer, (int, float)) or not (
                math.isfinite(self.softer) and self.softer >= 1):
            raise SetupError(f"special softer = {self.softer!r}: expected a finite number >= 1 (3 = 3x softer contact)")
        if self.softer == 1 and not self.hidden_effects:
            raise SetupError(f"special combination {self.combination}: expected softer > 1 or hidden_effects")


@dataclass(frozen=True)
class LibrarySpec:
    """What a synthetic library contains (everything else comes from the base :class:`BenchConfig`).

    Attributes
    ----------
    holder_types : tuple of str
        Names of ``populations``; at least one.
    per_type : int
        Combinations per holder type.
    diameters : tuple of float, m
        Shank-diameter catalogue, each within 6-20 mm; every holder type cycles through a random
        permutation of it.
    clamping_lengths : tuple of float, m
        Hammer-test lengths of every combination.
    truth_lengths : tuple of float, m
        Lengths of the true dominant tool-point frequencies in truth.json.
    clamping_range : (l_a, l_b) m
        Feasible range of the law (reference length l_a); contains both length lists.
    tool_length : (a, b)
        Tool total length ``a + b d`` (m) for shank diameter ``d``.
    flute_fraction, flute_ratio : float
        Fluted tip segment: this fraction of the tool length, effective diameter ratio.
    damping : {"fixed", "sampled"}
        See :data:`DAMPING_MODES`.
    specials : tuple of Special
    identify : dict
        ``bayes-rcsa identify`` options for the manifest's ``[defaults]`` (walkers, max_steps, ...).
    populations : dict of str to HolderPopulation
    """

    holder_types: tuple[str, ...] = tuple(HOLDER_TYPES)
    per_type: int = 4
    diameters: tuple[float, ...] = (0.006, 0.008, 0.010, 0.012, 0.016, 0.020)
    clamping_lengths: tuple[float, ...] = (0.025, 0.035, 0.045)
    truth_lengths: tuple[float, ...] = (0.020, 0.025, 0.030, 0.035, 0.040, 0.045)
    clamping_range: tuple[float, float] = (0.020, 0.045)
    tool_length: tuple[float, float] = (0.080, 2.0)
    flute_fraction: float = 0.35
    flute_ratio: float = 0.80
    damping: str = "fixed"
    specials: tuple[Special, ...] = ()
    identify: Mapping[str, Any] = field(default_factory=dict)
    populations: Mapping[str, HolderPopulation] = field(default_factory=lambda: dict(HOLDER_TYPES))

    def __post_init__(self) -> None:
        s = object.__setattr__
        for key in ("holder_types", "diameters", "clamping_lengths", "truth_lengths", "clamping_range",
                    "tool_length", "specials"):
            s(self, key, tuple(getattr(self, key)))
        s(self, "identify", dict(self.identify))
        s(self, "populations", dict(self.populations))
        if not self.holder_types or len(set(self.holder_types)) != len(self.holder_types):
            raise SetupError(f"library holder_types = {list(self.holder_types)!r}: expected distinct names")
        for t in self.holder_types:
            if t not in self.populations:
                raise SetupError(f"library holder type {t!r}: no population; known: {sorted(self.populations)}")
        if isinstance(self.per_type, bool) or not isinstance(self.per_type, int) or self.per_type < 1:
            raise SetupError(f"library per_type = {self.per_type!r}: expected an integer >= 1")
        lo, hi = _DIAMETER_RANGE
        if not self.diameters or any(not (lo - 1e-12 <= d <= hi + 1e-12) for d in self.diameters):
            raise SetupError(f"library diameters = {list(self.diameters)!r}: expected values within "
                             f"[{lo!r}, {hi!r}] m (6-20 mm)")
        la, lb = self.clamping_range
        if not (0 < la < lb):
            raise SetupError(f"library clamping_range = {list(self.clamping_range)!r}: expected 0 < l_a < l_b (m)")
        for key in ("clamping_lengths", "truth_lengths"):
            v = getattr(self, key)
            if not v or len(set(v)) != len(v) or any(not (la - 1e-12 <= x <= lb + 1e-12) for x in v):
                raise SetupError(f"library {key} = {list(v)!r}: expected distinct lengths within clamping_range "
                                 f"{list(self.clamping_range)!r} m")
        if self.damping not in DAMPING_MODES:
            raise SetupError(f"library damping = {self.damping!r}: expected one of {DAMPING_MODES}")
        if not (0 < self.flute_fraction < 1 and 0 < self.flute_ratio <= 1):
            raise SetupError(f"library flute_fraction = {self.flute_fraction!r}, flute_ratio = {self.flute_ratio!r}: "
                             "expected 0 < fraction < 1 and 0 < ratio <= 1")
        n = self.n_combinations
        seen = set()
        for sp in self.specials:
            if sp.combination >= n:
                raise SetupError(f"special combination = {sp.combination}: expected an index below the library's "
                                 f"{n} combinations")
            if sp.combination in seen:
                raise SetupError(f"special combination = {sp.combination}: listed twice")
            seen.add(sp.combination)

    @property
    def n_combinations(self) -> int:
        return len(self.holder_types) * self.per_type


@dataclass(frozen=True)
class Combination:
    """One holder-tool combination of a library.

    Attributes
    ----------
    name : str
        Unique; its directory and manifest name.
    holder_type : str
    diameter : float, m
    law : dict of str to float
        The true law (after ``softer``), names of :data:`~.library_population.LAW_NAMES`.
    population_median : dict of str to float
        The population median for this holder type and diameter.
    z : dict of str to float
        Standard-normal deviates of the draw.
    special : Special or None
    campaign : Campaign
    """

    name: str
    holder_type: str
    diameter: float
    law: dict
    population_median: dict
    z: dict
    special: Special | None
    campaign: Campaign

    def record(self) -> dict:
        """JSON-able summary (truth.json ``library`` and library.json ``combinations``)."""
        sp = self.special
        return {"name": self.name, "holder_type": self.holder_type, "diameter": self.diameter,
                "law": dict(self.law), "population_median": dict(self.population_median), "z": dict(self.z),
                "softer": 1.0 if sp is None else sp.softer,
                "hidden_effects": dict(self.campaign.truth["hidden_effects"]),
                "special": sp is not None}


@dataclass(frozen=True)
class Library:
    """A generated library: its combinations (manifest order), spec, base configuration and seed."""

    combinations: tuple[Combination, ...]
    spec: LibrarySpec
    base: BenchConfig
    seed: int

    def record(self) -> dict:
        """library.json: populations, settings and every combination's truth."""
        pops = {t: {"laws": {n: dataclasses.asdict(p) for n, p in self.spec.populations[t].laws.items()},
                    "holder": {"flange": list(self.spec.populations[t].flange),
                               "nose_length": self.spec.populations[t].nose_length,
                               "nose_outer": list(self.spec.populations[t].nose_outer)}}
                for t in self.spec.holder_types}
        return {
            "format": LIBRARY_FORMAT, "seed": self.seed, "reference_diameter": D_REF,
            "growth_ceiling": GROWTH_CEILING, "clamping_range": list(self.spec.clamping_range),
            "clamping_lengths": list(self.spec.clamping_lengths), "truth_lengths": list(self.spec.truth_lengths),
            "damping": self.spec.damping, "populations": pops,
            "population_model": {
                "stiffness_and_damping": "ln v = ln ref + slope ln(d / reference_diameter) + spread z",
                "growth": "g = growth_ceiling expit(logit(ref / growth_ceiling) + spread z)",
                "z": "independent standard normal per parameter and combination",
            },
            "combinations": [c.record() for c in self.combinations],
        }

    def manifest(self) -> dict:
        """The batch manifest (TOML-able dict): one ``[[setup]]`` per combination, identify only."""
        defaults = {"method": "multi", **self.spec.identify, "predict": False, "lobes": False}
        defaults.pop("seed", None)
        base_seed = int(self.spec.identify.get("seed", 0))
        return {"defaults": defaults,
                "setup": [{"name": c.name, "file": f"{c.name}/setup.toml", "seed": base_seed + i}
                          for i, c in enumerate(self.combinations)]}


def library_base_config(**overrides) -> BenchConfig:
    """The bench defaults of a library: x only, 300-2600 Hz in 4 Hz lines, growth bound 1.

    The band holds the dominant (contact) mode of every built-in holder type and diameter at
    20-45 mm; x only and 4 Hz lines keep stage 1 (an identify per combination) affordable.
    """
    kw = {"directions": ("x",), "frequency_start": 300.0, "frequency_stop": 2600.0, "frequency_step": 4.0,
          "growth_bound": GROWTH_CEILING}
    kw.update(overrides)
    return default_bench_config(**kw)


def _slug(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9._-]+", "_", text).strip("._-")
    return s or "holder"


def _mm(d: float) -> str:
    mm = round(d * 1e3, 3)
    return (f"{mm:g}").replace(".", "p")


def _combination_config(base: BenchConfig, spec: LibrarySpec, pop: HolderPopulation, diameter: float, law: dict,
                        special: Special | None) -> BenchConfig:
    a, b = spec.tool_length
    length = a + b * diameter
    soft = 1.0 if special is None else special.softer
    effects = {**base.hidden_effects, **({} if special is None else special.hidden_effects)}
    clamps = tuple(spec.clamping_lengths)
    return dataclasses.replace(
        base,
        name=f"synthetic {pop.name} holder + {diameter * 1e3:g} mm carbide end mill",
        holder_segments=pop.holder_segments(diameter),
        tool_total_length=length,
        tool_segments=(ToolSegment(spec.flute_fraction * length, diameter, spec.flute_ratio),
                       ToolSegment((1 - spec.flute_fraction) * length, diameter, 1.0)),
        k_xf=law["k_xf"] / soft, k_thetaM=law["k_thetaM"] / soft, growth=law["g_xf"], growth_thetaM=law["g_thetaM"],
        c_xf=law["c_xf"], c_thetaM=law["c_thetaM"], clamping_range=tuple(spec.clamping_range),
        clamping_lengths=clamps, hidden_effects=effects,
    )


def _tool_point_frequencies(config: BenchConfig, lengths) -> list[dict]:
    """Noise-free dominant tool-point frequency (the project's natural-frequency rule) at each length."""
    f = config.frequency_hz
    out = []
    for d in config.directions:
        for cl in lengths:
            h = measured_mean_frf(config, Configuration(float(cl), d, "tool"), f)
            fn = float(natural_frequency(f, h))
            out.append({"clamping_length": float(cl), "direction": d,
                        "dominant_frequency_hz": None if not math.isfinite(fn) else fn})
    return out


def generate_library(spec: LibrarySpec, base: BenchConfig | None = None, seed: int = 0) -> Library:
    """Draw a library's laws and simulate every combination's campaign.

    Parameters
    ----------
    spec : LibrarySpec
    base : BenchConfig, optional
        Materials, spindle, frequency grid, noise, hidden-effect options and library-wide hidden
        effects; default :func:`library_base_config`.
    seed : int >= 0
        ``numpy.random.SeedSequence(seed)`` spawns one stream for the diameters and laws and one per
        combination for its measurement noise, so a combination's data do not change when another
        is made special.

    Returns
    -------
    Library
    """
    base = library_base_config() if base is None else base
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise SetupError(f"library seed = {seed!r}: expected an integer >= 0")
    ss = np.random.SeedSequence(seed)
    law_seq, *noise_seqs = ss.spawn(1 + spec.n_combinations)
    rng = np.random.default_rng(law_seq)
    specials = {s.combination: s for s in spec.specials}
    combos = []
    catalogue = np.asarray(spec.diameters, dtype=float)
    for t in spec.holder_types:
        pop = spec.populations[t]
        order = rng.permutation(catalogue.size)
        for j in range(spec.per_type):
            i = len(combos)
            d = float(catalogue[order[j % catalogue.size]])
            law, z = draw_law(pop, d, rng)
            special = specials.get(i)
            config = _combination_config(base, spec, pop, d, law, special)
            campaign = generate_campaign(config, np.random.default_rng(noise_seqs[i]))
            name = f"{_slug(t)}_d{_mm(d)}_{j + 1}"
            setup = dict(campaign.setup)
            setup["holder"] = {"type": t, **setup["holder"]}
            if spec.damping == "sampled":
                setup["contact"] = {**setup["contact"], **SAMPLED_DAMPING}
            soft = 1.0 if special is None else special.softer
            true_law = {**law, "k_xf": law["k_xf"] / soft, "k_thetaM": law["k_thetaM"] / soft}
            combo = Combination(name, t, d, true_law, median_law(pop, d), z, special, campaign)
            truth = {**campaign.truth, "seed": seed, "library": combo.record(),
                     "tool_point_frequencies": _tool_point_frequencies(config, spec.truth_lengths)}
            combos.append(dataclasses.replace(combo, campaign=dataclasses.replace(campaign, setup=setup, truth=truth)))
    names = [c.name for c in combos]
    if len(set(names)) != len(names):  # two holder types with the same slug
        raise SetupError(f"library combination names collide: {names}; rename the holder types")
    return Library(tuple(combos), spec, base, seed)


def write_library(library: Library, out_dir, overwrite: bool = False) -> Path:
    """Write a library as one directory, atomically (see the module docstring).

    Returns
    -------
    Path
        ``DIR/manifest.toml``.
    """
    from ..io.atomic import begin_directory
    from ..io.jsonable import dumps_strict
    from ..io.toml_writer import dump_toml

    out_dir, tmp = begin_directory(out_dir, overwrite)
    try:
        for combo in library.combinations:
            write_campaign(combo.campaign, tmp / combo.name)
        (tmp / "manifest.toml").write_text(
            "# Synthetic tool library (bayes_rcsa.synthetic.library): one [[setup]] per holder-tool combination.\n"
            "# Read by `bayes-rcsa batch` and `bayes-rcsa library`; the truth is in library.json and */truth.json.\n"
            + dump_toml(library.manifest()), encoding="utf-8")
        (tmp / "library.json").write_text(
            dumps_strict(library.record(), nonfinite="error", indent=2, sort_keys=True) + "\n", encoding="utf-8")
        _replace_dir(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out_dir / "manifest.toml"


# ------------------------------------------------------------------ TOML --

_LIBRARY_KEYS = {"holder_types", "per_type", "diameters", "clamping_lengths", "truth_lengths", "clamping_range",
                 "tool_length", "flute_fraction", "flute_ratio", "damping", "special", "identify", "population"}


def load_library_config(path) -> tuple[BenchConfig, LibrarySpec] | None:
    """Read a bench configuration TOML with a ``[library]`` table; ``None`` if it has none.

    The tables other than ``[library]`` are the bench's (docs/synthetic.md) with the defaults of
    :func:`library_base_config`; ``[holder]``, ``[tool]``, ``[contact]`` and ``[campaign]`` are set per
    combination by the library and refused here.

    Raises
    ------
    SetupError
        Naming the file and the key.
    """
    path = Path(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SetupError(f"{path}: bench configuration file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SetupError(f"{path}: cannot read bench configuration ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise SetupError(f"{path}: invalid TOML: {exc}") from None
    if "library" not in doc:
        return None
    try:
        return _library_from_dict(doc)
    except SetupError as exc:
        raise SetupError(f"{path}: {exc}") from None


def _library_from_dict(doc: dict) -> tuple[BenchConfig, LibrarySpec]:
    lib = doc.pop("library")
    if not isinstance(lib, dict):
        raise SetupError(f"library = {lib!r}: expected a table [library]")
    for key in _PER_COMBINATION_TABLES:
        if key in doc:
            raise SetupError(f"[{key}]: not allowed with [library] (each combination's {key} comes from its holder "
                             "type and diameter; see docs/synthetic.md, Tool libraries)")
    unknown = sorted(set(lib) - _LIBRARY_KEYS)
    if unknown:
        raise SetupError(f"[library]: unknown key(s) {unknown}; known keys: {sorted(_LIBRARY_KEYS)}")
    defaults = library_base_config()
    doc.setdefault("campaign", {"directions": list(defaults.directions)})
    freq = doc.setdefault("frequency", {})
    if isinstance(freq, dict):
        for key, fname in (("start", "frequency_start"), ("stop", "frequency_stop"), ("step", "frequency_step")):
            freq.setdefault(key, getattr(defaults, fname))
    prior = doc.setdefault("prior", {})
    if isinstance(prior, dict):
        prior.setdefault("growth_bound", defaults.growth_bound)
    base = _from_dict(doc)
    kw: dict[str, Any] = {}
    for key in ("holder_types",):
        if key in lib:
            kw[key] = tuple(_strings(lib[key], f"library.{key}"))
    if "per_type" in lib:
        v = lib["per_type"]
        if isinstance(v, bool) or not isinstance(v, int):
            raise SetupError(f"library.per_type = {v!r}: expected an integer >= 1")
        kw["per_type"] = v
    for key in ("diameters", "clamping_lengths", "truth_lengths", "clamping_range", "tool_length"):
        if key in lib:
            kw[key] = tuple(_numbers(lib[key], f"library.{key}"))
    for key in ("clamping_range", "tool_length"):
        if key in kw and len(kw[key]) != 2:
            raise SetupError(f"library.{key} = {lib[key]!r}: expected a pair")
    for key in ("flute_fraction", "flute_ratio"):
        if key in lib:
            kw[key] = _numbers([lib[key]], f"library.{key}")[0]
    if "damping" in lib:
        kw["damping"] = lib["damping"]
    if "identify" in lib:
        if not isinstance(lib["identify"], dict):
            raise SetupError(f"library.identify = {lib['identify']!r}: expected a table of identify options")
        kw["identify"] = dict(lib["identify"])
    if "population" in lib:
        kw["populations"] = _populations(lib["population"])
    if "special" in lib:
        kw["specials"] = tuple(_special(s, i) for i, s in enumerate(_list(lib["special"], "library.special")))
    return base, LibrarySpec(**kw)


def _list(v, where):
    if not isinstance(v, list) or not v:
        raise SetupError(f"{where} = {v!r}: expected a non-empty array")
    return v


def _strings(v, where):
    v = _list(v, where)
    if not all(isinstance(x, str) and x.strip() for x in v):
        raise SetupError(f"{where} = {v!r}: expected an array of non-empty strings")
    return v


def _numbers(v, where):
    v = _list(v, where)
    if not all(not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x) for x in v):
        raise SetupError(f"{where} = {v!r}: expected finite numbers")
    return [float(x) for x in v]


def _special(entry, i) -> Special:
    where = f"library.special[{i}]"
    if not isinstance(entry, dict):
        raise SetupError(f"{where}: expected a table {{ combination, softer, hidden_effects }}")
    unknown = sorted(set(entry) - {"combination", "softer", "hidden_effects"})
    if unknown:
        raise SetupError(f"{where}: unknown key(s) {unknown}; known keys: ['combination', 'hidden_effects', 'softer']")
    if "combination" not in entry:
        raise SetupError(f"{where}: missing key 'combination' (0-based index in manifest order)")
    effects = entry.get("hidden_effects", {})
    if not isinstance(effects, dict):
        raise SetupError(f"{where}.hidden_effects = {effects!r}: expected a table name = magnitude")
    try:
        return Special(entry["combination"], entry.get("softer", 1.0), normalise_effects(effects, f"{where}.hidden_effects"))
    except SetupError as exc:
        raise SetupError(f"{where}: {exc}") from None


def _populations(tables) -> dict[str, HolderPopulation]:
    """``[library.population.<type>]``: a built-in type's parameters replaced, or a new type based on one."""
    if not isinstance(tables, dict):
        raise SetupError("library.population: expected tables [library.population.<holder type>]")
    pops = dict(HOLDER_TYPES)
    for name, tbl in tables.items():
        where = f"library.population.{name}"
        if not isinstance(tbl, dict):
            raise SetupError(f"{where}: expected a table")
        like = tbl.get("like", name)
        if like not in HOLDER_TYPES:
            raise SetupError(f"{where}: like = {like!r}: expected a built-in holder type {sorted(HOLDER_TYPES)}")
        unknown = sorted(set(tbl) - set(LAW_NAMES) - {"like"})
        if unknown:
            raise SetupError(f"{where}: unknown key(s) {unknown}; known keys: {['like', *LAW_NAMES]}")
        laws = {}
        for law, value in tbl.items():
            if law == "like":
                continue
            if not isinstance(value, dict) or not set(value) <= {"ref", "slope", "spread"}:
                raise SetupError(f"{where}.{law} = {value!r}: expected a table {{ ref, slope, spread }}")
            laws[law] = dataclasses.replace(HOLDER_TYPES[like].laws[law],
                                            **{k: _numbers([v], f"{where}.{law}.{k}")[0] for k, v in value.items()})
        pops[name] = dataclasses.replace(HOLDER_TYPES[like].replace(**laws), name=name)
    return pops
