"""Write files so that a failure leaves no partial output behind."""

from __future__ import annotations

import contextlib
import errno
import fcntl
import glob
import os
import re
import shutil
import tempfile
import time
from pathlib import Path
from typing import Iterable, Iterator

from ..errors import OutputError, SetupError

__all__ = [
    "atomic_path", "atomic_write_text", "atomic_write_bytes", "begin_directory",
    "directory_lock", "new_output_directory", "clean_stale_temporaries", "pid_alive", "directory_is_empty",
    "os_error_reason", "output_error", "is_io_error", "make_parents", "remove_empty_directories", "check_writable",
]


_ERRNO_IN_TEXT = re.compile(r"errno\s*=\s*(\d+)")


def is_io_error(exc: BaseException) -> bool:
    """Whether ``exc`` is a failed file operation: an :class:`OSError`, or HDF5's RuntimeError that carries one.

    HDF5 (h5py, h5netcdf) reports a write that failed while flushing or closing a file as ``RuntimeError``
    with ``errno = 28`` in its text.
    """
    return isinstance(exc, OSError) or (isinstance(exc, RuntimeError) and bool(_ERRNO_IN_TEXT.search(str(exc))))


def os_error_reason(exc: BaseException) -> str:
    """The errno meaning of ``exc`` as ``"No space left on device (ENOSPC)"``.

    HDF5 reports its I/O errors as an :class:`OSError` without ``errno`` but
    with ``errno = 28`` in the text; that number is used then.  Without any
    errno the exception's first line is returned.
    """
    code = getattr(exc, "errno", None)
    if not code:
        m = _ERRNO_IN_TEXT.search(str(exc))
        code = int(m.group(1)) if m else None
    if code:
        return f"{os.strerror(code)} ({errno.errorcode.get(code, f'errno {code}')})"
    text = (getattr(exc, "strerror", None) or str(exc) or type(exc).__name__).strip().splitlines()
    return text[0] if text else type(exc).__name__


def output_error(exc: BaseException, folder, what: str = "cannot write") -> OutputError:
    """An :class:`OutputError` for ``exc`` met while writing into ``folder``: one line naming the folder.

    When the failing path lies outside ``folder`` (an input read inside the
    writing block), that path is named instead.
    """
    folder = Path(folder)
    name = getattr(exc, "filename", None)
    if name is not None:
        try:
            inside = Path(os.fsdecode(name)).resolve().is_relative_to(folder.resolve())
        except (OSError, ValueError, TypeError):
            inside = True
        if not inside:
            return OutputError(f"{os.fsdecode(name)}: {os_error_reason(exc)}")
    return OutputError(f"{folder}: {what}: {os_error_reason(exc)}")


def check_writable(path, option: str = "--out") -> None:
    """Refuse an output path whose folder cannot be written (read-only, no permission), before any work.

    Creates and removes an empty temporary file in ``path`` when it is an
    existing directory, else in its nearest existing ancestor (where the
    missing folders would be made); nothing else is created.  A full disk
    usually still allows an empty file; it is met, and undone, at the first
    real write.

    Raises
    ------
    OutputError
        ``"--out DIR: cannot write in FOLDER: Read-only file system (EROFS)"``.
    """
    path = Path(path).absolute()
    folder = path if path.is_dir() else next((p for p in path.parents if p.exists()), None)
    if folder is None or not folder.is_dir():
        return  # a file in the way is named by the caller's own check
    try:
        fd, probe = tempfile.mkstemp(prefix=".bayes-rcsa-probe.", dir=folder)
    except OSError as exc:
        raise OutputError(f"{option} {path}: cannot write in {folder}: {os_error_reason(exc)}") from exc
    os.close(fd)
    os.unlink(probe)


def make_parents(path) -> list[Path]:
    """Create the missing directories of ``path`` (itself included); return the ones created, outermost first."""
    path = Path(path)
    missing = []
    for p in (path, *path.parents):
        if p.exists():
            break
        missing.append(p)
    missing.reverse()
    for p in missing:
        try:
            p.mkdir()
        except FileExistsError:  # made by a concurrent process meanwhile: not ours to remove
            missing = missing[missing.index(p) + 1:]
    return missing


