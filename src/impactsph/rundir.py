"""Run directories: one run per directory, one process at a time.

- :func:`check_run_dir` looks at a directory before any work: a file where a directory is
  wanted, a directory in use by another run, and (``if_exists="refuse"``) a directory that
  already holds something, or (``"overwrite"``) holds files that impactsph did not write, are
  refused with one line (:class:`~impactsph.errors.OutputError`).
- :class:`RunLock` is the directory's lock file, ``DIR/.lock``: created atomically
  (``O_CREAT | O_EXCL``), holding the process id, host and process start time, removed when
  the run ends.  A lock whose process is gone (killed, or the machine restarted) is taken
  over; the take-over is serialised by an advisory ``flock`` on the directory itself, so two
  runs that find the same stale lock cannot both take it.  A lock of another host is never
  taken over (its process cannot be checked from here).
- :func:`clear_outputs` removes a previous run's outputs (``--overwrite``).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import secrets
import shutil
import socket
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal

from .atomic import output_error
from .errors import OutputError

#: the lock file's name, in the run directory
LOCK = ".lock"
#: what a run writes into its directory: files, and folders (a reference run, ParaView files)
OUTPUT_FILES = ("case.json", "history.csv", "probes.csv", "gauges.csv", "snapshots.npz",
                "summary.json", "checkpoint.h5", "run.log")
#: the suffixes of figures and animations (``impactsph animate``) in a run directory
OUTPUT_SUFFIXES = (".png", ".gif", ".mp4")
OUTPUT_DIRS = ("vtk", "reference")

IfExists = Literal["keep", "refuse", "overwrite"]

#: lock files this process holds (a lock with this process's id that is not here was left by
#: an earlier process that had the same id)
_held: set[Path] = set()


def _is_output(entry: Path) -> bool:
    """Whether ``entry`` of a run directory is something impactsph run writes."""
    name = entry.name
    if entry.is_dir() and not entry.is_symlink():
        return name in OUTPUT_DIRS
    return (name in OUTPUT_FILES or name == LOCK or name.endswith(OUTPUT_SUFFIXES)
            or (name.startswith(".") and ".tmp" in name))  # an atomic write's leftover


def _entries(out: Path) -> list[Path]:
    try:
        return sorted(p for p in out.iterdir() if p.name != LOCK)
    except OSError as exc:
        raise output_error(exc, out, "read the output directory") from exc


def check_run_dir(out: Path | str, if_exists: IfExists = "keep") -> None:
    """Refuse ``out`` as a run directory, before any work, with one line: a file (or a link
    to one), a directory another process is running in, and by ``if_exists``: ``"refuse"``
    one that holds anything (a stale lock aside), ``"overwrite"`` one that holds anything
    impactsph did not write (so that clearing it deletes no file of the user's), ``"keep"``
    (library callers, sweeps) nothing more.  Nothing is created."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(errno.ENOTDIR, f"--out {out} is a file, not a directory")
    if not out.is_dir():
        return
    holder = lock_holder(out)
    if holder is not None:
        raise OutputError(errno.EBUSY, _in_use(out, holder))
    if if_exists == "keep":
        return
    entries = _entries(out)
    if not entries:
        return
    if if_exists == "refuse":
        shown = ", ".join(p.name for p in entries[:4]) + (", ..." if len(entries) > 4 else "")
        checkpoint = out / "checkpoint.h5"
        raise OutputError(errno.EEXIST, (
            f"--out {out} is not empty ({shown}): a run directory holds one run; "
            "--overwrite replaces its outputs"
            + (f", --restart {checkpoint} continues its run" if checkpoint.is_file() else "")))
    if not (out / "case.json").is_file():
        raise OutputError(errno.EEXIST, f"--overwrite: {out} is not a run directory (it has "
                                        "no case.json); not cleared")
    foreign = [p.name for p in entries if not _is_output(p)]
    if foreign:
        raise OutputError(errno.EEXIST, (
            f"--overwrite: {out} holds {', '.join(foreign[:4])}, which impactsph run did not "
            "write; not cleared (move it away or choose another --out)"))


def clear_outputs(out: Path | str) -> None:
    """Remove what a previous run wrote into ``out`` (not the lock, not anything else)."""
    out = Path(out)
    for entry in _entries(out):
        if not _is_output(entry):
            continue
        try:
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink(missing_ok=True)
        except OSError as exc:
            raise output_error(exc, entry, "remove") from exc


def make_run_dir(out: Path | str) -> bool:
    """Create ``out`` (and its parents) if need be; True if it was created here."""
    out = Path(out)
    if out.is_dir():
        return False
    try:
        out.mkdir(parents=True)
    except FileExistsError:
        if not out.is_dir():
            raise OutputError(errno.ENOTDIR, f"--out {out} is a file, not a directory"
                              ) from None
        return False
    except OSError as exc:
        raise output_error(exc, out, "create the output directory") from exc
    return True


def remove_if_empty(out: Path | str) -> None:
    """Remove the directory ``out`` if it is empty (a run that wrote nothing)."""
    with contextlib.suppress(OSError):
        Path(out).rmdir()


# -- the lock ----------------------------------------------------------------------------------


def _proc_stat(pid: int) -> tuple[str, str] | None:
    """The state and start time of process ``pid`` (Linux: fields 3 and 22 of
    /proc/PID/stat; the start time in clock ticks since boot tells a process from a later one
    that reuses its id); None where there is no /proc or no such process."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            stat = fh.read()
        fields = stat[stat.rindex(")") + 2:].split()
        return fields[0], fields[19]
    except (OSError, ValueError, IndexError):
        return None


def _start_time(pid: int) -> str | None:
    stat = _proc_stat(pid)
    return stat[1] if stat else None


def _key(path: Path) -> Path:
    return Path(os.path.realpath(path.parent)) / path.name


def _read_lock(path: Path) -> dict[str, Any] | None:
    """The lock's content; None if there is no lock; ``{}`` if it cannot be read (being
    written, or damaged)."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        return None
    except OSError:
        return {}
    try:
        holder = json.loads(text)
    except ValueError:
        return {}
    return holder if isinstance(holder, dict) else {}


