"""``run.log``: the log lines of a run (level INFO and above of the ``impactsph`` loggers),
kept in its run directory whatever the console shows.

:func:`run_log` adds a file handler to the ``impactsph`` logger for the duration of a run.
When that logger would drop INFO records (the default, or ``impactsph run --quiet``), it is
opened to INFO for the run, and the records below its former level reach ``run.log`` only:
what the console (the root logger's handlers) shows does not change.  The warnings of the
run's set-up, logged before its directory was its own (a GPU asked for and the CPU used:
:mod:`impactsph.devices`), are held by :func:`held_warnings` and written first.
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
    """Keeps the records it is given (:func:`held_warnings`)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@contextlib.contextmanager
def held_warnings() -> Iterator[list[logging.LogRecord]]:
    """The ``impactsph`` records of level WARNING and above logged while the block runs (as
    the console shows them too), for :func:`run_log`'s ``earlier``: a run's set-up, before
    its ``run.log`` can be opened."""
    logger = logging.getLogger("impactsph")
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
    (:func:`held_warnings`; written to the file only, the console has shown them)."""
    path = Path(out) / RUN_LOG
    logger = logging.getLogger("impactsph")
    handler = logging.FileHandler(path, mode="a", encoding="utf-8", delay=True)
    handler.setLevel(logging.INFO)
    handler.setFormatter(logging.Formatter(FORMAT))
    level, propagate = logger.level, logger.propagate
    effective = logger.getEffectiveLevel()
    forward = None
    if effective > logging.INFO:
        logger.setLevel(logging.INFO)
        if propagate:
            logger.propagate = False
            forward = _Forward(effective)
            logger.addHandler(forward)
    logger.addHandler(handler)
    for record in earlier:
        handler.handle(record)
    try:
        yield path
    finally:
        logger.removeHandler(handler)
        handler.close()
        if forward is not None:
            logger.removeHandler(forward)
        logger.setLevel(level)
        logger.propagate = propagate
