"""The errors impactsph raises for the user, in a module of their own that imports nothing,
so that any module can raise them without importing the case schema or the run loop."""

from __future__ import annotations


class CaseError(ValueError):
    """A case that cannot be run; the message is one line for the user."""


class SimulationError(RuntimeError):
    """The run went unstable; the message says where and when."""

    def __init__(self, message: str, step: int, time: float, particle: int | None):
        super().__init__(message)
        self.step, self.time, self.particle = step, time, particle


class DeviceMemoryError(SimulationError):
    """The GPU ran out of memory while the run was set up or stepped (an allocation the
    driver refused, e.g. a neighbour list that outgrew its buffer); the message says where
    and when, and what the run held on the GPU."""


class OutputError(OSError):
    """An output directory or file that cannot be used or written (a file where a directory
    is wanted, no permission, a full disk, a directory that holds another run or is in use);
    the message is one line for the user and names the path.  Made as ``OutputError(errno,
    message)``; ``str()`` is the message alone."""

    def __str__(self) -> str:
        return str(self.strerror) if self.strerror is not None else super().__str__()


class RunInterrupted(Exception):  # noqa: N818 (a stop on request, not an error)
    """A run stopped on request (Ctrl-C, SIGTERM) after a whole step, its outputs written.

    ``time`` and ``step``: where it stopped; ``checkpoint``: the checkpoint written there
    (None when the run itself had already finished, e.g. when stopped while drawing its
    figures); ``finished``: whether the simulated run was complete."""

    def __init__(self, message: str, *, time: float, step: int, checkpoint: str | None,
                 finished: bool = False):
        super().__init__(message)
        self.time, self.step, self.checkpoint, self.finished = time, step, checkpoint, finished
