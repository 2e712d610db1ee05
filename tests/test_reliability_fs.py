"""The file system fails under the command (issue #21, family 1): full disk, read-only, forbidden or vanished folders.

Each case runs the real command line in process with a fault injected at one write site (an ``os.replace`` that
commits an atomic write or a checkpoint copy, a checkpoint append, the lock file) or, where the test can mount
one, on a small or read-only tmpfs.  Each asserts exit status 2, ONE stderr line naming the folder and the errno
meaning, no traceback, the directory listing before and after (nothing left behind: no chain.h5, no mirror, no
empty folder, no lock), and that a rerun in the same place succeeds.
"""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from bayes_rcsa.cli.main import main
from bayes_rcsa.data import example_dir
from bayes_rcsa.inference.checkpoint import Checkpoint

# the smallest real identification: one length, 20 steps, checkpoint written at every check
# the chain (not the default importance sampling, which keeps no checkpoint): these cases fail its checkpoint writes
# --no-tail-check: the importance tail check writes nothing (it runs between the last checkpoint write and the
# results' writes, so every write site and count below is the same); it was ~0.5 s of CPU in each of the 14 runs
IDENTIFY = ["--lengths", "0.03", "--sampler", "mcmc", "--max-steps", "20", "--walkers", "10", "--check-every", "10",
            "--quiet", "--no-plots", "--checkpoint-interval", "0", "--no-tail-check"]
PREDICT = ["--lengths", "0.03", "--directions", "x", "--max-draws", "20", "--quiet", "--no-plots"]
# 20 realisations of the bundled files' random error ('# averages = 5'): the default 500 cost ~3 s of CPU per run
LOBES = ["--flutes", "4", "--kt", "790e6", "--kr", "230e6", "--immersion", "0.95", "--speeds", "5000:30000:12",
         "--depth-points", "12", "--draws", "20", "--quiet"]
