"""Stopping a run cleanly on Ctrl-C or SIGTERM (standard library only, so the command line
can install it before anything heavy is imported).

A run handed a :class:`StopRequest` (``run_case(..., stop=request)``) asks it after every
step and, when a stop was asked for, stops there with a checkpoint
(:class:`~impactsph.errors.RunInterrupted`).  :func:`stop_on_signals` makes SIGINT and
SIGTERM ask for it:

- before the run is set up (imports, compilation, reading a checkpoint: nothing to save
  yet), a signal stops at once (:class:`KeyboardInterrupt`);
- once it is set up (:meth:`StopRequest.arm`), the first signal asks for a stop after the
  current step; a second one before the run has taken the request up (a step that takes
  long) stops at once (:class:`KeyboardInterrupt`); later ones, while the run writes its last
  outputs, are ignored.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator


class StopRequest:
    """A request to stop a run after its current step.  ``request()`` says whether a stop
    was asked for (:meth:`set`), and once it has said so, marks it as taken up by the run
    (:attr:`taken`)."""

    def __init__(self) -> None:
        self.requested = False
        self.taken = False
        self.armed = False
        self.signal: int | None = None

    def arm(self) -> None:
        """The run is set up: from now on a signal asks for a stop instead of stopping at
        once (called by :func:`~impactsph.runner.run_case`)."""
        self.armed = True

    def set(self, signum: int | None = None) -> None:
        """Ask the run to stop after its current step."""
        self.requested = True
        self.signal = signum

    def __call__(self) -> bool:
        if self.requested:
            self.taken = True
        return self.requested


@contextlib.contextmanager
def stop_on_signals(signals: tuple[int, ...] = (signal.SIGINT, signal.SIGTERM)
                    ) -> Iterator[StopRequest]:
    """While in the block, SIGINT (Ctrl-C) and SIGTERM act on the :class:`StopRequest` it
    yields, as the module says; on leaving, the previous handlers are restored.  Outside the
    main thread, where Python cannot handle signals, the request is yielded but no signal
    sets it."""
    request = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield request
        return

    def handler(signum: int, frame: object) -> None:
        if not request.armed or (request.requested and not request.taken):
            raise KeyboardInterrupt
        if not request.requested:
            request.set(signum)

    previous = {s: signal.signal(s, handler) for s in signals}
    try:
        yield request
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
