"""The batch manifest: which setups of a tool library to run, and with which options.

A manifest is a TOML file (format in docs/data-formats.md and docs/scaling-out.md)::

    [defaults]                      # optional; every [[setup]] key except name and file
    method = "multi"
    lengths = [0.025, 0.040]
    [defaults.predict]
    lengths = [0.025, 0.030, 0.035, 0.040]
    [defaults.lobes]
    clamping_length = 0.030
    flutes = 4
    kt = "790e6"
    kr = "230e6"
    immersion = 0.95
    speeds = "5000:30000:400"

    [[setup]]
    name = "er32_d8"                 # unique; the setup's directory under --out
    file = "er32_d8/setup.toml"      # relative to the manifest
    seed = 3

Each setup becomes three ordinary commands (``identify``, ``predict``,
``lobes``; the last two are left out with ``predict = false`` /
``lobes = false``, and ``lobes`` also when it has no cutting conditions).
Their argument lists are built here and nowhere else, so a batch run computes
exactly what the same commands typed by hand compute.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
from pathlib import Path

from .. import messages
from ..errors import DataWarning, SetupError
from ..inference.identify import SAMPLERS
from ..inference.problem import METHODS
from ..io.tables import TableContext, did_you_mean, is_number, load_document

__all__ = ["SetupJob", "load_manifest", "IDENTIFY_KEYS", "PREDICT_KEYS", "LOBES_KEYS"]

#: Identification options of a setup (``bayes-rcsa identify`` options of the same name).
IDENTIFY_KEYS = {"method", "seed", "lengths", "sampler", "max_steps", "walkers", "check_every", "ess_min", "band",
                 "plots"}
#: Keys of a ``predict`` table (``bayes-rcsa predict`` options); ``seed`` defaults to the setup's seed.
PREDICT_KEYS = {"lengths", "directions", "tool", "freq", "max_draws", "seed", "plots"}
#: Keys of a ``lobes`` table (``bayes-rcsa lobes`` options of the posterior mode); ``seed`` as for predict.
LOBES_KEYS = {"clamping_length", "draws", "seed", "flutes", "kt", "kr", "allow_unusual", "immersion", "angles",
              "milling", "feed", "pitch", "speeds", "max_depth", "flute_length", "speed_tolerance", "depth_margin",
              "depth_points", "method", "intervals", "max_modes", "level", "budget", "tests", "plots"}
_SETUP_KEYS = {"name", "file", "predict", "lobes"} | IDENTIFY_KEYS
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")
# options whose values are file names: relative to the manifest, like ``file``
_PATH_KEYS = {"tests"}


@dataclasses.dataclass(frozen=True)
class SetupJob:
    """One setup of the manifest: its name and the commands that process it.

    Attributes
    ----------
    name : str
        Unique name; the setup's results go to ``OUT/setups/<name>/``.
    setup_file : Path
        Absolute path of the setup TOML.
    seed : int
    commands : tuple of (step, argv) pairs
        ``step`` is ``"identify"``, ``"predict"`` or ``"lobes"``; ``argv`` the
        command's argument list with ``{dir}`` standing for the setup's output
        directory (filled in by :meth:`argv`).
    """

    name: str
    setup_file: Path
    seed: int
    commands: tuple[tuple[str, tuple[str, ...]], ...]

    def argv(self, step: str, setup_dir) -> list[str]:
        """Argument list of ``step`` writing under ``setup_dir``."""
        for s, argv in self.commands:
            if s == step:
                return [a.replace("{dir}", str(setup_dir)) for a in argv]
        raise KeyError(step)

    @property
    def steps(self) -> tuple[str, ...]:
        return tuple(s for s, _ in self.commands)

    def fingerprint(self) -> str:
        """Digest of the commands and the setup file's bytes: a finished result is reused only while both match.

        The measurement files the setup names are not hashed (they can be
        large); replacing them under the same names needs ``--force``.
        """
        h = hashlib.sha256(json.dumps([self.name, self.commands], sort_keys=True).encode())
        try:
            h.update(self.setup_file.read_bytes())
        except OSError:
            h.update(b"<unreadable>")
        return h.hexdigest()


def _value(ctx: TableContext, where: str, key: str, v) -> str:
    """A manifest value as the command-line text of its option."""
    if isinstance(v, bool):
        raise ctx.bad(where, key, v, "a number, a string or a list")
    if is_number(v):
        return repr(v) if isinstance(v, float) else str(v)
    if isinstance(v, str) and v.strip():
        return v
    if isinstance(v, list) and v and all(is_number(x) or isinstance(x, str) for x in v):
        return ",".join(repr(x) if isinstance(x, float) else str(x) for x in v)
    raise ctx.bad(where, key, v, "a number, a non-empty string or a non-empty list of numbers")


def _options(ctx: TableContext, where: str, table: dict, allowed: set[str], skip: set[str] = frozenset()) -> list[str]:
    """``--key value`` pairs (``--key`` alone for ``true``) for the keys of ``table``, in sorted order."""
    argv: list[str] = []
    for key in sorted(table):
        if key in skip:
            continue
        if key not in allowed:
            raise ctx.error(where, f"unknown key {key!r}{did_you_mean(key, allowed)}")
        v = table[key]
        opt = "--" + key.replace("_", "-")
        if key == "plots":
            if not isinstance(v, bool):
                raise ctx.bad(where, key, v, "true or false")
            if not v:
                argv.append("--no-plots")
            continue
        if isinstance(v, bool):
            if v:
                argv.append(opt)
            continue
        text = _value(ctx, where, key, v)
        if key in _PATH_KEYS:
            text = str(ctx.resolve(text))
        argv += [opt, text]
    return argv


def _sub_table(ctx: TableContext, where: str, entry: dict, defaults: dict, key: str) -> dict | None:
    """``defaults[key]`` updated by ``entry[key]``; ``None`` when switched off (``key = false``, the entry's word first)."""
    for src, label in ((entry, where), (defaults, "[defaults]")):
        v = src.get(key)
        if v is not None and v is not False and not isinstance(v, dict):
            raise ctx.bad(label, key, v, "a table of options, or false")
    if entry.get(key) is False or (key not in entry and defaults.get(key) is False):
        return None
    merged = dict(defaults.get(key) or {})
    merged.update(entry.get(key) or {})
    return merged


def _inside(path: Path, folder: Path) -> bool:
    """Whether ``path`` lies in ``folder`` or below, symbolic links followed (``..`` and links out count as outside)."""
    try:
        return path.resolve().is_relative_to(folder.resolve())
    except OSError:
        return False


def load_manifest(path) -> tuple[SetupJob, ...]:
    """Read a manifest and build every setup's commands; refuse anything unknown before anything runs.

    Parameters
    ----------
    path : path-like, the manifest TOML

    Returns
    -------
    tuple of SetupJob, in manifest order

    Raises
    ------
    SetupError
        Unknown tables or keys (with a suggestion), missing ``name``/``file``,
        duplicate or unusable names, setup files that do not exist or are no TOML document, values of
        the wrong type.  The commands check the values themselves when they
        run (a bad value fails that setup only).

    Warns
    -----
    DataWarning
        A setup file outside the manifest's folder (``file = "../x/setup.toml"``, an absolute path or a
        symbolic link out of it): allowed, named once per setup.
    """
    path = Path(path)
    doc = load_document(path, "batch manifest")
    ctx = TableContext(path)
    for key in doc:
        if key not in ("defaults", "setup"):
            raise ctx.error(f"[{key}]", f"unknown table{did_you_mean(key, ('defaults', 'setup'))}; a manifest has "
                                        "[defaults] and [[setup]] entries")
    defaults = doc.get("defaults", {})
    if not isinstance(defaults, dict):
        raise ctx.error("[defaults]", "expected a table")
    for key in defaults:
        if key in ("name", "file") or key not in _SETUP_KEYS:
            raise ctx.error("[defaults]", f"unknown key {key!r}{did_you_mean(key, _SETUP_KEYS - {'name', 'file'})}")
    entries = doc.get("setup")
    if not isinstance(entries, list) or not entries or not all(isinstance(e, dict) for e in entries):
        raise ctx.error("[[setup]]", "expected at least one [[setup]] entry with name and file")
    jobs, seen = [], set()
    for i, entry in enumerate(entries):
        where = f"[[setup]] #{i + 1}"
        for key in ("name", "file"):
            if not isinstance(entry.get(key), str) or not entry[key].strip():
                raise ctx.missing(where, key, "a non-empty string")
        name = entry["name"]
        where = f"[[setup]] {name!r}"
        if not _NAME.match(name):
            raise ctx.bad(where, "name", name, "letters, digits, '.', '_' or '-' (it names a directory)")
        if name in seen:
            raise ctx.error(where, "duplicate name")
        seen.add(name)
        for key in entry:
            if key not in _SETUP_KEYS:
                raise ctx.error(where, f"unknown key {key!r}{did_you_mean(key, _SETUP_KEYS)}")
        setup_file = ctx.resolve(entry["file"])
        if not setup_file.is_file():
            raise ctx.bad(where, "file", entry["file"], f"an existing setup file ({setup_file} not found)")
        try:
            # a file that is no TOML document at all (the entry names the wrong file) is refused here, before any
            # setup folder is made, like a missing one; what the setup holds is checked when it runs
            load_document(setup_file)
        except SetupError as exc:
            raise ctx.bad(where, "file", entry["file"], f"a setup file (TOML); {exc}") from None
        if not _inside(setup_file, path.absolute().parent):
            # policy (docs/scaling-out.md, "Setup files outside the manifest's folder"): allowed, with a warning
            messages.warn(f"{path}: {where} file = {entry['file']!r} lies outside the manifest's folder "
                          f"({setup_file}); it is used, but moving or copying the library folder will not take it "
                          "along, and on a cluster every worker must see it under the same path", DataWarning,
                          stacklevel=2)
        ident = {k: v for k, v in {**defaults, **entry}.items() if k in IDENTIFY_KEYS}
        seed = ident.get("seed", 0)
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ctx.bad(where, "seed", seed, "an integer >= 0")
        ident["seed"] = seed
        # the words identify accepts, checked here so that a misspelt value stops the batch before any setup runs
        # (it was refused only when that setup's identify step ran, after others had been computed)
        for key, allowed in (("method", METHODS), ("sampler", SAMPLERS)):
            if key in ident and ident[key] not in allowed:
                raise ctx.bad(where, key, ident[key], " or ".join(repr(a) for a in allowed))
        method = ident.get("method", "multi")
        setup = str(setup_file)
        commands = [("identify", ("identify", setup, "--out", "{dir}/identify", "--quiet",
                                  *_options(ctx, where, ident, IDENTIFY_KEYS)))]
        posterior = "{dir}/identify/posterior.nc"
        predict = _sub_table(ctx, where, entry, defaults, "predict")
        lobes = _sub_table(ctx, where, entry, defaults, "lobes")
        if method == "deterministic" and (predict or lobes):
            raise ctx.error(where, "predict and lobes need a posterior: method 'deterministic' has none "
                                   "(set predict = false and lobes = false)")
        if predict is not None:
            predict.setdefault("seed", seed)
            commands.append(("predict", ("predict", setup, "--posterior", posterior, "--out", "{dir}/predict",
                                         "--quiet", *_options(ctx, f"{where} predict", predict, PREDICT_KEYS))))
        if lobes:  # an empty table has no cutting conditions: nothing to compute
            lobes.setdefault("seed", seed)
            commands.append(("lobes", ("lobes", setup, "--posterior", posterior, "--out", "{dir}/lobes", "--quiet",
                                       *_options(ctx, f"{where} lobes", lobes, LOBES_KEYS))))
        jobs.append(SetupJob(name, setup_file, seed, tuple(commands)))
    return tuple(jobs)