# A figure is nearly all of a lobes or report run here: lobes.png costs 0.4-1.0 s of CPU (the run without it
# 0.04 s), the report of the lobes run draws its P(stable) map (~0.5 s; the report of the identify run draws no
# figure).  Only the cases whose failure needs the figure draw it: lobes.png is the file a failure at p_stable.npz
# must remove, and the figures fill the 48 kB disks.
NO_PLOTS = ["--no-plots"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The example data, a tiny identify run (its posterior) and a lobes run, made once."""
    root = tmp_path_factory.mktemp("fs")
    data = root / "data"
    shutil.copytree(example_dir(), data)
    assert main(["identify", str(data / "setup.toml"), "--out", str(root / "ident"), *IDENTIFY]) == 0
    assert main(["lobes", "--measured-x", str(data / "tip_x_30mm.csv"), "--measured-y", str(data / "tip_y_30mm.csv"),
                 *LOBES, "--out", str(root / "lob")]) == 0
    return root


def _argv(command: str, runs: Path, out: Path, figures: bool = True) -> list[str]:
    data = runs / "data"
    lobes_plots = [] if figures else NO_PLOTS
    return {
        "identify": ["identify", str(data / "setup.toml"), "--out", str(out), *IDENTIFY],
        "predict": ["predict", str(data / "setup.toml"), "--posterior", str(runs / "ident" / "posterior.nc"),
                    "--out", str(out), *PREDICT],
        "lobes": ["lobes", "--measured-x", str(data / "tip_x_30mm.csv"), "--measured-y", str(data / "tip_y_30mm.csv"),
                  *LOBES, *lobes_plots, "--out", str(out)],
        "report": ["report", str(runs / ("lob" if figures else "ident")), "--out", str(out / "report.html")],
        "simulate": ["simulate", str(data / "setup.toml"), "--clamping-length", "0.03", "--kx", "1e7", "--ktheta",
                     "1e5", "--out", str(out / "x.csv")],
    }[command]


class Faults:
    """Fail the n-th write (or the first write to a named file) with an OSError of a chosen errno.

    Write sites: every ``os.replace`` (the commit of each atomic write and of each checkpoint file), every
    checkpoint append and, with ``lock=True``, the creation of the output lock file.
    """

    def __init__(self, monkeypatch):
        self.count = 0
        self.at: int | None = None
        self.name: str | None = None
        self.code = errno.ENOSPC
        self.kind: type[BaseException] | None = None
        self.lock = False
        real_replace, real_append, real_open = os.replace, Checkpoint._append_file, os.open

        def replace(src, dst, *a, **k):
            self._write(dst)
            return real_replace(src, dst, *a, **k)

        def append(path, *a, **k):
            self._write(path)
            return real_append(path, *a, **k)

        def open_(path, flags, *a, **k):
            if self.lock and str(path).endswith(".lock"):
                self._raise(path)
            return real_open(path, flags, *a, **k)

        monkeypatch.setattr(os, "replace", replace)
        monkeypatch.setattr(Checkpoint, "_append_file", staticmethod(append))
        monkeypatch.setattr(os, "open", open_)

    def arm(self, at=None, name=None, code=errno.ENOSPC, kind=None, lock=False):
        self.count, self.at, self.name, self.code, self.kind, self.lock = 0, at, name, code, kind, lock

    def disarm(self):
        self.arm(at=None, name=None)

    def _write(self, path):
        self.count += 1
        if (self.at is not None and self.count == self.at) or (self.name is not None and Path(path).name == self.name):
            self._raise(path)

    def _raise(self, path):
        self.at = self.name = None
        self.lock = False
        if self.kind is not None:
            raise self.kind()
        raise OSError(self.code, os.strerror(self.code), str(path))


@pytest.fixture()
def faults(monkeypatch):
    return Faults(monkeypatch)


def _tree(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def _one_error_line(err: str, *fragments: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err and lines[0].startswith("bayes-rcsa "), err
    assert ": error: " in lines[0], err
    for f in fragments:
        assert f in lines[0], (f, lines[0])
    return lines[0]


@dataclass
class Case:
    id: str
    command: str
    at: int | None = None
    name: str | None = None
    code: int = errno.ENOSPC
    lock: bool = False
    figures: bool = True  # lobes: write lobes.png (its first file); report: of the lobes run (NO_PLOTS above)


E = errno
CASES = [
    # identify: the first checkpoint file, an append to the mirror, the posterior and the last file (summary.json)
    Case("identify-enospc-checkpoint-create", "identify", at=1),
    Case("identify-erofs-checkpoint-append", "identify", at=4, code=E.EROFS),
    Case("identify-eacces-lock", "identify", code=E.EACCES, lock=True),
    Case("predict-enoent-vanished", "predict", at=1, code=E.ENOENT),
    Case("predict-eacces-last", "predict", name="report.html", code=E.EACCES),
    Case("predict-enoent-lock", "predict", code=E.ENOENT, lock=True),
    Case("lobes-enospc-npz", "lobes", name="p_stable.npz"),
    # p_stable.npz is written before lobes.json: the failure still has a file of its own to remove
    Case("lobes-erofs-json", "lobes", name="lobes.json", code=E.EROFS, figures=False),
    Case("lobes-enospc-lock", "lobes", code=E.ENOSPC, lock=True, figures=False),
    # the report is one file, whatever its runs: its one write fails
    Case("report-enospc", "report", at=1, figures=False),
    Case("report-erofs", "report", at=1, code=E.EROFS, figures=False),
    Case("report-enoent", "report", at=1, code=E.ENOENT, figures=False),
    Case("simulate-enospc", "simulate", at=1),
]


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_injected_write_failure_leaves_nothing_and_rerun_succeeds(case: Case, runs, faults, tmp_path, capsys):
    # a nested --out: the folders this run would create must go again too
    out = tmp_path / "new" / "out"
    before = _tree(tmp_path)
    faults.arm(at=case.at, name=case.name, code=case.code, lock=case.lock)
    rc = main(_argv(case.command, runs, out, case.figures))
    err = capsys.readouterr().err
    assert rc == 2, err
    line = _one_error_line(err, f"({errno.errorcode[case.code]})", os.strerror(case.code))
    assert str(tmp_path) in line  # the folder is named
    assert ".tmp" not in line and "/." not in line, line  # not an internal temporary file
    assert _tree(tmp_path) == before  # nothing left: no chain.h5, no mirror, no empty folder, no lock
    faults.disarm()
    assert main(_argv(case.command, runs, out, case.figures)) == 0, capsys.readouterr().err  # a rerun is not blocked
    capsys.readouterr()


def test_failure_in_existing_folder_keeps_its_files(runs, faults, tmp_path, capsys):
    """--force into a folder with foreign files: the run's own files go, the others stay."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    faults.arm(name="lobes.json")  # after p_stable.npz: a file of the run's own to remove
    assert main(_argv("lobes", runs, out, figures=False) + ["--force"]) == 2
    _one_error_line(capsys.readouterr().err, "(ENOSPC)")
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_interrupt_keeps_the_checkpoint_for_resume(runs, faults, tmp_path, capsys):
    """Ctrl-C is not a failure of the disk: the checkpoint stays so that --resume continues the run."""
    out = tmp_path / "out"
    faults.arm(at=4, kind=KeyboardInterrupt)
    assert main(_argv("identify", runs, out)) == 130
    capsys.readouterr()
    assert {p.name for p in out.iterdir()} == {"chain.h5", "chain.mirror.h5"}
    assert main(_argv("identify", runs, out) + ["--resume"]) == 0


def test_resume_failure_keeps_the_checkpoint_it_started_from(runs, faults, tmp_path, capsys):
    out = tmp_path / "out"
    shutil.copytree(runs / "ident", out)
    (out / "posterior.nc").unlink()
    (out / "summary.json").unlink()
    faults.arm(name="summary.json")
    assert main(_argv("identify", runs, out) + ["--resume"]) == 2
    _one_error_line(capsys.readouterr().err, "(ENOSPC)")
    assert sorted(p.name for p in out.iterdir()) == ["chain.h5"]


# ------------------------------------------------------------------------ a real (small or read-only) tmpfs


def _can_mount() -> str | None:
    if os.geteuid() != 0:
        return "mounting a tmpfs needs root"
    if shutil.which("mount") is None:
        return "no mount command"
    return None


def _remount(disk: Path, options: str) -> None:
    """Change the size of the tmpfs ``disk`` or make it read-only."""
    subprocess.run(["mount", "-o", f"remount,{options}", str(disk)], check=True, capture_output=True)


@pytest.fixture()
def tmpfs(tmp_path):
    """A mounted tmpfs ``tmp_path/disk`` (64 kB), unmounted afterwards."""
    why = _can_mount()
    if why:
        pytest.skip(why)
    disk = tmp_path / "disk"
    disk.mkdir()
    res = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)], capture_output=True, text=True)
    if res.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {res.stderr.strip()}")

    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], capture_output=True)


