"""Write files so that a failure leaves no partial output behind."""

from __future__ import annotations

import contextlib
import fcntl
import glob
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Iterator

from ..errors import SetupError

__all__ = [
    "atomic_path", "atomic_write_text", "atomic_write_bytes", "begin_directory",
    "directory_lock", "new_output_directory", "clean_stale_temporaries", "pid_alive", "directory_is_empty",
]

#: Name of the lock file when it has to live inside the output directory (see :func:`directory_lock`).
_INNER_LOCK = ".bayes-rcsa.lock"


def directory_is_empty(path) -> bool:
    """Whether ``path`` does not exist or is a directory holding nothing but this package's lock file."""
    path = Path(path)
    if not path.exists():
        return True
    if not path.is_dir():
        return False
    return all(p.name == _INNER_LOCK for p in path.iterdir())


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` on success.

    The temporary file is removed if the block raises, so callers never leave
    a half-written output file.  ``suffix`` defaults to the target's suffix so
    that libraries that choose a format by extension (matplotlib, h5py) work.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix if suffix is not None else path.suffix, dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    # mkstemp creates 0600; give the final file the permissions a plain open() would.
    os.chmod(tmp_path, 0o666 & ~_umask())
    try:
        yield tmp_path
        os.replace(tmp_path, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp_path.unlink()
        raise


def atomic_write_text(path, text: str, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding=encoding)


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def begin_directory(out_dir, overwrite: bool = False) -> tuple[Path, Path]:
    """Check ``out_dir`` and create an empty sibling temporary directory to fill.

    The caller writes everything into the temporary directory and then moves
    it onto ``out_dir`` (or removes it on failure), so a failed run leaves no
    partial output.

    Returns
    -------
    out_dir : Path
        Resolved (``"."`` or ``"dir/"`` need a real name for the sibling).
    tmp : Path
        The temporary directory, with the permissions a plain mkdir would give.

    Raises
    ------
    SetupError
        ``out_dir`` is a file, or a non-empty directory without ``overwrite``.
    """
    out_dir = Path(out_dir).resolve()
    if out_dir.exists():
        if not out_dir.is_dir():
            raise SetupError(f"{out_dir}: exists and is not a directory")
        if any(out_dir.iterdir()) and not overwrite:
            raise SetupError(f"{out_dir}: directory exists and is not empty (choose another or allow overwriting)")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    clean_stale_temporaries(out_dir)
    # The owner's PID in the name lets a later run recognise (and remove) what a killed run left behind.
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.{os.getpid()}.", suffix=".tmp", dir=out_dir.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    return out_dir, tmp


def pid_alive(pid: int) -> bool:
    """Whether a process with this PID exists (on this machine)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, owned by someone else
    return True


def clean_stale_temporaries(out_dir) -> list[Path]:
    """Remove temporary siblings ``.NAME.PID.*.tmp`` of ``out_dir`` left by runs that died.

    Only directories whose owner PID (in the name) no longer runs are
    removed, so a concurrent run's work in progress is never touched.

    Returns
    -------
    list of Path
        The removed directories.
    """
    out_dir = Path(out_dir).resolve()
    prefix = f".{out_dir.name}."
    removed = []
    for cand in out_dir.parent.glob(glob.escape(prefix) + "*.tmp"):
        pid_text = cand.name[len(prefix):].split(".", 1)[0]
        if not pid_text.isdigit() or not cand.is_dir() or cand.is_symlink():
            continue
        if pid_alive(int(pid_text)):
            continue
        shutil.rmtree(cand, ignore_errors=True)
        removed.append(cand)
    return removed


def _lock_file(out_dir: Path) -> Path:
    # Beside the directory, so that it can be locked before it exists and while it is replaced.
    # When the parent is not writable (``--out .`` in a home directory) but the directory is,
    # the lock lives inside it; every process decides the same way, so they meet on one file.
    if not os.access(out_dir.parent, os.W_OK) and out_dir.is_dir() and os.access(out_dir, os.W_OK):
        return out_dir / _INNER_LOCK
    return out_dir.parent / f".{out_dir.name}.lock"


@contextlib.contextmanager
def directory_lock(out_dir, option: str = "--out") -> Iterator[Path]:
    """Hold an exclusive lock on the output directory ``out_dir`` while the block runs.

    The lock is ``fcntl.flock`` on the hidden file ``.NAME.lock`` beside
    ``out_dir`` (so the directory itself need not exist yet, and commands
    that replace the directory atomically keep their lock); inside
    ``out_dir`` as ``.bayes-rcsa.lock`` when only the directory is writable.  The file holds
    the owner's PID for the message of a second run; it is removed on
    release.  The kernel drops the lock when its owner dies, so a killed run
    never blocks the next one.

    Parameters
    ----------
    out_dir : path-like
    option : str
        Command-line option named in the message.

    Yields
    ------
    Path
        ``out_dir`` resolved.

    Raises
    ------
    SetupError
        Another process holds the lock: ``"DIR is in use by PID n"``.
    """
    out_dir = Path(out_dir).resolve()
    if not out_dir.parent.exists():
        out_dir.parent.mkdir(parents=True)
    lock = _lock_file(out_dir)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            # The holder writes its PID right after locking; give it a moment if we came in between.
            owner = ""
            for _ in range(20):
                os.lseek(fd, 0, os.SEEK_SET)
                owner = os.read(fd, 32).decode("ascii", "replace").strip()
                if owner:
                    break
                time.sleep(0.01)
            owner = owner or "unknown"
            os.close(fd)
            raise SetupError(f"{option} {out_dir} is in use by PID {owner} (another bayes-rcsa run writes there; "
                             "wait for it or choose another directory)") from None
        # The previous owner unlinks the file on release: if it did so between our open() and
        # flock(), we hold a lock on a deleted file; start again on the current one.
        try:
            same = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode("ascii"))
        yield out_dir
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(lock)
        os.close(fd)


@contextlib.contextmanager
def new_output_directory(out_dir, option: str = "--out") -> Iterator[Path]:
    """Create ``out_dir`` if needed for a command that writes into it in place; undo on failure.

    If the block raises and this call created the directory, the directory
    is removed again when it is still empty, so an early failure leaves
    nothing behind.  Take :func:`directory_lock` around it.
    """
    out_dir = Path(out_dir)
    created = not out_dir.exists()
    out_dir.mkdir(parents=True, exist_ok=True)
    try:
        yield out_dir
    except BaseException:
        if created:
            with contextlib.suppress(OSError):
                out_dir.rmdir()  # only succeeds when empty
        raise