def remove_empty_directories(dirs: Iterable[Path]) -> None:
    """Remove each directory of ``dirs`` that is (still) empty, innermost first; others are left alone."""
    for d in reversed(list(dirs)):
        try:
            d.rmdir()
        except OSError:  # not empty (a later command wrote there) or already gone: leave it
            continue

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
    created: list[Path] = []
    tmp_path = None
    try:
        try:
            created = make_parents(path.parent)
        except OSError as exc:
            raise output_error(exc, path.parent, "cannot create the folder") from exc
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix if suffix is not None else path.suffix,
                                   dir=path.parent)
        os.close(fd)
        tmp_path = Path(tmp)
        # mkstemp creates 0600; give the final file the permissions a plain open() would.
        os.chmod(tmp_path, 0o666 & ~_umask())
        yield tmp_path
        os.replace(tmp_path, path)
    except BaseException as exc:
        if tmp_path is not None:
            with contextlib.suppress(OSError):
                tmp_path.unlink()
        remove_empty_directories(created)
        if is_io_error(exc):
            # a full disk, a read-only or vanished folder: one line naming the folder, not the temporary file
            raise output_error(exc, path.parent, f"cannot write {path.name}") from exc
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
    created: list[Path] = []
    try:
        created = make_parents(out_dir.parent)
        fd, lock = _acquire(out_dir, option)
    except OSError as exc:
        # read-only or vanished parent, no permission, full disk: nothing of ours may stay behind
        remove_empty_directories(created)
        raise output_error(exc, out_dir.parent, f"cannot create the lock file for {option} {out_dir}") from exc
    except BaseException:
        remove_empty_directories(created)
        raise
    try:
        yield out_dir
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(lock)
        os.close(fd)
        # parents made for a run that then wrote nothing (it failed early) go again
        remove_empty_directories(created)


def _acquire(out_dir: Path, option: str) -> tuple[int, Path]:
    """Open and flock the lock file of ``out_dir``; write our PID into it.  Returns (fd, lock path)."""
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
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(lock)
        os.close(fd)
        raise
    return fd, lock


@contextlib.contextmanager
def new_output_directory(out_dir, option: str = "--out", keep_on_interrupt: Iterable[str] = ()) -> Iterator[Path]:
    """Create ``out_dir`` if needed for a command that writes into it in place; undo on failure.

    If the block raises, every entry of ``out_dir`` that was not there when
    the block began is removed (files, and folders with what is in them),
    then ``out_dir`` itself and the parents this call created if they are
    empty: a failed run, a full disk or a folder turned read-only leaves
    nothing behind, and a rerun is not blocked.  The entries that *were*
    there (an earlier run's results under ``--force``) are copied aside
    first and put back as they were, so a failed forced run never leaves
    a mix of old and new results (a failure while copying them aside is an
    :class:`OutputError` before anything is written).  Entries named in
    ``keep_on_interrupt`` stay when the failure is a keyboard interrupt (the
    checkpoint of ``identify``, which ``--resume`` continues).  An
    :class:`OSError` raised in the block becomes one :class:`OutputError`
    line naming the folder and the errno meaning.  Take
    :func:`directory_lock` around it.
    """
    out_dir = Path(out_dir)
    keep = set(keep_on_interrupt)
    try:
        before = {p.name for p in out_dir.iterdir()} if out_dir.is_dir() else set()
        created = make_parents(out_dir)
    except OSError as exc:
        raise output_error(exc, out_dir, "cannot create the output folder") from exc
    # the earlier entries, except the lock and the entries that carry their own progress (a checkpoint)
    saved = sorted(n for n in before if n != _INNER_LOCK and n not in keep)
    backup = _back_up(out_dir, saved) if saved else None
    try:
        yield out_dir
    except BaseException as exc:
        interrupted = isinstance(exc, KeyboardInterrupt)
        with contextlib.suppress(OSError):
            for p in list(out_dir.iterdir()):
                if (p.name in before and p.name not in saved) or (interrupted and p.name in keep) or p == backup:
                    continue
                _remove(p)
        if backup is not None:
            with contextlib.suppress(OSError):
                for name in saved:
                    if (backup / name).exists() or (backup / name).is_symlink():
                        os.replace(backup / name, out_dir / name)
        remove_empty_directories(created)
        if is_io_error(exc):
            raise output_error(exc, out_dir) from exc
        raise
    finally:
        if backup is not None:
            shutil.rmtree(backup, ignore_errors=True)


def _remove(p: Path) -> None:
    """Remove a file, link or folder tree; errors are left to the caller's suppression."""
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            p.unlink()


def _back_up(out_dir: Path, names: list) -> Path:
    """Copy ``names`` of ``out_dir`` into a hidden folder beside it (inside it when the parent is read-only).

    Raises
    ------
    OutputError
        When the copies cannot be made (a full disk): nothing of the run has been written yet.
    """
    try:
        backup = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.restore-", dir=out_dir.parent))
    except OSError:
        try:
            backup = Path(tempfile.mkdtemp(prefix=".bayes-rcsa.restore-", dir=out_dir))
        except OSError as exc:
            raise output_error(exc, out_dir, "cannot set the earlier results aside before replacing them") from exc
    try:
        for name in names:
            src = out_dir / name
            if src.is_dir() and not src.is_symlink():
                shutil.copytree(src, backup / name, symlinks=True)
            else:
                shutil.copy2(src, backup / name, follow_symlinks=False)
    except OSError as exc:
        shutil.rmtree(backup, ignore_errors=True)
        raise output_error(exc, out_dir, "cannot set the earlier results aside before replacing them") from exc
    return backup
