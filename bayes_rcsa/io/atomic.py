"""Write files so that a failure leaves no partial output behind."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path
from typing import Iterator

__all__ = ["atomic_path", "atomic_write_text", "atomic_write_bytes"]


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
    from ..errors import SetupError

    out_dir = Path(out_dir).resolve()
    if out_dir.exists():
        if not out_dir.is_dir():
            raise SetupError(f"{out_dir}: exists and is not a directory")
        if any(out_dir.iterdir()) and not overwrite:
            raise SetupError(f"{out_dir}: directory exists and is not empty (choose another or allow overwriting)")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", suffix=".tmp", dir=out_dir.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    return out_dir, tmp
