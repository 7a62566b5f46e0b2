"""Atomic file writes: a file is written whole under a temporary name in its own directory,
then renamed onto its final name, so a reader (or a run restarted after a crash) never sees
a partial file; a failed write leaves the previous file, if any, as it was.

:func:`atomic_path` is the one implementation; :func:`write_bytes` and :func:`write_text`
are shorthands for data already in memory.  Writers that need a file name (h5py, meshio,
matplotlib) write to the path that :func:`atomic_path` yields.
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: Path | str) -> Iterator[Path]:
    """Yield a temporary path beside ``path`` for the caller to create and write; on leaving
    the block without an exception, flush it to disk and rename it onto ``path``; on an
    exception, remove it.

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