TMPFS = [("identify", "size=64k", errno.ENOSPC), ("predict", "size=64k", errno.ENOSPC),
         ("lobes", "size=48k", errno.ENOSPC), ("report", "size=48k", errno.ENOSPC),
         ("identify", "ro", errno.EROFS), ("lobes", "ro", errno.EROFS), ("report", "ro", errno.EROFS)]


@pytest.mark.parametrize("command,options,code", TMPFS, ids=[f"{c}-{o}" for c, o, _ in TMPFS])
def test_full_or_read_only_tmpfs(command, options, code, runs, tmpfs, capsys):
    out = tmpfs / "a" / "out"
    _remount(tmpfs, options)
    before = _tree(tmpfs)
    # a read-only disk refuses the first folder, before any file: the figures are needed only to fill the 48 kB one
    figures = options != "ro"
    rc = main(_argv(command, runs, out, figures))
    err = capsys.readouterr().err
    assert rc == 2, err
    line = _one_error_line(err, f"({errno.errorcode[code]})")
    assert str(tmpfs) in line
    assert _tree(tmpfs) == before
    _remount(tmpfs, "rw,size=8m")
    assert main(_argv(command, runs, out, figures)) == 0, capsys.readouterr().err
    capsys.readouterr()


def test_failed_forced_run_puts_the_earlier_results_back_unchanged(runs, faults, tmp_path, capsys):
    """--force over an earlier run, failing on its last file: no mix of old and new results is left."""
    out = tmp_path / "out"
    # the earlier run predicts 10 draws, the forced one 20: every file differs between the two
    earlier_argv = [a if a != "20" else "10" for a in _argv("predict", runs, out)]
    assert main(earlier_argv) == 0
    capsys.readouterr()
    (out / "mine.txt").write_text("kept\n")
    earlier = {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    # count the writes of the forced run elsewhere, then fail its last write: every file before it is replaced
    faults.arm(at=10**9)
    assert main(_argv("predict", runs, tmp_path / "count") + ["--force"]) == 0
    n_writes = faults.count
    assert n_writes >= 2
    capsys.readouterr()
    faults.arm(at=n_writes)
    assert main(_argv("predict", runs, out) + ["--force"]) == 2
    _one_error_line(capsys.readouterr().err, "(ENOSPC)")
    after = {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == earlier
    assert not list(tmp_path.glob(".out.restore-*"))  # the copies set aside are gone