def _alive(holder: dict[str, Any], path: Path) -> bool:
    """Whether the run that wrote the lock ``holder`` may still be going."""
    pid = holder.get("pid")
    if not isinstance(pid, int):
        # empty or unreadable: a lock being written this instant is live; an old one is not
        try:
            return time.time() - path.stat().st_mtime < 10.0
        except OSError:
            return False
    if holder.get("host") not in (None, socket.gethostname()):
        return True  # another machine's process: cannot be checked from here
    if pid == os.getpid():
        return _key(path) in _held
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass  # alive, another user's
    except OSError:
        return True
    stat = _proc_stat(pid)
    if stat is None:
        return True  # no /proc: alive as far as can be told
    state, started = stat
    if state in ("Z", "X"):
        return False  # ended; a zombie its parent has not yet reaped
    return holder.get("started") in (None, started)


def lock_holder(out: Path | str) -> dict[str, Any] | None:
    """The lock of a run going on in ``out`` (its ``pid``, ``host``), or None if there is
    none or it is stale."""
    path = Path(out) / LOCK
    holder = _read_lock(path)
    if holder is None or not _alive(holder, path):
        return None
    return holder


def _in_use(out: Path, holder: dict[str, Any]) -> str:
    who = f"process {holder.get('pid', '?')}"
    if holder.get("host") not in (None, socket.gethostname()):
        who += f" on {holder['host']}"
        return (f"--out {out} is in use by another run ({who}, {out / LOCK}); if no run is "
                f"going on there, remove {out / LOCK}")
    return (f"--out {out} is in use by another run ({who}, {out / LOCK}); wait for it to end "
            "or choose another --out")


@contextlib.contextmanager
def _directory_mutex(out: Path) -> Iterator[None]:
    """An exclusive advisory lock on the directory itself for the moment of taking the lock
    file (POSIX ``flock``; skipped where there is none)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover (not POSIX)
        yield
        return
    try:
        fd = os.open(out, os.O_RDONLY)
    except OSError:
        yield
        return
    try:
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the flock


class RunLock:
    """``DIR/.lock`` held while a run writes into ``DIR``: ``with RunLock(out): ...``, or
    :meth:`acquire` and :meth:`release`.  Refuses (:class:`OutputError`) a directory another
    live run holds; takes over the lock of a run that is gone."""

    def __init__(self, out: Path | str) -> None:
        self.out = Path(out)
        self.path = self.out / LOCK
        self.token = secrets.token_hex(8)
        self.held = False

    def acquire(self) -> RunLock:
        content = json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                              "started": _start_time(os.getpid()), "token": self.token})
        with _directory_mutex(self.out):
            for _ in range(3):
                try:
                    fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
                except FileExistsError:
                    holder = _read_lock(self.path)
                    if holder is not None and _alive(holder, self.path):
                        raise OutputError(errno.EBUSY, _in_use(self.out, holder)) from None
                    with contextlib.suppress(FileNotFoundError):
                        self.path.unlink()  # stale: its run is gone
                    continue
                except OSError as exc:
                    raise output_error(exc, self.path) from exc
                try:
                    os.write(fd, content.encode())
                except OSError as exc:
                    os.close(fd)
                    self.path.unlink(missing_ok=True)
                    raise output_error(exc, self.path) from exc
                os.close(fd)
                self.held = True
                _held.add(_key(self.path))
                return self
        raise OutputError(errno.EBUSY, f"--out {self.out}: cannot take its lock {self.path}")

    def release(self) -> None:
        """Remove the lock file, if it is still this lock's."""
        if not self.held:
            return
        self.held = False
        _held.discard(_key(self.path))
        holder = _read_lock(self.path)
        if holder and holder.get("token") == self.token:
            with contextlib.suppress(OSError):
                self.path.unlink()

    def __enter__(self) -> RunLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
