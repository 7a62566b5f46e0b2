"""Atomic file writes: a file is written whole under a temporary name in its own directory,
then renamed onto its final name, so a reader (or a run restarted after a crash) never sees
a partial file; a failed write leaves the previous file, if any, as it was.

:func:`atomic_path` is the one implementation; :func:`write_bytes` and :func:`write_text`
are shorthands for data already in memory.  Writers that need a file name (h5py, meshio,
matplotlib) write to the path that :func:`atomic_path` yields.

Files are created with the usual permissions (``0o666`` less the umask), like any file a
program opens for writing; an operating-system error while writing (a full disk, no
permission) is raised as :class:`~impactsph.errors.OutputError`, a one-line message that
names the file (:func:`output_error`).
"""

from __future__ import annotations

import errno
import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from .errors import OutputError

#: errno values that mean the disk (or the user's quota) is full
_FULL = {errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)}


def output_error(exc: OSError, path: Path | str, doing: str = "write") -> OutputError:
    """``exc``, raised while doing ``doing`` to ``path``, as a one-line :class:`OutputError`
    naming the path: ``cannot write PATH: the disk is full (No space left on device)``."""
    if isinstance(exc, OutputError):
        return exc
    code = exc.errno
    text = exc.strerror or str(exc)
    if code in _FULL or "No space left" in str(exc) or "Disk quota" in str(exc):
        why = f"the disk is full ({text})"
    elif code in (errno.EACCES, errno.EPERM):
        why = "permission denied"
    elif code == errno.EROFS:
        why = "the file system is read-only"
    else:
        why = text
    return OutputError(code, f"cannot {doing} {path}: {why}")


@contextmanager
def atomic_path(path: Path | str) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` for the caller to create and write; on leaving
    the block without an exception, flush it to disk and rename it onto ``path``; on an
    exception, remove it (an :class:`OSError` is raised again as an :class:`OutputError`
    naming ``path``).

    The temporary name is hidden (a leading dot), unique, and ends in ``path``'s own suffix,
    so writers that infer the format from the extension (matplotlib) write the right one.
    It is not created in advance: the writer creates it, with the usual permissions."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.{os.getpid()}-{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise output_error(exc, path) from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_bytes(path: Path | str, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp, open(tmp, "xb") as fh:
        fh.write(data)


def write_text(path: Path | str, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_bytes(path, text.encode())
