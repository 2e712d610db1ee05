"""Crash-safe HDF5 checkpoint of an emcee run, in emcee's HDFBackend layout.

The chain is written in the group ``mcmc`` exactly as
:class:`emcee.backends.HDFBackend` writes it (datasets ``chain``,
``log_prob``, ``accepted``; attributes ``iteration``, ``nwalkers``,
``ndim``, ``random_state_*``), so ``emcee.backends.HDFBackend(path,
read_only=True)`` reads a checkpoint directly.  The group ``bayes_rcsa``
holds the run's fingerprint (refusing to resume a different run) and the
results of the start-up stage (optimum, tempering), so a resumed run skips
the optimiser and continues bit for bit.

Why not emcee's backend as is: it opens and closes the file for every
step, which costs several milliseconds per step (comparable to the whole
likelihood), and a SIGKILL while HDF5 flushes its metadata can leave a file
that no longer opens.  Here steps are appended in batches (every
``interval`` seconds and at every convergence check), and every batch is
written to two files in turn, ``chain.h5`` then ``chain.mirror.h5``.  A
kill can damage at most the file being written; the other holds every
step up to the previous batch (or the current one), and :meth:`Checkpoint.open`
picks the readable file with more steps and restores the other from it.
Steps completed but not yet flushed when the process dies (at most
``interval`` seconds of sampling) are recomputed identically on resume,
because the random state stored with each batch is the one after its last
step.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SetupError
from ..io.atomic import is_io_error, output_error

__all__ = ["Checkpoint", "CheckpointState"]

_GROUP = "mcmc"
_META = "bayes_rcsa"


@dataclass(frozen=True)
class CheckpointState:
    """Content of a checkpoint.

    Attributes
    ----------
    chain : (n_steps, n_walkers, ndim)
    log_prob : (n_steps, n_walkers)
    accepted : (n_walkers,) accepted-proposal counts
    random_state : tuple or None
        ``numpy.random.RandomState.get_state()`` after the last stored step.
    meta : dict
        The start-up information stored by :meth:`Checkpoint.create`.
    """

    chain: np.ndarray
    log_prob: np.ndarray
    accepted: np.ndarray
    random_state: tuple | None
    meta: dict

    @property
    def iteration(self) -> int:
        return int(self.chain.shape[0])


@contextlib.contextmanager
def _writing(path: Path, tmp: Path | None = None):
    """A failed checkpoint write (full disk, read-only or vanished folder) becomes one line naming the folder;
    the temporary copy ``tmp`` goes.  The run's own files are removed by the command (see
    :func:`bayes_rcsa.io.atomic.new_output_directory`), which knows whether they existed before."""
    try:
        yield
    except (OSError, RuntimeError) as exc:
        if not is_io_error(exc):
            raise
        if tmp is not None:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise output_error(exc, path.parent, f"cannot write the checkpoint {path.name}") from exc


class Checkpoint:
    """A pair of HDF5 files (primary and mirror) holding one emcee run.

    Parameters
    ----------
    path : path of the primary file (e.g. ``DIR/chain.h5``)
    """

    def __init__(self, path):
        import h5py  # noqa: F401  (fail early with a clear ImportError)

        self.path = Path(path)
        self.mirror = self.path.with_name(self.path.stem + ".mirror" + self.path.suffix)

    # -- creation ---------------------------------------------------------
    def create(self, n_walkers: int, ndim: int, meta: dict) -> None:
        """Start a new, empty checkpoint (replacing any old one)."""
        for p in (self.path, self.mirror):
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
        for p in (self.path, self.mirror):
            self._init_file(p, n_walkers, ndim, meta)

    @staticmethod
    def _init_file(path: Path, n_walkers: int, ndim: int, meta: dict) -> None:
        import emcee
        import h5py

        tmp = path.with_name("." + path.name + ".tmp")
        with _writing(path, tmp), h5py.File(tmp, "w", locking=False) as f:
            g = f.create_group(_GROUP)
            g.attrs["version"] = emcee.__version__
            g.attrs["nwalkers"] = n_walkers
            g.attrs["ndim"] = ndim
            g.attrs["has_blobs"] = False
            g.attrs["iteration"] = 0
            g.create_dataset("accepted", data=np.zeros(n_walkers))
            g.create_dataset("chain", (0, n_walkers, ndim), maxshape=(None, n_walkers, ndim), dtype=np.float64,
                             chunks=(64, n_walkers, ndim))
            g.create_dataset("log_prob", (0, n_walkers), maxshape=(None, n_walkers), dtype=np.float64,
                             chunks=(64, n_walkers))
            m = f.create_group(_META)
            m.attrs["meta"] = json.dumps(meta, sort_keys=True)
        with _writing(path, tmp):
            os.replace(tmp, path)

    # -- writing ----------------------------------------------------------
    def append(self, coords: np.ndarray, log_prob: np.ndarray, accepted: np.ndarray, random_state) -> None:
        """Append a batch of steps to both files.

        Parameters
        ----------
        coords : (n, n_walkers, ndim)
        log_prob : (n, n_walkers)
        accepted : (n_walkers,) accepted proposals in this batch
        random_state : RandomState state after the batch's last step
        """
        if coords.shape[0] == 0:
            return
        for p in (self.path, self.mirror):
            self._append_file(p, coords, log_prob, accepted, random_state)

    @staticmethod
    def _append_file(path, coords, log_prob, accepted, random_state) -> None:
        import h5py

        # No HDF5 file lock: a reader (a user, or a monitor) holding the file open must not
        # crash the run; the two alternating copies protect against reading a torn write.
        with _writing(path), h5py.File(path, "a", locking=False) as f:
            g = f[_GROUP]
            it = int(g.attrs["iteration"])
            n = coords.shape[0]
            g["chain"].resize(it + n, axis=0)
            g["log_prob"].resize(it + n, axis=0)
            g["chain"][it : it + n] = coords
            g["log_prob"][it : it + n] = log_prob
            g["accepted"][:] = g["accepted"][:] + accepted
            for i, v in enumerate(random_state):
                g.attrs[f"random_state_{i}"] = v
            g.attrs["iteration"] = it + n

    # -- reading ----------------------------------------------------------
    def exists(self) -> bool:
        return self.path.exists() or self.mirror.exists()

    @staticmethod
    def _read(path: Path) -> CheckpointState | None:
        import h5py

        try:
            with h5py.File(path, "r", locking=False) as f:
                g = f[_GROUP]
                it = int(g.attrs["iteration"])
                chain = np.array(g["chain"][:it])
                log_prob = np.array(g["log_prob"][:it])
                accepted = np.array(g["accepted"][:])
                keys = sorted(k for k in g.attrs if k.startswith("random_state_"))
                rs = tuple(g.attrs[k] for k in sorted(keys, key=lambda k: int(k.rsplit("_", 1)[1]))) or None
                meta = json.loads(f[_META].attrs["meta"])
        except (OSError, KeyError, ValueError):
            return None
        if chain.shape[0] != it or log_prob.shape[0] != it:
            return None
        return CheckpointState(chain, log_prob, accepted, rs, meta)

    def read(self) -> CheckpointState:
        """The most complete readable copy, without writing anything.

        Raises
        ------
        SetupError
            If neither file exists or can be read.
        """
        states = {p: self._read(p) for p in (self.path, self.mirror) if p.exists()}
        good = {p: s for p, s in states.items() if s is not None}
        if not good:
            raise SetupError(f"no readable checkpoint at {self.path} (nothing to resume)")
        return good[max(good, key=lambda p: good[p].iteration)]

    def repair(self, best: CheckpointState) -> None:
        """Make both copies hold ``best`` (call only once the run is known to continue)."""
        states = {p: self._read(p) if p.exists() else None for p in (self.path, self.mirror)}
        source = next((p for p, s in states.items() if s is not None and s.iteration == best.iteration), None)
        if source is None:
            raise SetupError(f"checkpoint {self.path}: the state to continue from is no longer on disk")
        for p, s in states.items():
            if p != source and (s is None or s.iteration != best.iteration):
                tmp = p.with_name("." + p.name + ".tmp")
                with _writing(p, tmp):
                    shutil.copyfile(source, tmp)
                    os.replace(tmp, p)

    def open(self) -> CheckpointState:
        """:meth:`read` the most complete copy and :meth:`repair` the other one."""
        best = self.read()
        self.repair(best)
        return best

    def finish(self) -> None:
        """Drop the mirror once the run is complete (the primary stays)."""
        with contextlib.suppress(FileNotFoundError):
            self.mirror.unlink()
