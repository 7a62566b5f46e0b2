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
