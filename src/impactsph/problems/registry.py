"""The registry of problems, by name: what ``analysis = "NAME"`` in a case file selects.

It imports nothing but :mod:`.base`, so the case validation (:mod:`impactsph.config`) reads it
without importing the problem modules' figures and studies; :mod:`impactsph.problems`
registers the built-in problems."""

from __future__ import annotations

import logging
from typing import Any, TypeVar

from .base import ProblemKind

log = logging.getLogger("impactsph")

_REGISTRY: dict[str, ProblemKind] = {}

P = TypeVar("P", bound=ProblemKind | type[ProblemKind])


class NoAnalysis(ProblemKind):
    """``analysis = "none"``: the run's generic summary and the kinetic energy only."""

    name = "none"
    title = "no problem-specific analysis"


def register_problem(kind: P, *, replace: bool = False) -> P:
    """Register a problem under its :attr:`~ProblemKind.name`, so that ``analysis = "NAME"``
    selects it.  ``kind``: an instance of a :class:`ProblemKind` subclass, or the subclass
    itself (instantiated without arguments; so this works as a class decorator).  Returns
    ``kind``.  The name must be a Python identifier; a name already registered is refused
    (:class:`ValueError`) unless ``replace``, and ``none`` always is."""
    problem = kind() if isinstance(kind, type) else kind
    if not isinstance(problem, ProblemKind):
        raise TypeError(f"cannot register {problem!r}: not a ProblemKind")
    name = problem.name
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"problem name {name!r} must be a Python identifier")
    if name in _REGISTRY and (name == "none" or not replace):
        raise ValueError(f"a problem named {name!r} is already registered"
                         + ("" if name == "none" else " (pass replace=True to replace it)"))
    _REGISTRY[name] = problem
    return kind


def unregister_problem(name: str) -> None:
    """Remove the problem ``name`` (tests register toy problems and remove them again);
    ``none`` stays."""
    if name != "none":
        _REGISTRY.pop(name, None)


def problem_names() -> tuple[str, ...]:
    """The registered problems' names, ``none`` first, then in the order registered."""
    return tuple(_REGISTRY)


def get_problem(name: str) -> ProblemKind:
    """The problem registered as ``name`` (:class:`ValueError` naming the registered ones if
    there is none)."""
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise ValueError(f"no problem named {name!r}; registered: "
                         f"{', '.join(problem_names())}") from None


def analyse(name: str, sim: Any) -> dict[str, Any]:
    """Metrics of the problem ``name`` (the case's ``analysis`` field) for a finished run:
    ``{}`` for ``none``.  Never raises for a problem whose metrics fail: the result is then
    ``{"notes": [why]}`` (the run keeps its generic measures), and the failure is logged."""
    problem = get_problem(name)
    try:
        metrics = dict(problem.metrics(sim))
    except Exception as exc:  # noqa: BLE001 - an analysis never stops a finished run
        note = (f"analysis {name!r}: its metrics could not be taken ({type(exc).__name__}: "
                f"{exc}); the run's generic measures are kept")
        log.warning("%s", note)
        return {"notes": [note]}
    notes = metrics.get("notes")
    if notes is not None and not isinstance(notes, list):
        metrics["notes"] = [str(notes)]
    return metrics
