"""``run.log``: the log lines of a run (level INFO and above of the ``impactsph`` loggers),
kept in its run directory whatever the console shows.

:func:`run_log` adds a file handler to the ``impactsph`` logger for the duration of a run.
When that logger would drop INFO records (the default, or ``impactsph run --quiet``), it is
opened to INFO for the run, and the records below its former level reach ``run.log`` only:
what the console (the root logger's handlers) shows does not change.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
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


@contextlib.contextmanager
def run_log(out: Path | str) -> Iterator[Path]:
    """Append the ``impactsph`` log records of level INFO and above to ``out/run.log`` while
    the block runs (a restarted run appends to its log)."""
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
    try:
        yield path
    finally:
        logger.removeHandler(handler)
        handler.close()
        if forward is not None:
            logger.removeHandler(forward)
        logger.setLevel(level)
        logger.propagate = propagate
