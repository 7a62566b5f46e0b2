"""``run.log``: the log lines of a run (level INFO and above of the ``impactsph`` loggers),
kept in its run directory whatever the console shows.

:func:`run_log` adds a file handler to the ``impactsph`` logger for the duration of a run.
When that logger would drop INFO records (the default, or ``impactsph run --quiet``), it is
opened to INFO for the run, and the records below its former level reach ``run.log`` only:
what the console (the root logger's handlers) shows does not change.  The warnings of the
run's set-up, logged before its directory was its own (a GPU asked for and the CPU used:
:mod:`impactsph.devices`; a checkpoint read unverified), are held by :func:`held_records`
and written first.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator, Sequence
from pathlib import Path

#: the file's name, in the run directory
RUN_LOG = "run.log"
FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"


class _Forward(logging.Handler):
    """Passes the records at or above ``level`` on to the root logger's handlers: what the
    ``impactsph`` logger propagated before it was opened to INFO."""

    def __init__(self, level: int) -> None:
        super().__init__(logging.NOTSET)
        self.threshold = level

    def emit(self, record: logging.LogRecord) -> None:
        if record.levelno >= self.threshold:
            logging.getLogger().callHandlers(record)


class _Held(logging.Handler):
    """Keeps the records it is given (:func:`held_records`)."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@contextlib.contextmanager
def _at_info() -> Iterator[logging.Logger]:
    """The ``impactsph`` logger opened to INFO while the block runs, where it would drop INFO
    records, with the records below its former level kept off the console (the root
    logger's handlers see what they saw before)."""
    logger = logging.getLogger("impactsph")
    level, propagate = logger.level, logger.propagate
    effective = logger.getEffectiveLevel()
    forward = None
    if effective > logging.INFO:
        logger.setLevel(logging.INFO)
        if propagate:
            logger.propagate = False
            forward = _Forward(effective)
            logger.addHandler(forward)
    try:
        yield logger
    finally:
        if forward is not None:
            logger.removeHandler(forward)
        logger.setLevel(level)
        logger.propagate = propagate


@contextlib.contextmanager
def held_records() -> Iterator[list[logging.LogRecord]]:
    """The ``impactsph`` records of level INFO and above logged while the block runs (the
    console shows what it would have), for :func:`run_log`'s ``earlier``: a run's set-up,
    before its ``run.log`` can be opened."""
    with _at_info() as logger:
        held = _Held()
        logger.addHandler(held)
        try:
            yield held.records
        finally:
            logger.removeHandler(held)


@contextlib.contextmanager
def run_log(out: Path | str, earlier: Sequence[logging.LogRecord] = ()) -> Iterator[Path]:
    """Append the ``impactsph`` log records of level INFO and above to ``out/run.log`` while
    the block runs (a restarted run appends to its log), after the ``earlier`` records
    (:func:`held_records`; written to the file only, the console has shown them)."""
    path = Path(out) / RUN_LOG
    handler = logging.FileHandler(path, mode="a", encoding="utf-8", delay=True)
    handler.setLevel(logging.INFO)
    handler.setFormatter(logging.Formatter(FORMAT))
    with _at_info() as logger:
        logger.addHandler(handler)
        for record in earlier:
            handler.handle(record)
        try:
            yield path
        except BaseException as exc:
            # the file only (the console says it its own way), where the run has logged to
            # it: a run refused as its directory was set up leaves none behind; a disk that
            # is full keeps the error it gave
            if path.exists():
                handler.flush()
                with contextlib.suppress(OSError), open(path, "a", encoding="utf-8") as fh:
                    fh.write(handler.format(_ending(exc)) + "\n")
            raise
        finally:
            logger.removeHandler(handler)
            handler.close()


def _ending(exc: BaseException) -> logging.LogRecord:
    """The record of how a run that did not finish ended, for ``run.log``: the console's
    line (the command line prints it after the log is closed) was missing there."""
    from .errors import OutputError, RunInterrupted, SimulationError

    if isinstance(exc, RunInterrupted):
        level, text = logging.WARNING, f"stopped: {exc}"
    elif isinstance(exc, KeyboardInterrupt):
        level, text = logging.WARNING, ("stopped at once (a second signal), without a "
                                        "checkpoint of the step it was in")
    elif isinstance(exc, SimulationError | OutputError):
        level, text = logging.ERROR, f"run stopped: {exc}"
    else:
        level, text = logging.ERROR, f"run stopped: {type(exc).__name__}: {exc}"
    return logging.LogRecord("impactsph", level, __file__, 0, text.replace("\n", " "), None,
                             None)
